"""The path-matched leak check for faults (`sportsngen.eval.leak_paths`)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sportsngen.eval.leak_paths import check_fault_paths, path_matched_auc, serve_paths
from sportsngen.eval.leaks import leak_auc


def _serves(fault_receiver_speed: float | None = None) -> pd.DataFrame:
    """Serves on three lateral lines (the receiver at y = 0): his speed 12 frames on grows with the
    lateral distance to the ball's line, whatever the outcome. Faults land 0.1-0.3 m long, ins
    0.1-0.9 m inside the service line; faults come mostly on the wide line (y = 4), so within
    one stratum faults move more than ins. `fault_receiver_speed` plants a leak."""
    rows = []
    for line_y, n_in, n_fault in ((0.0, 30, 2), (2.0, 30, 4), (4.0, 30, 14)):
        for i in range(n_in + n_fault):
            fault = i >= n_in
            bx = 6.5 + 0.1 * (i % 3) if fault else 6.3 - 0.2 * (i % 5)
            speed = 0.23 + 0.35 * line_y  # inexact in binary: equal speeds must still tie
            if fault and fault_receiver_speed is not None:
                speed = fault_receiver_speed
            rows.append({"k": 12, "fault_vs_in": int(fault), "at_frame": 40, "land_frame": 45,
                         "serve_number": 1, "hitter": "S", "opponent": "R",
                         "bounce_x": -bx, "bounce_y": line_y, "contact_y": -0.5,
                         "speed_mps": 45.0, "hitter_x": 11.4, "hitter_y": -0.5,
                         "opponent_x": -12.0, "opponent_y": 0.0,
                         "hitter_speed_mps": 1.0, "hitter_acc_mps2": 2.0,
                         "opponent_speed_mps": speed, "opponent_acc_mps2": 3.0})
    return pd.DataFrame(rows)


def _row(table: pd.DataFrame, role: str, feature: str) -> pd.Series:
    return table.set_index(["pair", "role", "feature", "k"]).loc[("fault_vs_in", role, feature,
                                                                  12)]


def test_movement_that_follows_the_path_is_not_a_leak():
    table = _serves()
    raw = leak_auc(table.assign(rally_id=np.arange(len(table)), shot_index=0, frame=28,
                                outcome_frame=45, ace_vs_returned=-1, winner_vs_returned=-1,
                                error_vs_in=-1), n_boot=0, stratify=False)
    # Faults come wide more often, so their receiver runs faster: the raw AUC sees a "leak".
    assert _row(raw, "opponent", "speed_mps")["auc"] == pytest.approx(1260 / 1800)
    got = path_matched_auc(table, n_neighbours=5, n_boot=50)
    row = _row(got, "opponent", "speed_mps")
    # Every fault's five nearest ins are on its own line: residuals 0, every pair a tie.
    assert (row["auc"], row["lo"], row["hi"]) == (0.5, 0.5, 0.5)
    assert (row["n_pos"], row["n_neg"]) == (20, 90)
    assert set(got["auc"]) == {0.5}


def test_a_receiver_who_stops_before_faults_is_flagged():
    got = path_matched_auc(_serves(fault_receiver_speed=0.0), n_neighbours=5, n_boot=200)
    row = _row(got, "opponent", "speed_mps")
    # A stopped receiver is below the ins on his path on every line.
    assert (row["auc"], row["hi"]) == (0.0, 0.0)
    assert _row(got, "hitter", "speed_mps")["auc"] == 0.5
    with pytest.raises(ValueError, match="n_neighbours"):
        path_matched_auc(_serves(), n_neighbours=0)


def test_a_group_with_too_few_ins_is_left_out():
    table = _serves()
    got = path_matched_auc(table[(table["fault_vs_in"] == 1) | (table.index % 10 == 0)],
                           n_neighbours=10)
    assert got["auc"].isna().all() and (got["n_pos"] == 0).all()


def test_serve_paths_reads_the_tables_with_the_server_at_plus_x():
    from sportsngen.synth import generate_matches

    data = generate_matches([("Roger Federer", "Rafael Nadal")], "hard", 60, seed=3)
    kin = _kinematics(data)
    paths = serve_paths(data, kin)
    assert len(paths) == (kin["shot_index"] == 0).sum() > 0
    assert (paths["hitter_x"] > 0).all() and (paths["opponent_x"] < 0).all()
    serve = data.shots[data.shots["shot_index"] == 0].set_index("rally_id")
    one = paths.iloc[0]
    turn = 1.0 if serve.loc[one["rally_id"], "contact_x"] >= 0 else -1.0
    frame = data.frames.set_index(["rally_id", "frame", "object"]).loc[
        (one["rally_id"], one["frame"], one["opponent"])]
    assert one["opponent_x"] == pytest.approx(turn * frame["x"])
    assert one["bounce_y"] == pytest.approx(turn * serve.loc[one["rally_id"], "bounce_y"],
                                            nan_ok=True)
    table = check_fault_paths(data, n_boot=20)
    assert list(table["pair"].unique()) == ["fault_vs_in"] and len(table) == 8


def _kinematics(data):
    from sportsngen.eval.leaks import contact_kinematics

    return contact_kinematics(data, (6, 12))


def test_other_pairs_are_matched_on_the_path_when_asked():
    # The same serves read as aces (the faults) against returned serves (the ins), the serve
    # becoming an ace visible at the land frame: a server slower after aces is flagged.
    table = _serves(fault_receiver_speed=0.0).rename(columns={"fault_vs_in": "ace_vs_returned"})
    table["hitter_speed_mps"] = np.where(table["ace_vs_returned"] == 1, 0.5, 1.0)
    table["outcome_frame"] = 45
    got = path_matched_auc(table, n_neighbours=5, n_boot=0, pairs=("ace_vs_returned",))
    assert set(got["pair"]) == {"ace_vs_returned"}
    row = got.set_index(["role", "feature"])
    assert row.loc[("hitter", "speed_mps"), "auc"] == 0.0
    assert row.loc[("hitter", "acc_mps2"), "auc"] == 0.5
