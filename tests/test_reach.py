"""Who reaches the ball (`sportsngen.eval.reach`) on generated points."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sportsngen.data.tracking import RallyData
from sportsngen.eval.__main__ import main
from sportsngen.eval.reach import (
    answered_by_need,
    contact_rows,
    contact_states,
    reach_rows,
    toward_speeds,
)
from sportsngen.synth import generate_matches


@pytest.fixture(scope="module")
def points() -> RallyData:
    return generate_matches([("Roger Federer", "Rafael Nadal")], "hard", n_points=80, seed=0,
                            workers=1)


def test_the_generators_players_answer_the_good_balls_they_can_reach(points):
    every = reach_rows(points)
    rows = every[every["shot"] >= 1]
    assert set(rows["role"]) == {"server", "receiver"} and len(rows) > 100
    assert (rows["need_m"] >= 0).all() and (rows["gap_m"] >= 0).all()
    # They run to the ball (nearer to it than where they stood, but for balls that come at
    # them, stepped around), and answer almost all of
    # those within 5 m (0.92-0.99 over 500 points).
    assert (rows["gap_m"] <= rows["need_m"] + 1e-9).mean() > 0.9
    near = rows[rows["need_m"] <= 5.0]
    assert near["answered"].mean() > 0.88
    # An answered ball came within a racket's reach.
    assert rows.loc[rows["answered"], "gap_m"].median() < 1.2
    table = answered_by_need(rows)
    assert list(table.columns) == ["need (m)", "answered (receiver)", "answered (server)",
                                   "n (receiver)", "n (server)"]
    assert table[["n (receiver)", "n (server)"]].sum().sum() == len(rows)
    fast = answered_by_need(rows, by="need_speed_mps")
    assert fast.columns[0] == "need (m/s)"
    assert fast[["n (receiver)", "n (server)"]].sum().sum() == len(rows)
    np.testing.assert_allclose(rows["need_speed_mps"] * rows["time_s"], rows["need_m"])
    assert (rows["time_s"] > 0).all()
    # By how close the ball came as he moved: the generator's players answer the balls that
    # come within a racket's reach and none that pass beyond any player's (3 m).
    by_gap = answered_by_need(rows, by="gap_m").set_index("gap (m)")
    assert by_gap[["n (receiver)", "n (server)"]].sum().sum() == len(rows)
    near = rows[rows["gap_m"] <= 1.2]
    assert near["answered"].mean() > 0.95
    assert not rows.loc[rows["gap_m"] > 3.0, "answered"].any()
    with pytest.raises(ValueError, match="by must be"):
        answered_by_need(rows, by="speed")
    speeds = toward_speeds(rows)
    assert list(speeds["frames after the contact"]) == ["receiver", "server"]
    # Running toward a ball 3-7 m away: at least 2 m/s half a second after the contact.
    assert (speeds["10-14"] > 2.0).all()
    # Good serves are the receiver's: every one within 2 m is returned (1.00 over 500 points),
    # and each serve row's bounce was in its box (faults are not the receiver's to answer).
    serves = every[every["shot"] == 0]
    assert len(serves) > 40 and set(serves["role"]) == {"receiver"}
    assert serves.loc[serves["need_m"] <= 2.0, "answered"].mean() > 0.95
    r = points.rallies.set_index("rally_id")
    assert not r.loc[serves["rally_id"], "end_reason"].isin(["fault", "double_fault"]).any()
    by_need = answered_by_need(every, shots="serve")
    assert list(by_need.columns) == ["need (m)", "answered (receiver)", "n (receiver)"]
    assert by_need["n (receiver)"].sum() == len(serves)
    assert list(toward_speeds(every, (1.0, 7.0), shots="serve")["frames after the contact"]) \
        == ["receiver"]
    with pytest.raises(ValueError, match="shots must be"):
        answered_by_need(every, shots="returns")


def test_a_player_who_never_moves_gets_no_closer_than_where_he_stood(points):
    frames = points.frames.copy()
    who = frames["object"] == "Rafael Nadal"
    first = frames[who].groupby("rally_id")[["x", "y"]].transform("first")
    frames.loc[who, ["x", "y"]] = first.to_numpy()
    still = RallyData.from_tables(frames, points.rallies, points.shots, fps=points.fps,
                                  validate=False)
    rows = reach_rows(still)
    nadal = rows[(rows["role"] == "receiver") == (
        still.rallies.set_index("rally_id").loc[rows["rally_id"], "receiver"].to_numpy()
        == "Rafael Nadal")]
    assert len(nadal) > 20
    np.testing.assert_allclose(nadal["gap_m"], nadal["need_m"])
    cols = [c for c in rows.columns if c.startswith("toward_mps_")]
    assert np.nanmax(np.abs(nadal[cols].to_numpy())) == 0.0


def test_no_rally_ball_is_an_error_and_the_command_line_reads_a_folder(points, tmp_path, capsys):
    with pytest.raises(ValueError, match="no good rally balls"):
        answered_by_need(pd.DataFrame(columns=["need_m", "role", "answered"]))
    points.save(tmp_path / "pts")
    assert main(["reach", str(tmp_path / "pts")]) == 0
    out = capsys.readouterr().out
    assert "answered (server)" in out and "speed toward" in out and "good serves" in out
    assert "where the ball is struck" in out
    assert main(["reach", str(tmp_path / "missing")]) == 2


def test_the_generators_players_strike_from_behind_the_baseline_within_their_reach(points):
    rows = contact_rows(points)
    assert set(rows["role"]) == {"server", "receiver"} and (rows["shot"] >= 1).all()
    # Odd shots are the receiver's.
    assert ((rows["shot"] % 2 == 1) == (rows["role"] == "receiver")).all()
    table = contact_states(rows)
    ret = table[table["shot"] == 1].set_index("player")
    # Nadal returns from deep (the generator's 500 points: 3.3 m behind his baseline on first
    # serves, 2.1 on second), Federer from the baseline (0.1 and -1.3), off serves that arrive
    # at about 21 m/s and leave at 27.
    assert ret.at["Rafael Nadal", "behind_m"] > 1.5 > ret.at["Roger Federer", "behind_m"] + 0.5
    assert ((15.0 < ret["in_mps"]) & (ret["in_mps"] < 30.0)).all()
    assert ((20.0 < ret["out_mps"]) & (ret["out_mps"] < 35.0)).all()
    # The generator's players strike within their reach (1.8 m for both, `synth.profiles`, and
    # the kernel's 0.15 m tolerance), read on the shots table's frame, which lies up to half a
    # frame from the racket's: the ball (the faster of its speeds in and out) and the player
    # (at most 7 m/s) move on by then. Most strike squarely: they run to a spot 0.3-1.2 m
    # beside the ball (`rally.CONTACT_LATERAL_RANGE_M`; a median 0.8 m over 500 points).
    half_frame = 0.5 * (np.maximum(rows["in_mps"], rows["out_mps"]) + 7.0) / points.fps
    assert (rows["gap_m"] <= 1.8 + 0.15 + half_frame).all()
    assert rows["gap_m"].quantile(0.9) < 1.2 + half_frame.median()
    assert 0.6 < rows["gap_m"].median() < 1.0
    assert (rows["height_m"] > 0).all()
    assert table["n"].sum() == int((rows["shot"] <= 4).sum())
    with pytest.raises(ValueError, match="no rally contact"):
        contact_states(rows[rows["shot"] > 99])


def test_a_hitter_half_a_metre_beside_the_ball_is_measured_at_half_a_metre(points):
    frames = points.frames.copy().sort_values(["rally_id", "frame"])
    ball = frames[frames["object"] == "ball"].set_index(["rally_id", "frame"])
    for name in ("Roger Federer", "Rafael Nadal"):
        who = frames["object"] == name
        at = ball.loc[list(zip(frames.loc[who, "rally_id"], frames.loc[who, "frame"]))]
        frames.loc[who, "x"] = at["x"].to_numpy()
        frames.loc[who, "y"] = at["y"].to_numpy() + 0.5
    beside = RallyData.from_tables(frames, points.rallies, points.shots, fps=points.fps,
                                   validate=False)
    rows = contact_rows(beside)
    assert len(rows) > 100
    np.testing.assert_allclose(rows["gap_m"], 0.5, atol=1e-6)
