"""A receiver's reach for the return drawn from his record (`sportsngen.sim.return_reach`) and
the rollout rules that take it per row."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
import torch

from sportsngen.sim.constraints import PhysicalLimits, StrikeInReach, return_reaches
from sportsngen.sim.return_reach import (
    MAX_REACH_M,
    MIN_REACH_M,
    ReturnReach,
    fit_logistic,
    fit_return_reach,
    serve_rows,
)


def _serves(centre_m: float, scale_m: float, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    gap = rng.uniform(0.0, 2.5, n)
    returned = rng.uniform(size=n) < 1.0 / (1.0 + np.exp((gap - centre_m) / scale_m))
    return gap, returned


def test_the_fit_finds_the_centre_and_scale_the_serves_were_drawn_with():
    gap, returned = _serves(1.45, 0.06, 20000, seed=0)
    c, s = fit_logistic(gap, returned)
    assert abs(c - 1.45) < 0.01 and abs(s - 0.06) < 0.01
    gap, returned = _serves(1.60, 0.12, 20000, seed=1)
    c, s = fit_logistic(gap, returned)
    assert abs(c - 1.60) < 0.02 and abs(s - 0.12) < 0.02


def test_a_draw_returns_a_serve_at_its_receivers_odds():
    table = ReturnReach((1.5, 0.05), {"Rafael Nadal": (1.43, 0.04), "Roger Federer": (1.55, 0.08)})
    rng = np.random.default_rng(3)
    for name, gap in (("Rafael Nadal", 1.40), ("Rafael Nadal", 1.48), ("Roger Federer", 1.60),
                      ("Somebody Else", 1.52)):
        reach = table.draw([name] * 40000, rng)
        want = float(table.returned_odds([name], [gap])[0])
        assert abs((reach >= gap).mean() - want) < 0.01, (name, gap)
    # An unknown receiver plays the pooled row; exact odds at the centre are one half.
    assert table.returned_odds(["Somebody Else"], [1.5]).tolist() == [0.5]
    c, s = table.centre_scale(["Roger Federer", "Nobody"])
    assert c.tolist() == [1.55, 1.5] and s.tolist() == [0.08, 0.05]
    wide = ReturnReach((1.5, 2.0)).draw(["x"] * 5000, rng)
    assert wide.min() == MIN_REACH_M and wide.max() == MAX_REACH_M


def test_the_table_round_trips_and_refuses_what_it_cannot_hold():
    table = ReturnReach((1.5, 0.05), {"A": (1.4, 0.03)})
    assert ReturnReach.from_dict(table.to_dict()) == table
    with pytest.raises(ValueError, match="positive"):
        ReturnReach((1.5, 0.0))
    with pytest.raises(ValueError, match="positive"):
        ReturnReach((1.5, 0.05), {"B": (float("nan"), 0.1)})
    with pytest.raises(ValueError, match="every serve returned or none"):
        fit_logistic(np.array([1.0, 2.0]), np.array([True, True]))
    with pytest.raises(ValueError, match="as many"):
        fit_logistic(np.array([1.0, 2.0]), np.array([True]))


def test_each_receiver_with_enough_serves_gets_his_own_row():
    parts = []
    for name, (c, s), n in (("A", (1.40, 0.05), 6000), ("B", (1.60, 0.05), 6000),
                            ("C", (1.20, 0.05), 50)):
        gap, returned = _serves(c, s, n, seed=len(parts))
        parts.append(pd.DataFrame({"receiver": name, "gap_m": gap, "answered": returned}))
    serves = pd.concat(parts, ignore_index=True)
    table = fit_return_reach(serves, min_serves=200)
    assert sorted(table.players) == ["A", "B"]
    assert abs(table.players["A"][0] - 1.40) < 0.015 and abs(table.players["B"][0] - 1.60) < 0.015
    assert 1.40 < table.pooled[0] < 1.60
    with pytest.raises(ValueError, match="columns"):
        fit_return_reach(serves.drop(columns="gap_m"))


def test_serve_rows_names_each_serves_server_and_receiver():
    rows = pd.DataFrame({"rally_id": [7, 7, 9], "shot": [0, 1, 0], "gap_m": [1.2, 0.5, 1.9],
                         "answered": [True, True, False]})
    rallies = pd.DataFrame({"rally_id": [9, 7], "server": ["A", "B"], "receiver": ["B", "A"]})
    out = serve_rows(rows, rallies)
    assert out.to_dict("list") == {"server": ["B", "A"], "receiver": ["A", "B"],
                                   "gap_m": [1.2, 1.9],
                                   "answered": [True, False]}


def test_the_rules_take_each_rows_own_return_reach():
    # Rows 0-2 await the return, row 3 a rally ball; each row's own return reach where given.
    tracker = SimpleNamespace(n_shots=np.array([1, 1, 1, 3]))
    rows_m = np.array([1.2, 1.4, 1.6, 1.3])
    assert return_reaches(tracker, np.arange(4), 1.5, rows_m, 1.8).tolist() == [1.2, 1.4, 1.6,
                                                                                1.8]
    assert return_reaches(tracker, np.array([3, 1]), 1.5, None, 1.8).tolist() == [1.8, 1.5]

    # The contact limit: the ball 1.3 m from the receiver, struck back. Allowed where his
    # reach is 1.4 or 1.6 m, refused at 1.2 m; the rally ball within the contact's 1.8 m.
    tr = SimpleNamespace(n_shots=np.array([1, 1, 1, 3]))
    pos = torch.zeros(4, 3, 3)
    pos[:, 0, :2] = torch.tensor([11.0, 0.0])
    pos[:, 1, :2] = torch.tensor([-11.0, 0.0])
    pos[:, 2] = torch.tensor([-11.0, 1.3, 1.0])
    vel = torch.zeros(4, 3, 3)
    vel[:, 2] = torch.tensor([-20.0, 0.0, -2.0])
    nxt = pos.clone()
    nxt[:, 2, 0] += 0.8
    lim = PhysicalLimits(fps=25.0, reach_m=1.8, tracker=tr)       # no fixed return reach
    assert lim.accept(np.arange(4), 10, pos, nxt, vel).all()
    lim.return_reach_rows_m = rows_m
    assert lim.accept(np.arange(4), 10, pos, nxt, vel).tolist() == [False, True, True, True]

    # The strike rule: the ball 1.36 m from him leaves unstruck: his to leave at a 1.2 m reach,
    # to strike at 1.4 and 1.6 m.
    tr = SimpleNamespace(ended=np.zeros(4, dtype=bool), hitter=np.zeros(4, dtype=np.int64),
                         n_bounces=np.ones(4, dtype=np.int64), server_end=np.ones(4),
                         n_shots=np.array([1, 1, 1, 3]))
    pos[:, 2] = torch.tensor([-10.6, 1.3, 1.0])
    nxt = pos.clone()
    nxt[:, 2, 0] -= 0.8
    nxt[:, 2, 1] += 0.7
    con = StrikeInReach(tr, reach_m=1.5, max_z_m=2.3, fps=25.0)
    assert con.accept(np.arange(4), 10, pos, nxt).tolist() == [False] * 4
    con.return_reach_rows_m = rows_m
    assert con.accept(np.arange(4), 10, pos, nxt).tolist() == [True, False, False, False]


def test_a_simulator_draws_each_serves_reach_from_the_files_table(tiny_model_file, tmp_path):
    import shutil

    from sportsngen.model.export import update_extra
    from sportsngen.sim.simulator import RETURN_REACH_STREAM, Simulator, points_plan

    path = shutil.copy(tiny_model_file, tmp_path / "with_reach.pt")
    table = ReturnReach((1.5, 0.05), {"Toy Gamma": (1.3, 0.04)})
    update_extra(path, return_reach=table.to_dict())
    plan = points_plan("Toy Alpha", "Toy Gamma", "hard", 6, seed=0)
    off = Simulator.from_pretrained(path, max_duration_s=1.5)
    assert off.return_reach == table and off._return_reaches(plan, 3, 0) is None
    assert Simulator.from_pretrained(tiny_model_file, return_reach_draw=True)._return_reaches(
        plan, 3, 0) is None                       # no table in the file: the fixed reaches
    sim = Simulator.from_pretrained(path, max_duration_s=1.5, strike_in_reach=True,
                                    return_reach_draw=True)
    got = sim._return_reaches(plan, 3, 0)
    want = table.draw(plan["receiver"].to_numpy(),
                      np.random.default_rng((3, 0, RETURN_REACH_STREAM)))
    assert np.array_equal(got, want) and 1.15 < got.mean() < 1.45
    a = sim.simulate_points("Toy Alpha", "Toy Gamma", "hard", 6, seed=3)
    b = sim.simulate_points("Toy Alpha", "Toy Gamma", "hard", 6, seed=3)
    pd.testing.assert_frame_equal(a.frames, b.frames)


def test_the_script_writes_the_table_and_the_default_into_a_copy(
        tiny_model_file, federer_points_and_head_model, tmp_path, monkeypatch, capsys):
    """`scripts/fit_return_reach.py` on a file, its training rallies stood in for by 80
    generated points: the copy carries the fitted table and draws from it; the source is left
    as it was."""
    import importlib.util
    import sys
    from pathlib import Path

    from sportsngen.model.export import read_extra
    from sportsngen.sim.simulator import Simulator

    path = Path(__file__).resolve().parents[1] / "scripts/fit_return_reach.py"
    spec = importlib.util.spec_from_file_location("fit_return_reach_script", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    data = federer_points_and_head_model[0]
    monkeypatch.setattr(script, "training_rally_data", lambda src, more: [data])
    out = tmp_path / "with_reach.pt"
    monkeypatch.setattr(sys, "argv", ["fit_return_reach.py", "--model", str(tiny_model_file),
                                      "--out", str(out)])
    script.main()
    assert "good serves" in capsys.readouterr().out
    table = ReturnReach.from_dict(read_extra(out)["return_reach"])
    assert table.players == {} and 1.2 < table.pooled[0] < 1.8     # 80 points: the pooled row
    assert Simulator.from_pretrained(out).return_reach_draw is True
    assert "return_reach" not in read_extra(tiny_model_file)
