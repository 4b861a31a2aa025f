"""A player's reach for the return and for the rally balls drawn from his record
(`sportsngen.sim.reach_table`) and the rollout rules that take it per row."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
import torch

from sportsngen.sim.constraints import PhysicalLimits, StrikeInReach, contact_reaches
from sportsngen.sim.reach_table import (
    MAX_REACH_M,
    MIN_REACH_M,
    ReachTable,
    fit_logistic,
    fit_reach_table,
    rally_rows,
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
    table = ReachTable((1.5, 0.05), {"Rafael Nadal": (1.43, 0.04), "Roger Federer": (1.55, 0.08)})
    rng = np.random.default_rng(3)
    for name, gap in (("Rafael Nadal", 1.40), ("Rafael Nadal", 1.48), ("Roger Federer", 1.60),
                      ("Somebody Else", 1.52)):
        reach = table.draw([name] * 40000, rng)
        want = float(table.answered_odds([name], [gap])[0])
        assert abs((reach >= gap).mean() - want) < 0.01, (name, gap)
    # An unknown receiver plays the pooled row; exact odds at the centre are one half.
    assert table.answered_odds(["Somebody Else"], [1.5]).tolist() == [0.5]
    c, s = table.centre_scale(["Roger Federer", "Nobody"])
    assert c.tolist() == [1.55, 1.5] and s.tolist() == [0.08, 0.05]
    wide = ReachTable((1.5, 2.0)).draw(["x"] * 5000, rng)
    assert wide.min() == MIN_REACH_M and wide.max() == MAX_REACH_M


def test_the_table_round_trips_and_refuses_what_it_cannot_hold():
    table = ReachTable((1.5, 0.05), {"A": (1.4, 0.03)})
    assert ReachTable.from_dict(table.to_dict()) == table
    with pytest.raises(ValueError, match="positive"):
        ReachTable((1.5, 0.0))
    with pytest.raises(ValueError, match="positive"):
        ReachTable((1.5, 0.05), {"B": (float("nan"), 0.1)})
    with pytest.raises(ValueError, match="every ball answered or none"):
        fit_logistic(np.array([1.0, 2.0]), np.array([True, True]))
    with pytest.raises(ValueError, match="as many"):
        fit_logistic(np.array([1.0, 2.0]), np.array([True]))


def test_each_receiver_with_enough_serves_gets_his_own_row():
    parts = []
    for name, (c, s), n in (("A", (1.40, 0.05), 6000), ("B", (1.60, 0.05), 6000),
                            ("C", (1.20, 0.05), 50)):
        gap, returned = _serves(c, s, n, seed=len(parts))
        parts.append(pd.DataFrame({"player": name, "gap_m": gap, "answered": returned}))
    serves = pd.concat(parts, ignore_index=True)
    table = fit_reach_table(serves, min_balls=200)
    assert sorted(table.players) == ["A", "B"]
    assert abs(table.players["A"][0] - 1.40) < 0.015 and abs(table.players["B"][0] - 1.60) < 0.015
    assert 1.40 < table.pooled[0] < 1.60
    with pytest.raises(ValueError, match="columns"):
        fit_reach_table(serves.drop(columns="gap_m"))


def test_serve_and_rally_rows_name_the_player_due_to_answer_each_ball():
    rows = pd.DataFrame({"rally_id": [7, 7, 9, 9, 9], "shot": [0, 1, 0, 1, 2],
                         "role": ["receiver", "server", "receiver", "server", "receiver"],
                         "gap_m": [1.2, 0.5, 1.9, 1.0, 1.7],
                         "answered": [True, True, False, True, False]})
    rallies = pd.DataFrame({"rally_id": [9, 7], "server": ["A", "B"], "receiver": ["B", "A"]})
    out = serve_rows(rows, rallies)
    assert out.to_dict("list") == {"server": ["B", "A"], "receiver": ["A", "B"],
                                   "player": ["A", "B"], "shot": [0, 0], "gap_m": [1.2, 1.9],
                                   "answered": [True, False]}
    out = rally_rows(rows, rallies)
    assert out.to_dict("list") == {"server": ["B", "A", "A"], "receiver": ["A", "B", "B"],
                                   "player": ["B", "A", "B"], "shot": [1, 1, 2],
                                   "gap_m": [0.5, 1.0, 1.7], "answered": [True, True, False]}


def test_the_rules_take_each_rows_own_return_reach():
    # Rows 0-2 await the return, row 3 a rally ball; each row's own return reach where given.
    tracker = SimpleNamespace(n_shots=np.array([1, 1, 1, 3]))
    rows_m = np.array([1.2, 1.4, 1.6, 1.3])
    assert contact_reaches(tracker, np.arange(4), 1.5, rows_m, 1.8).tolist() == [1.2, 1.4, 1.6,
                                                                                1.8]
    assert contact_reaches(tracker, np.array([3, 1]), 1.5, None, 1.8).tolist() == [1.8, 1.5]

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
    table = ReachTable((1.5, 0.05), {"Toy Gamma": (1.3, 0.04)})
    update_extra(path, return_reach=table.to_dict())
    plan = points_plan("Toy Alpha", "Toy Gamma", "hard", 6, seed=0)
    off = Simulator.from_pretrained(path, max_duration_s=1.5)
    assert off.return_reach == table and off._return_reaches(plan, 3, 0) is None
    assert Simulator.from_pretrained(tiny_model_file, return_reach_draw=True)._return_reaches(
        plan, 3, 0) is None                       # no table in the file: the fixed reaches
    sim = Simulator.from_pretrained(path, max_duration_s=1.5, physical_limits=False,
                                    strike_in_reach=True, return_reach_draw=True)
    got = sim._return_reaches(plan, 3, 0)
    want = table.draw(plan["receiver"].to_numpy(),
                      np.random.default_rng((3, 0, RETURN_REACH_STREAM)))
    assert np.array_equal(got, want) and 1.15 < got.mean() < 1.45
    a = sim.simulate_points("Toy Alpha", "Toy Gamma", "hard", 6, seed=3)
    b = sim.simulate_points("Toy Alpha", "Toy Gamma", "hard", 6, seed=3)
    pd.testing.assert_frame_equal(a.frames, b.frames)


def test_the_fit_writes_the_table_and_the_default_into_a_copy(
        tiny_model_file, federer_points_and_head_model, tmp_path, monkeypatch, capsys):
    """`fit_return_reach_file` (`scripts/fit_return_reach.py`) on a file, its training rallies
    stood in for by 80 generated points: the copy carries the fitted table and draws from it;
    the source is left as it was."""
    from sportsngen.model.export import read_extra
    from sportsngen.sim.simulator import Simulator
    from sportsngen.train import rule_tables

    data = federer_points_and_head_model[0]
    monkeypatch.setattr(rule_tables, "training_rally_data", lambda src, more: [data])
    out = tmp_path / "with_reach.pt"
    rule_tables.fit_return_reach_file(str(tiny_model_file), str(out))
    assert "good serves" in capsys.readouterr().out
    table = ReachTable.from_dict(read_extra(out)["return_reach"])
    assert table.players == {} and 1.2 < table.pooled[0] < 1.8     # 80 points: the pooled row
    assert Simulator.from_pretrained(out).return_reach_draw is True
    assert "return_reach" not in read_extra(tiny_model_file)


def test_the_rules_take_each_rally_balls_own_reach():
    # Row 0 awaits the return (its own return reach), rows 1-3 rally balls: contact k reads
    # column k mod 4 of its row.
    tracker = SimpleNamespace(n_shots=np.array([1, 2, 3, 6]))
    rally_m = np.array([[9.0, 9.0, 9.0, 9.0], [9.0, 9.0, 1.1, 9.0], [9.0, 9.0, 9.0, 1.7],
                        [9.0, 9.0, 2.0, 9.0]])
    rows_m = np.array([1.4, 9.0, 9.0, 9.0])
    assert contact_reaches(tracker, np.arange(4), None, rows_m, 1.8,
                           rally_m).tolist() == [1.4, 1.1, 1.7, 2.0]
    # Without a per-row return reach or a fixed one the return takes the rally's fixed reach.
    assert contact_reaches(tracker, np.array([0, 2]), None, None, 1.8,
                           rally_m).tolist() == [1.8, 1.7]

    # The contact limit and the strike rule on a rally ball (the server's, shot 2) 1.3 m from
    # the receiver: struck back, refused where his reach is 1.2 m; leaving him unstruck,
    # refused where it is 1.4 m.
    tr = SimpleNamespace(n_shots=np.array([2, 2]), ended=np.zeros(2, dtype=bool),
                         hitter=np.zeros(2, dtype=np.int64), n_bounces=np.ones(2, dtype=np.int64),
                         server_end=np.ones(2))
    reach = np.array([[1.2] * 4, [1.4] * 4])
    pos = torch.zeros(2, 3, 3)
    pos[:, 0, :2] = torch.tensor([11.0, 0.0])
    pos[:, 1, :2] = torch.tensor([-11.0, 0.0])
    pos[:, 2] = torch.tensor([-11.0, 1.3, 1.0])
    vel = torch.zeros(2, 3, 3)
    vel[:, 2] = torch.tensor([-20.0, 0.0, -2.0])
    back = pos.clone()
    back[:, 2, 0] += 0.8
    lim = PhysicalLimits(fps=25.0, reach_m=1.8, tracker=tr)
    assert lim.accept(np.arange(2), 10, pos, back, vel).all()
    lim.rally_reach_rows_m = reach
    assert lim.accept(np.arange(2), 10, pos, back, vel).tolist() == [False, True]
    pos[:, 2] = torch.tensor([-10.6, 1.3, 1.0])
    past = pos.clone()
    past[:, 2, 0] -= 0.8
    past[:, 2, 1] += 0.7
    con = StrikeInReach(tr, reach_m=1.5, max_z_m=2.3, fps=25.0)
    assert con.accept(np.arange(2), 10, pos, past).tolist() == [False, False]
    con.rally_reach_rows_m = reach
    assert con.accept(np.arange(2), 10, pos, past).tolist() == [True, False]


def test_a_simulator_draws_each_rally_balls_reach_from_the_player_due(tiny_model_file,
                                                                       tmp_path):
    import shutil

    from sportsngen.model.export import update_extra
    from sportsngen.sim.simulator import (
        RALLY_REACH_DRAWS,
        RALLY_REACH_STREAM,
        Simulator,
        points_plan,
    )

    path = shutil.copy(tiny_model_file, tmp_path / "with_rally_reach.pt")
    table = ReachTable((1.8, 0.2), {"Toy Alpha": (1.2, 0.01), "Toy Gamma": (2.1, 0.01)})
    update_extra(path, rally_reach=table.to_dict())
    plan = points_plan("Toy Alpha", "Toy Gamma", "hard", 6, seed=0)
    assert Simulator.from_pretrained(path)._rally_reaches(plan, 3, 0) is None    # off
    sim = Simulator.from_pretrained(path, max_duration_s=1.5, physical_limits=False,
                                    strike_in_reach=True, rally_reach_draw=True)
    assert sim.rally_reach == table
    got = sim._rally_reaches(plan, 3, 0)
    assert got.shape == (6, RALLY_REACH_DRAWS)
    # The receiver is due at odd contacts (1 the return), the server at even ones.
    server_gamma = (plan["server"] == "Toy Gamma").to_numpy()
    odd = np.arange(RALLY_REACH_DRAWS) % 2 == 1
    gamma_due = server_gamma[:, None] ^ odd[None, :]
    assert (np.abs(got[gamma_due] - 2.1) < 0.1).all()
    assert (np.abs(got[~gamma_due] - 1.2) < 0.1).all()
    due = np.where(gamma_due, "Toy Gamma", "Toy Alpha")
    assert np.array_equal(got, table.draw(due, np.random.default_rng((3, 0, RALLY_REACH_STREAM))))
    a = sim.simulate_points("Toy Alpha", "Toy Gamma", "hard", 6, seed=3)
    b = sim.simulate_points("Toy Alpha", "Toy Gamma", "hard", 6, seed=3)
    pd.testing.assert_frame_equal(a.frames, b.frames)


def test_the_fit_takes_the_rally_balls_table_with_rally(
        tiny_model_file, federer_points_and_head_model, tmp_path, monkeypatch, capsys):
    """`rally=True, serves_too=True` (`--rally --serves-too`) writes both tables and both
    defaults; `rally` alone only the rally balls' (pooled rows: 80 points are too few for a
    player's own)."""
    from sportsngen.model.export import read_extra
    from sportsngen.sim.simulator import Simulator
    from sportsngen.train import rule_tables

    data = federer_points_and_head_model[0]
    monkeypatch.setattr(rule_tables, "training_rally_data", lambda src, more: [data])
    both, rally = tmp_path / "both.pt", tmp_path / "rally.pt"
    for out, flags in ((both, {"rally": True, "serves_too": True}), (rally, {"rally": True})):
        rule_tables.fit_return_reach_file(str(tiny_model_file), str(out), **flags)
    printed = capsys.readouterr().out
    assert printed.count("good serves") == 1 and printed.count("good rally balls") == 2
    extra = read_extra(both)
    assert ReachTable.from_dict(extra["return_reach"]).players == {}
    pooled = ReachTable.from_dict(extra["rally_reach"]).pooled
    assert 1.0 < pooled[0] < 2.5 and pooled[1] > 0
    assert "return_reach" not in read_extra(rally) and "rally_reach" in read_extra(rally)
    sim = Simulator.from_pretrained(both)
    assert sim.rally_reach_draw is True and sim.return_reach_draw is True
    assert Simulator.from_pretrained(rally).return_reach_draw is False
