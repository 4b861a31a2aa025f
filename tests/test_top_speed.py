"""Each player's top speed read from his record (`sportsngen.sim.top_speed`)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sportsngen.sim.top_speed import TopSpeeds, fit_top_speeds, player_speeds


def test_frame_speeds_are_read_per_player_and_rally_without_the_ball():
    # Rally 1: A steps 0.2 m a frame (5 m/s at 25 fps), B 3-4-5 over two frames (2.5 m/s);
    # rally 2: A stands. The ball's frames and each rally's first are left out.
    rows = []
    for k in range(3):
        rows += [(1, k, "A", 0.2 * k, 0.0), (1, k, "B", 0.0, 0.0) if k < 2 else
                 (1, k, "B", 0.06, 0.08), (1, k, "ball", 9.0 * k, 1.0)]
    rows += [(2, 0, "A", 1.0, 1.0), (2, 1, "A", 1.0, 1.0)]
    frames = pd.DataFrame(rows, columns=["rally_id", "frame", "object", "x", "y"])
    out = player_speeds(frames, 25.0)
    got = out.groupby("player")["speed_mps"].apply(lambda s: sorted(np.round(s, 6)))
    assert got.to_dict() == {"A": [0.0, 5.0, 5.0], "B": [0.0, 2.5]}


def test_each_player_with_enough_frames_gets_his_own_quantile():
    rng = np.random.default_rng(0)
    speeds = pd.concat([pd.DataFrame({"player": "A", "speed_mps": rng.uniform(0, 6.0, 20000)}),
                        pd.DataFrame({"player": "B", "speed_mps": rng.uniform(0, 7.0, 20000)}),
                        pd.DataFrame({"player": "C", "speed_mps": rng.uniform(0, 9.0, 100)})])
    table = fit_top_speeds(speeds, quantile=0.999, min_frames=5000)
    assert sorted(table.players_mps) == ["A", "B"]
    assert table.players_mps["A"] == pytest.approx(5.994, abs=0.01)
    assert table.players_mps["B"] == pytest.approx(6.993, abs=0.01)
    assert table.speeds_mps([["A", "C"], ["B", "A"]]).round(2).tolist() == \
        [[5.99, round(table.pooled_mps, 2)], [6.99, 5.99]]
    with pytest.raises(ValueError, match="quantile"):
        fit_top_speeds(speeds, quantile=1.5)
    with pytest.raises(ValueError, match="no player frames"):
        fit_top_speeds(speeds.iloc[:0])


def test_the_table_round_trips_and_refuses_what_it_cannot_hold():
    table = TopSpeeds(6.5, {"A": 6.0})
    assert TopSpeeds.from_dict(table.to_dict()) == table
    with pytest.raises(ValueError, match="positive"):
        TopSpeeds(0.0)
    with pytest.raises(ValueError, match="positive"):
        TopSpeeds(6.5, {"B": float("nan")})


def test_the_fit_writes_the_table_and_the_default_into_a_copy(
        tiny_model_file, federer_points_and_head_model, tmp_path, monkeypatch, capsys):
    """`fit_top_speed_file` (`scripts/fit_top_speed.py`) on a file, its training rallies stood
    in for by 80 generated points of Federer against Nadal: the copy carries each player's top
    speed (the generator's 6.8 and 7.0 m/s) and bounds the rollouts by it; the source is left
    as it was."""
    from sportsngen.model.export import read_extra
    from sportsngen.sim.simulator import Simulator
    from sportsngen.train import rule_tables

    data = federer_points_and_head_model[0]
    monkeypatch.setattr(rule_tables, "training_rally_data", lambda src, more: [data])
    out = tmp_path / "with_top_speed.pt"
    rule_tables.fit_top_speed_file(str(tiny_model_file), str(out), min_frames=1000)
    assert "top speed" in capsys.readouterr().out
    table = TopSpeeds.from_dict(read_extra(out)["top_speed"])
    assert set(table.players_mps) == {"Roger Federer", "Rafael Nadal"}
    assert 6.0 < table.players_mps["Roger Federer"] <= 6.8 + 1e-6
    assert 6.0 < table.players_mps["Rafael Nadal"] <= 7.0 + 1e-6
    assert Simulator.from_pretrained(out).player_top_speed is True
    assert "top_speed" not in read_extra(tiny_model_file)
