"""The learned engine end to end with a tiny model: rollouts, initial conditions, matches."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch
from hydra import compose, initialize_config_dir

from sportsngen.data.points import POINTS_DTYPES
from sportsngen.data.serve_starts import InitialConditions
from sportsngen.data.toy import make_toy_rallies
from sportsngen.eval.stats import serve_stats
from sportsngen.model.export import load_model, save_model
from sportsngen.model.inputs import flip_xy
from sportsngen.sim import Simulator
from sportsngen.sim.assemble import rules_shot_outcome
from sportsngen.sim.rollout import RolloutInputs, cpu_threads, rollout
from sportsngen.tennis.scoring import MatchFormat, MatchState

REPO = Path(__file__).resolve().parents[1]
SHORT = MatchFormat(best_of=1, games_per_set=2, tiebreak_at=1, no_ad=True)


_LOAD = Simulator.from_pretrained


def _sim(path, **kw) -> Simulator:
    """The tiny model's Simulator: short unretried rallies, without the physical limits unless a
    test asks for them (drawing the untrained model's frames again until they pass was most of
    these tests' time, conftest.tiny_sim)."""
    return _LOAD(path, **{"max_duration_s": 1.2, "max_retries": 0, "physical_limits": False,
                          **kw})


def test_tiny_model_simulates_a_short_match(tiny_model_file):
    sim = _sim(tiny_model_file)
    res = sim.simulate_match("Toy Alpha", "Toy Beta", "hard", fmt=SHORT, seed=0,
                             progress=False)
    assert res.state.is_over
    assert res.winner in ("Toy Alpha", "Toy Beta")
    assert re.fullmatch(r"Toy (Alpha|Beta) d\. Toy (Alpha|Beta) \d-\d(\(\d+\))?", res.score_line)
    pts = res.points
    assert list(pts.columns) == list(POINTS_DTYPES)
    assert len(pts) == res.state.points_played
    # Replaying the points table's winners through the scoring gives the same final score.
    names = ("Toy Alpha", "Toy Beta")
    first = names.index(pts["server"].iat[0])
    state = MatchState.new(SHORT, first_server=first)
    for w in pts["winner"]:
        state = state.point_won(names.index(w))
    assert state.is_over and state.score_str() == res.state.score_str()
    stats = serve_stats(pts)
    assert set(stats.index) <= {"Toy Alpha", "Toy Beta"}
    r = res.rallies.rallies
    assert (r["realistic"] | (r["end_reason"] != "none")).all()
    # With no replays nothing is set aside, and each rally that was not realistic, or that
    # the rules left undecided (its winner then tossed: end_detail "none"), is counted forced:
    # a count of rallies, not points (the CLI had printed 28 "points" of a 25-point match).
    assert res.n_discarded == 0 and res.forced_decisions > 0
    assert res.forced_decisions == int((~r["realistic"] | (r["end_detail"] == "none")).sum())
    assert set(res.rallies.frames["rally_id"]) == set(r["rally_id"])
    # The shots table tells each rally's end as the rallies table does (the rules').
    shots = res.rallies.shots.sort_values(["rally_id", "shot_index"])
    is_last = shots.groupby("rally_id")["shot_index"].transform("max") == shots["shot_index"]
    assert (shots.loc[~is_last, "outcome"] == "in_play").all()
    # (a point given by a coin toss keeps end_detail "none" and its shots as they were played)
    tossed = r.loc[r["end_detail"] == "none", "rally_id"]
    last = shots[is_last & ~shots["rally_id"].isin(tossed)].set_index("rally_id")
    assert len(last) > 0
    end = r.set_index("rally_id").loc[last.index, "end_reason"]
    for reason, outcome, kind in zip(end, last["outcome"], last["error_kind"]):
        assert (outcome, kind) == rules_shot_outcome(reason, 0, 1)


def test_simulate_points_is_deterministic_for_a_seed(tiny_model_file):
    sim = _sim(tiny_model_file, max_duration_s=1.5)
    a = sim.simulate_points("Toy Alpha", "Toy Gamma", "hard", 6, seed=3)
    b = sim.simulate_points("Toy Alpha", "Toy Gamma", "hard", 6, seed=3)
    c = sim.simulate_points("Toy Alpha", "Toy Gamma", "hard", 6, seed=4)
    pd.testing.assert_frame_equal(a.frames, b.frames)
    pd.testing.assert_frame_equal(a.rallies, b.rallies)
    assert not np.allclose(a.frames["x"].to_numpy()[:300], c.frames["x"].to_numpy()[:300])
    r = a.rallies
    assert "realistic" in r.columns and r["realistic"].dtype == bool
    assert (r.loc[r["serve_number"] == 2, "point"].isin(
        r.loc[(r["serve_number"] == 1) & (r["end_reason"] == "fault"), "point"])).all()
    # Every rally starts at frame 0 with the server, the receiver and the ball.
    f0 = a.frames[a.frames["frame"] == 0]
    assert (f0.groupby("rally_id").size() == 3).all()


def test_rollout_cache_recompute_and_window_agree(tiny_model_file):
    model, _, _, cfg = load_model(tiny_model_file)
    w = cfg.window_frames
    rng = np.random.default_rng(0)
    b = 3
    init = rng.normal(0, 1, (b, 2, 3, 3)).astype(np.float32)
    init[..., 2] = np.abs(init[..., 2])
    inputs = RolloutInputs(init, np.tile([[2, 3, 0]], (b, 1)), np.zeros(b, np.int64),
                           np.zeros(b, np.int64), np.zeros(b, np.int64),
                           np.zeros((b, 7), np.float32))
    n = w + 6
    cache = rollout(model, inputs, n, seed=1, mode="cache", top_p_ball=0.9)
    full = rollout(model, inputs, n, seed=1, mode="recompute", top_p_ball=0.9)
    short = rollout(model, inputs, w, seed=1, mode="window", top_p_ball=0.9)
    assert cache.pos_m.shape == (b, n, 3, 3) and (cache.length == n).all()
    np.testing.assert_allclose(cache.pos_m, full.pos_m, atol=1e-4)
    # Until the rally outgrows the window, the naive rolling window is the same model.
    np.testing.assert_allclose(cache.pos_m[:, :w], short.pos_m, atol=1e-4)
    assert (cache.pos_m[:, 2:, :2, 2] == 0).all()       # sampled players on the ground
    with pytest.raises(ValueError, match="mode"):
        rollout(model, inputs, n, mode="fast")
    # A cache re-filled from the last window on every frame is the rolling window, past the
    # window too (a training window's view); never re-filled, it is the band.
    every = rollout(model, inputs, n, seed=1, mode="cache", top_p_ball=0.9, refresh_frames=1)
    window = rollout(model, inputs, n, seed=1, mode="window", top_p_ball=0.9)
    np.testing.assert_allclose(every.pos_m, window.pos_m, atol=1e-4)
    assert not np.allclose(every.pos_m[:, w + 1:], cache.pos_m[:, w + 1:], atol=1e-3)
    np.testing.assert_allclose(every.pos_m[:, :w + 1], cache.pos_m[:, :w + 1], atol=1e-4)


def test_initial_conditions_draw_rotate_and_round_trip():
    data = make_toy_rallies(12, seed=2)
    ic = InitialConditions.from_rally_data(data, n_frames=4, max_per_key=50)
    assert ic.pos_m.shape[1:] == (4, 3, 3) and len(ic) == len(data)
    i = 0
    s, n, side, e = ic.server[i], int(ic.serve_number[i]), ic.side[i], int(ic.server_end[i])
    only = (ic.server == s) & (ic.serve_number == n) & (ic.side == side)
    rng = np.random.default_rng(0)
    same = ic.draw(s, n, side, e, rng)
    other = ic.draw(s, n, side, -e, np.random.default_rng(0))
    np.testing.assert_array_equal(other, flip_xy(same))
    assert any(np.array_equal(same, p) for p in ic.pos_m[only])
    back = InitialConditions.from_dict(ic.to_dict())
    np.testing.assert_array_equal(back.pos_m, ic.pos_m)
    with pytest.raises(ValueError, match="side"):
        ic.draw(s, n, "middle", e, rng)


def test_initial_conditions_put_the_receiver_at_his_own_stance():
    data = make_toy_rallies(40, seed=3)
    ic = InitialConditions.from_rally_data(data, n_frames=4, max_per_key=50)
    assert ic.receiver is not None and len(set(ic.receiver)) >= 2
    i = 0
    s, n, side, e = ic.server[i], int(ic.serve_number[i]), ic.side[i], int(ic.server_end[i])
    rcv = ic.receiver[i]
    for seed in range(10):
        got = ic.draw(s, n, side, e, np.random.default_rng(seed), receiver=rcv)
        own = (ic.receiver == rcv) & (ic.serve_number == n) & (ic.side == side)
        # The receiver's frames are one of his own examples', turned to this end; the server
        # and the ball one of the server's.
        turned = [p if int(ic.server_end[j]) == e else flip_xy(p)
                  for j, p in zip(np.flatnonzero(own), ic.pos_m[own])]
        assert any(np.array_equal(got[:, 1], p[:, 1]) for p in turned)
        mine = (ic.server == s) & (ic.serve_number == n) & (ic.side == side)
        turned = [p if int(ic.server_end[j]) == e else flip_xy(p)
                  for j, p in zip(np.flatnonzero(mine), ic.pos_m[mine])]
        assert any(np.array_equal(got[:, [0, 2]], p[:, [0, 2]]) for p in turned)
    # A pool stored without receivers (older model files) draws as before.
    old = InitialConditions.from_dict({**ic.to_dict(), "receiver": None})
    assert old.receiver is None
    np.testing.assert_array_equal(
        old.draw(s, n, side, e, np.random.default_rng(4), receiver=rcv),
        ic.draw(s, n, side, e, np.random.default_rng(4)))
    back = InitialConditions.from_dict(ic.to_dict())
    assert back.receiver.tolist() == ic.receiver.tolist()
    assert ic.merged(old).receiver is None and len(ic.merged(ic).receiver) == 2 * len(ic)


def test_simulator_bad_input(tiny_model_file, tmp_path):
    with pytest.raises(ValueError, match="top_p_ball"):
        _sim(tiny_model_file, top_p_ball=0.0)
    model, ec, vocab, _ = load_model(tiny_model_file)
    bare = save_model(tmp_path / "bare.pt", model, vocab, ec)
    with pytest.raises(ValueError, match="initial conditions"):
        Simulator.from_pretrained(bare)
    sim = _sim(tiny_model_file, max_duration_s=0.5)
    with pytest.warns(UserWarning, match="Nobody"):
        sim.simulate_points("Nobody", "Toy Beta", "hard", 1, seed=0, serve_number=1)
    with pytest.raises(ValueError, match="matchups"):
        sim.simulate_matches([("Toy Alpha", "Toy Alpha")], "hard")
    torch.manual_seed(0)


def test_stored_sim_defaults_are_defaults_and_arguments_win(tiny_model_file, tmp_path):
    import shutil

    from sportsngen.model.export import update_extra

    path = shutil.copy(tiny_model_file, tmp_path / "with_defaults.pt")
    update_extra(path, sim_defaults={"top_p_player": 1.0, "top_p_ball": 0.45,
                                     "contact_odds": True})
    sim = Simulator.from_pretrained(path)
    assert sim.top_p_ball == 0.45 and sim.contact_odds is True
    sim = Simulator.from_pretrained(path, contact_odds=False, top_p_ball=0.9)
    assert sim.top_p_ball == 0.9 and sim.contact_odds is False
    assert Simulator.from_pretrained(tiny_model_file).contact_odds is False
    update_extra(path, sim_defaults={"top_p_ball": 0.45, "contact_odds": True,
                                     "top_p_contact": 0.8})
    assert Simulator.from_pretrained(path).top_p_contact == 0.8
    assert Simulator.from_pretrained(tiny_model_file).top_p_contact is None
    with pytest.raises(ValueError, match="top_p_contact"):
        Simulator.from_pretrained(tiny_model_file, top_p_contact=1.5)
    with pytest.raises(ValueError, match="refresh_frames"):
        Simulator.from_pretrained(tiny_model_file, refresh_frames=0)
    assert Simulator.from_pretrained(tiny_model_file, refresh_frames=25.0).refresh_frames == 25
    # A stored refresh (the bundled file's, written as a float) is an int; None asked for
    # explicitly is the band, whatever the file stores.
    update_extra(path, sim_defaults={"refresh_frames": 25.0})
    assert Simulator.from_pretrained(path).refresh_frames == 25
    assert Simulator.from_pretrained(path, refresh_frames=None).refresh_frames is None


def test_simulate_py_learned_engine_writes_outputs(tiny_model_file, tmp_path, capsys):
    from sportsngen.cli.simulate import run_simulation

    over = [f"output_dir={tmp_path}", "engine=sportsngen", f"model_file={tiny_model_file}",
            "player1=Toy Alpha", "player2=Toy Beta", "format.best_of=1",
            "format.games_per_set=2", "format.tiebreak_at=1", "format.no_ad=true", "top_p=0.9",
            "animation_max_frames=12", "report_whatif_rollouts=4", "lookahead=0"]
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base=None):
        cfg = compose("simulate", overrides=over)
    # Keep the CLI quick: short, unretried rallies, no physical limits (redrawing the untrained
    # model's frames would be most of its time; the limits are tested above).
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Simulator, "from_pretrained", classmethod(
            lambda cls, path, **kw: _sim(path, **kw)))
        points = run_simulation(cfg)
    assert len(points) > 0 and set(points["winner"]) <= {"Toy Alpha", "Toy Beta"}
    for name in ("points.parquet", "rallies/rallies.parquet", "rally_1.png", "point.gif",
                 "report.html"):
        assert (tmp_path / name).exists(), name
    from PIL import Image

    with Image.open(tmp_path / "point.gif") as gif:
        assert 2 <= gif.n_frames <= 12
    out = capsys.readouterr().out
    assert "match 1: Toy" in out and "1st in" in out


def test_rules_shot_outcome_labels_shots_as_the_generator_does():
    assert rules_shot_outcome("ace", 0, 1) == ("winner", "none")
    assert rules_shot_outcome("winner", 4, 5) == ("winner", "none")
    assert rules_shot_outcome("winner", 3, 5) == ("in_play", "none")
    assert rules_shot_outcome("fault", 0, 1) == ("error", "fault")
    assert rules_shot_outcome("double_fault", 0, 1) == ("error", "fault")
    assert rules_shot_outcome("forced_error", 2, 3) == ("error", "forced")
    assert rules_shot_outcome("unforced_error", 1, 2) == ("error", "unforced")
    assert rules_shot_outcome("unforced_error", 0, 2) == ("in_play", "none")
    assert rules_shot_outcome("none", 6, 7) == ("in_play", "none")
    with pytest.raises(ValueError, match="unknown end_reason"):
        rules_shot_outcome("let", 0, 1)
    with pytest.raises(ValueError, match="outside a rally"):
        rules_shot_outcome("ace", 1, 1)


def test_a_serves_direction_is_its_bounces_third_of_the_box_not_the_classifiers_label():
    from sportsngen.data.tracking import DIRECTIONS
    from sportsngen.sim.assemble import PLAN_COLUMNS, assemble

    plan = make_toy_rallies(3, seed=0).rallies.iloc[:3][PLAN_COLUMNS].reset_index(drop=True)
    n = 10
    pos = np.zeros((3, n, 3, 3))
    # The classifier calls every frame "T" (what it said of every cut-short fault).
    labels = np.zeros((3, n, 4), dtype=np.int64)
    labels[:, :, 1] = DIRECTIONS.index("T")
    results = pd.DataFrame({
        "contact_frames": [[1], [1], [1, 6]], "hitters": [[0], [0], [0, 1]],
        "contacts_m": [[[11.9, 1.0, 2.8]]] * 2 + [[[11.9, 1.0, 2.8], [-12.0, -3.0, 1.0]]],
        # a fault past the sideline, a serve into the net (no bounce), a serve to the body
        "bounce_frames": [[4], [], [4]],
        "bounces_m": [[[-5.0, -4.5]], [], [[-5.0, -2.0]]],
        "end_reason": ["fault", "fault", "none"], "end_detail": ["out", "net", "none"],
        "winner": [1, 1, -1], "n_shots": [1, 1, 2], "realistic": [True] * 3,
        "failed_checks": [[], [], []]})
    shots = assemble(plan, pos, np.full(3, n), results, labels, fps=25.0).shots
    serves = shots[shots["shot_index"] == 0].set_index("rally_id")["direction"]
    assert serves.tolist() == ["wide", "T", "body"]
    # Rally shots keep the classifier's label.
    assert shots.loc[shots["shot_index"] == 1, "direction"].tolist() == ["T"]


def test_wilson_interval_known_values():
    from sportsngen.sim.whatif import wilson_interval

    lo, hi = wilson_interval(50, 100)
    assert abs(lo - 0.4038) < 1e-4 and abs(hi - 0.5962) < 1e-4
    assert wilson_interval(0, 10)[0] == 0.0 and np.isnan(wilson_interval(0, 0)[0])


def test_shot_constraint_judges_the_landing_of_the_ball_leaving_the_hitter():
    from sportsngen.sim.whatif import ShotConstraint

    def step(ball_now, ball_next):
        pos = torch.zeros(1, 3, 3)
        pos[0, 0] = torch.tensor([11.0, 0.5, 0.0])
        nxt = pos.clone()
        pos[0, 2] = torch.tensor(ball_now)
        nxt[0, 2] = torch.tensor(ball_next)
        return pos, nxt

    # From (10, 0, 1) at (-20, -5, 2) m/s the ballistic landing is (-3.99, -3.50).
    pos, nxt = step([10.8, 0.2, 0.92], [10.0, 0.0, 1.0])
    inside = ShotConstraint((-5.0, -3.0, -4.0, -3.0), 0, 1, "right", "forehand", "deuce", 5)
    outside = ShotConstraint((-5.0, -3.0, 3.0, 4.0), 0, 1, "right", "forehand", "deuce", 5)
    assert inside.accept(np.array([0]), 5, pos, nxt).tolist() == [True] and inside.done == {0}
    assert outside.accept(np.array([0]), 5, pos, nxt).tolist() == [False]
    # A ball still coming toward the hitter is not judged yet.
    pos2, nxt2 = step([9.0, 0.0, 1.0], [10.0, 0.0, 1.0])
    waiting = ShotConstraint((-5.0, -3.0, 3.0, 4.0), 0, 1, "right", "forehand", "deuce", 5)
    assert waiting.accept(np.array([0]), 5, pos2, nxt2).tolist() == [True]
    assert waiting.done == set()


def test_rally_win_probability_and_counterfactual_run_on_a_real_rally(tiny_model_file):
    sim = _sim(tiny_model_file, max_duration_s=1.6)
    data = make_toy_rallies(4, seed=3)
    rid = int(data.rallies["rally_id"].iat[0])
    from sportsngen.sim.whatif import rally_win_probability

    d = rally_win_probability(sim, data, rid, frame=10, n=8, seed=0, details=True)
    assert d["n_sims"] == 8 and d["n"] + d["n_unrealistic"] == 8
    assert np.isnan(d["p"]) or 0.0 <= d["p"] <= 1.0
    table = sim.counterfactual(data, rid, shot_index=1, n=6, seed=0)
    assert list(table.columns) == ["option", "win_probability", "ci_low", "ci_high", "n",
                                   "n_sims", "n_unrealistic", "n_forced_failed"]
    assert table["option"].tolist() == ["cross_court", "down_the_line"]
    assert (table["n_sims"] == 6).all()
    with pytest.raises(ValueError, match="outside rally"):
        sim.rally_win_probability(data, rid, frame=10 ** 6, n=2)
    with pytest.raises(ValueError, match="no shot 99"):
        sim.counterfactual(data, rid, shot_index=99, n=2)


def test_calibrated_rally_win_probability_maps_the_raw_one(tiny_model_file, monkeypatch,
                                                          tmp_path):
    import shutil

    from sportsngen.eval.calibration import IsotonicCalibrator
    from sportsngen.model.export import update_extra
    from sportsngen.sim import whatif

    data = make_toy_rallies(2, seed=3)
    rid = int(data.rallies["rally_id"].iat[0])
    with pytest.raises(ValueError, match="no outcome calibrator"):
        _sim(tiny_model_file).rally_win_probability(data, rid, 10, n=2, calibrated=True)
    path = shutil.copy(tiny_model_file, tmp_path / "calibrated.pt")
    update_extra(path, outcome_calibrator=IsotonicCalibrator.from_dict(
        {"x": [0.2, 0.6], "y": [0.3, 0.5]}).to_dict())
    sim = _sim(path)
    monkeypatch.setattr(whatif, "rally_win_probability", lambda *a, **k: 0.4)
    assert sim.rally_win_probability(data, rid, 10, n=2) == 0.4
    assert sim.rally_win_probability(data, rid, 10, n=2, calibrated=True) == pytest.approx(0.4)
    monkeypatch.setattr(whatif, "rally_win_probability", lambda *a, **k: 0.9)
    assert sim.rally_win_probability(data, rid, 10, n=2, calibrated=True) == pytest.approx(0.5)
    # A logistic map (the study's default): sigmoid(a + b * logit(p)).
    update_extra(path, outcome_calibrator={"kind": "logistic", "a": 0.5, "b": 2.0, "eps": 0.01})
    sim = _sim(path)
    assert sim.rally_win_probability(data, rid, 10, n=2, calibrated=True) == pytest.approx(
        1 / (1 + math.exp(-(0.5 + 2.0 * math.log(9)))))


def test_counterfactual_plot(tiny_model_file, tmp_path):
    from sportsngen.sim.whatif import counterfactual
    from sportsngen.viz.counterfactual_plot import plot_counterfactual

    sim = _sim(tiny_model_file, max_duration_s=1.6)
    data = make_toy_rallies(2, seed=3)
    rid = int(data.rallies["rally_id"].iat[0])
    table, branches = counterfactual(sim, data, rid, 1, n=3, seed=0, return_branches=True)
    assert set(branches) == {"cross_court", "down_the_line"}
    frame = int(data.shots[data.shots["rally_id"] == rid]["frame"].iat[1]) - 1
    plot_counterfactual(data, rid, table, branches, frame, tmp_path / "cf.png")
    assert (tmp_path / "cf.png").read_bytes()[:4] == b"\x89PNG"


def test_physical_limits_reject_ball_below_ground_and_through_the_net():
    from sportsngen.sim.constraints import AllOf, PhysicalLimits

    lim = PhysicalLimits()
    pos = torch.zeros(4, 3, 3)
    nxt = torch.zeros(4, 3, 3)
    pos[:, 2] = torch.tensor([[0.5, 0.0, 1.0]] * 4)
    nxt[:, 2] = torch.tensor([[-0.5, 0.0, 1.2],     # over the cord (0.914 m at y = 0): fine
                              [-0.5, 0.0, 0.5],     # crossing at 0.75 m: through the net
                              [0.3, 0.0, -0.10],    # 10 cm under the ground
                              [0.3, 0.0, 0.0]])     # on the ground: fine
    assert lim.accept(np.arange(4), 5, pos, nxt).tolist() == [True, False, False, True]
    fixed = lim.project(pos, nxt)
    # Through the net: stopped 5 cm before it, at the height it met the net (0.75 m).
    np.testing.assert_allclose(fixed[1, 2].numpy(), [0.05, 0.0, 0.75], atol=1e-6)
    assert fixed[2, 2, 2].item() == 0.0                        # lifted onto the ground
    assert torch.equal(fixed[0], nxt[0]) and torch.equal(fixed[3], nxt[3])
    assert lim.projected == 1
    both = AllOf(lim, None)
    both.offset = 3
    assert lim.offset == 3 and both.max_tries == lim.max_tries


def test_simulator_counts_resampled_frames(tiny_model_file):
    sim = _sim(tiny_model_file, max_duration_s=1.2, physical_limits=True)
    d = sim.simulate_points("Toy Alpha", "Toy Beta", "hard", 4, seed=0, serve_number=1)
    assert "resampled_frames" in d.rallies.columns and (d.rallies["resampled_frames"] >= 0).all()
    off = _sim(tiny_model_file, max_duration_s=1.2, physical_limits=False)
    d2 = off.simulate_points("Toy Alpha", "Toy Beta", "hard", 4, seed=0, serve_number=1)
    assert (d2.rallies["resampled_frames"] == 0).all()


def test_concat_renumber_makes_ids_unique_and_leaves_parts_alone():
    from sportsngen.data.tracking import RallyData

    a, b = make_toy_rallies(3, seed=1), make_toy_rallies(2, seed=2)
    ids_a = a.rallies["rally_id"].tolist()
    both = RallyData.concat([a, b], renumber=True)
    r = both.rallies
    assert r["rally_id"].is_unique and len(r) == 5
    assert set(both.frames["rally_id"]) == set(r["rally_id"]) >= set(both.shots["rally_id"])
    assert r["match_id"].str[:2].tolist() == ["0-"] * 3 + ["1-"] * 2
    assert a.rallies["rally_id"].tolist() == ids_a                 # parts unchanged
    # Points stay points: the same count as the two parts' points together.
    assert len(both.points()) == len(a.points()) + len(b.points())


def test_cpu_threads_lowers_then_restores_the_thread_count():
    before = torch.get_num_threads()
    with cpu_threads(1):
        assert torch.get_num_threads() == 1
    assert torch.get_num_threads() == before
    with pytest.raises(RuntimeError, match="boom"), cpu_threads(1):
        raise RuntimeError("boom")
    assert torch.get_num_threads() == before
    with cpu_threads(before + 4):          # never raises the count
        assert torch.get_num_threads() == before


def test_physical_limits_reject_a_ball_struck_back_out_of_everyones_reach():
    from sportsngen.sim.constraints import PhysicalLimits

    lim = PhysicalLimits(fps=25.0)
    pos = torch.zeros(5, 3, 3)
    pos[:, 0, :2] = torch.tensor([11.0, 0.0])             # server at his baseline
    pos[:, 1, :2] = torch.tensor([-11.0, 0.0])            # receiver at his
    pos[:, 2] = torch.tensor([[-8.0, 0.0, 1.0],           # 3 m in front of the receiver
                              [-9.0, 1.0, 1.0],           # 2.2 m from him
                              [-8.0, 0.0, 1.0],
                              [-0.5, 0.0, 0.8],           # at the net
                              [-9.0, 1.0, 3.8]])          # near him but over any racket
    vel = torch.zeros(5, 3, 3)
    vel[:, 2] = torch.tensor([-20.0, 0.0, -2.0])          # flying toward the receiver
    nxt = pos.clone()
    nxt[:, 2, 0] += torch.tensor([0.8, 0.8, -0.8, 0.1, 0.8])  # back 20 m/s, or on (row 2)
    ok = lim.accept(np.arange(5), 10, pos, nxt, vel)
    assert ok.tolist() == [False, True, True, True, False]
    # A player's own reach (the generator's players strike within about 2 m): the ball 2.2 m
    # from the receiver is out of it.
    ok = PhysicalLimits(fps=25.0, reach_m=1.8).accept(np.arange(5), 10, pos, nxt, vel)
    assert ok.tolist() == [False, False, True, True, False]
    # Without velocities (or with reach_m None) only the ground and the net are judged.
    assert lim.accept(np.arange(5), 10, pos, nxt).all()
    assert PhysicalLimits(reach_m=None).accept(np.arange(5), 10, pos, nxt, vel).all()


def test_physical_limits_give_the_return_its_own_reach():
    from types import SimpleNamespace

    from sportsngen.sim.constraints import PhysicalLimits

    # Rows 0-1: the serve is the only shot so far (the next contact is the return); rows 2-3:
    # a rally ball (three shots). The ball is 1.6 m from the receiver (rows 0, 2) or 1.3 m
    # (rows 1, 3) and struck back.
    tracker = SimpleNamespace(n_shots=np.array([1, 1, 3, 3]))
    pos = torch.zeros(4, 3, 3)
    pos[:, 0, :2] = torch.tensor([11.0, 0.0])
    pos[:, 1, :2] = torch.tensor([-11.0, 0.0])
    pos[:, 2] = torch.tensor([[-11.0, 1.6, 1.0], [-11.0, 1.3, 1.0],
                              [-11.0, 1.6, 1.0], [-11.0, 1.3, 1.0]])
    vel = torch.zeros(4, 3, 3)
    vel[:, 2] = torch.tensor([-20.0, 0.0, -2.0])
    nxt = pos.clone()
    nxt[:, 2, 0] += 0.8                                    # back at 20 m/s
    lim = PhysicalLimits(fps=25.0, reach_m=1.8, tracker=tracker, return_reach_m=1.5)
    assert lim.accept(np.arange(4), 10, pos, nxt, vel).tolist() == [False, True, True, True]
    # The rows are the tracker's: asked for rows 2 and 0 only, in that order.
    assert lim.accept(np.array([2, 0]), 10, pos[[2, 0]], nxt[[2, 0]],
                      vel[[2, 0]]).tolist() == [True, False]
    assert PhysicalLimits(fps=25.0, reach_m=1.8).accept(np.arange(4), 10, pos, nxt,
                                                        vel).all()
    with pytest.raises(ValueError, match="needs a tracker"):
        PhysicalLimits(return_reach_m=1.5)


def test_physical_limits_reject_a_ball_braked_in_mid_air_out_of_everyones_reach():
    from sportsngen.sim.constraints import PhysicalLimits

    lim = PhysicalLimits(fps=25.0)
    pos = torch.zeros(7, 3, 3)
    pos[:, 0, :2] = torch.tensor([11.0, 0.0])
    pos[:, 1, :2] = torch.tensor([-15.0, 0.0])            # the receiver far back
    pos[:, 2] = torch.tensor([[-2.0, 0.0, 1.2],            # past the net, in the air
                              [-2.0, 0.0, 1.2],
                              [-5.0, 0.0, 0.3],            # about to bounce
                              [-5.0, 0.0, 0.3],
                              [-13.5, 0.0, 1.0],           # 1.5 m from the receiver
                              [-0.5, 0.0, 1.0],            # at the net
                              [-2.0, 0.0, 1.2]])
    vel = torch.zeros(7, 3, 3)
    vel[:, 2] = torch.tensor([-40.0, 0.0, -8.0])          # a serve coming down
    step = torch.tensor([[-1.6, 0.0, -0.32],               # free flight: kept
                         [-0.5, 0.0, -0.32],               # 40 -> 12.5 m/s: rejected
                         [-1.2, 0.0, 0.0],                 # a bounce keeping 0.75: kept
                         [-0.3, 0.0, 0.0],                 # keeping 0.19: rejected
                         [-0.5, 0.0, -0.32],               # braked, but a racket is there
                         [-0.5, 0.0, -0.32],               # the net
                         [-1.6, 0.3, -0.32]])              # 7.5 m/s sideways: rejected
    nxt = pos.clone()
    nxt[:, 2] += step
    ok = lim.accept(np.arange(7), 10, pos, nxt, vel)
    assert ok.tolist() == [True, False, True, False, True, True, False]
    assert lim.jolted(pos, nxt, vel).tolist() == [False, True, False, True, True, True, True]


def test_contact_odds_rollouts_are_reproducible_and_change_only_the_ball(tiny_model_file):
    kw = dict(max_duration_s=1.2, top_p_ball=0.6)
    a = _sim(tiny_model_file, contact_odds=True, **kw).simulate_points(
        "Toy Alpha", "Toy Beta", "hard", 4, seed=0, serve_number=1)
    b = _sim(tiny_model_file, contact_odds=True, **kw).simulate_points(
        "Toy Alpha", "Toy Beta", "hard", 4, seed=0, serve_number=1)
    c = _sim(tiny_model_file, **kw).simulate_points("Toy Alpha", "Toy Beta", "hard", 4, seed=0,
                                                    serve_number=1)
    pd.testing.assert_frame_equal(a.frames, b.frames)

    def same_ball(d, e) -> bool:
        # (the frames table is long: one row an object a frame)
        x, y = (t.frames.loc[t.frames["object"] == "ball", ["x", "y", "z"]].to_numpy()
                for t in (d, e))
        return x.shape == y.shape and np.array_equal(x, y)

    assert same_ball(a, b) and not same_ball(a, c)
    # A contact nucleus equal to the ball's changes nothing; a wider one changes the ball.
    same = _sim(tiny_model_file, contact_odds=True, top_p_contact=0.6, **kw).simulate_points(
        "Toy Alpha", "Toy Beta", "hard", 4, seed=0, serve_number=1)
    pd.testing.assert_frame_equal(a.frames, same.frames)
    wide = _sim(tiny_model_file, contact_odds=True, top_p_contact=1.0, **kw).simulate_points(
        "Toy Alpha", "Toy Beta", "hard", 4, seed=0, serve_number=1)
    assert not same_ball(a, wide)


def test_strike_in_reach_rejects_a_good_ball_leaving_the_due_players_reach_unstruck():
    from types import SimpleNamespace

    from sportsngen.sim.constraints import StrikeInReach

    # Rows 0-5: the server (end +1) hit last, the ball bounced good on the receiver's side (x < 0).
    n = 8
    tracker = SimpleNamespace(ended=np.zeros(n, dtype=bool), hitter=np.zeros(n, dtype=np.int64),
                              n_bounces=np.ones(n, dtype=np.int64), server_end=np.ones(n),
                              n_shots=np.ones(n, dtype=np.int64))   # the serve: the return due
    tracker.n_bounces[2] = 0            # row 2: not bounced yet (a volley is the player's choice)
    tracker.ended[3] = True             # row 3: the rally is over
    tracker.hitter[6:] = 1              # rows 6-7: the receiver hit; the server (x > 0) is due
    tracker.n_shots[6:] = 2             # (his first rally ball)
    con = StrikeInReach(tracker, reach_m=1.2, max_z_m=2.3, fps=25.0)
    pos = torch.zeros(n, 3, 3)
    pos[:, 0, :2] = torch.tensor([11.0, 0.0])
    pos[:, 1, :2] = torch.tensor([-11.0, 0.0])
    pos[:, 2] = torch.tensor([-11.6, 0.6, 1.0])          # 0.85 m from the receiver
    pos[4, 2, 2] = 2.6                                   # row 4: above any groundstroke
    pos[6:, 2] = torch.tensor([11.6, 0.6, 1.0])          # 0.85 m from the server
    nxt = pos.clone()
    nxt[:, 2, 0] -= 0.8                                  # on past the receiver (1.52 m), 20 m/s
    nxt[6:, 2, 0] += 1.6                                 # on past the server (1.52 m)
    nxt[5, 2, 0] = pos[5, 2, 0] + 0.6                    # row 5: sent back toward the net
    nxt[7, 2, 0] = pos[7, 2, 0] + 0.2                    # row 7: 1.0 m from him, still in reach
    ok = con.accept(np.arange(n), 10, pos, nxt)
    assert ok.tolist() == [False, False, True, True, True, True, False, True]
    # The player keeping the ball in reach (he moved with it) is a possible frame too.
    nxt[0, 1, 0] -= 0.8
    assert bool(con.accept(np.arange(1), 10, pos[:1], nxt[:1])[0])
    # Given the velocities, a ball braked in mid-air in his reach (20 m/s to 2.5 m/s: it
    # would hang there until the end rules called it an ace) is rejected like a pass; flying
    # on within reach, or sent back, it is not.
    vel = torch.zeros(n, 3, 3)
    vel[:, 2, 0] = -20.0
    vel[6:, 2, 0] = 20.0
    braked = pos.clone()
    braked[:, 2, 0] -= 0.1
    braked[6:, 2, 0] += 0.2                              # the server's: braked to 5 m/s
    braked[5, 2, 0] = pos[5, 2, 0] + 0.6                 # sent back
    got = con.accept(np.arange(n), 10, pos, braked, vel)
    assert got.tolist() == [False, False, True, True, True, True, False, False]
    assert con.accept(np.arange(n), 10, pos, braked).tolist() == [True] * n    # no velocities
    flying = pos.clone()
    flying[:, 2, 0] -= 0.8
    flying[:, 1, 0] -= 0.8                               # he moves with it: still in reach
    assert bool(con.accept(np.arange(1), 10, pos[:1], flying[:1], vel[:1])[0])
    # From the server's first rally ball on, the return is left to the model.
    rally = StrikeInReach(tracker, reach_m=1.2, max_z_m=2.3, fps=25.0, from_shot=2)
    assert rally.accept(np.arange(n), 10, pos, nxt).tolist() == [True] * 6 + [False, True]
    with pytest.raises(ValueError, match="positive"):
        StrikeInReach(tracker, reach_m=0.0)
    with pytest.raises(ValueError, match="from_shot"):
        StrikeInReach(tracker, from_shot=0)


def test_strike_in_reach_gives_the_return_its_own_reach():
    from types import SimpleNamespace

    from sportsngen.sim.constraints import StrikeInReach

    # The receiver (x = -11) is due in every row; rows 0-1 the return (only the serve struck),
    # rows 2-3 a later ball. The ball is 1.36 m from him (1.08 m in rows 1, 3) and leaves his
    # reach unstruck (to 1.75 m or more).
    tracker = SimpleNamespace(ended=np.zeros(4, dtype=bool), hitter=np.zeros(4, dtype=np.int64),
                              n_bounces=np.ones(4, dtype=np.int64), server_end=np.ones(4),
                              n_shots=np.array([1, 1, 3, 3]))
    pos = torch.zeros(4, 3, 3)
    pos[:, 0, :2] = torch.tensor([11.0, 0.0])
    pos[:, 1, :2] = torch.tensor([-11.0, 0.0])
    pos[:, 2] = torch.tensor([-10.6, 1.3, 1.0])
    pos[[1, 3], 2, 1] = 1.0                              # rows 1, 3: 1.08 m beside him
    nxt = pos.clone()
    nxt[:, 2, 0] -= 0.8
    nxt[:, 2, 1] += 0.7
    con = StrikeInReach(tracker, reach_m=1.5, max_z_m=2.3, fps=25.0, return_reach_m=1.2)
    # The return 1.36 m away is his to leave; 1.08 m away, and any later ball, must be struck.
    assert con.accept(np.arange(4), 10, pos, nxt).tolist() == [True, False, False, False]
    same = StrikeInReach(tracker, reach_m=1.5, max_z_m=2.3, fps=25.0)
    assert same.accept(np.arange(4), 10, pos, nxt).tolist() == [False] * 4
    with pytest.raises(ValueError, match="return_reach_m"):
        StrikeInReach(tracker, return_reach_m=0.0)


def test_strike_in_reach_rejects_a_good_ball_falling_low_or_passing_behind_him_unstruck():
    from types import SimpleNamespace

    from sportsngen.sim.constraints import STRIKE_BEHIND_M, STRIKE_MIN_Z_M, StrikeInReach

    # The receiver (x = -11) is due; the ball bounced good and stays within 0.6 m of him.
    n = 6
    tracker = SimpleNamespace(ended=np.zeros(n, dtype=bool), hitter=np.zeros(n, dtype=np.int64),
                              n_bounces=np.ones(n, dtype=np.int64), server_end=np.ones(n),
                              n_shots=np.ones(n, dtype=np.int64))
    con = StrikeInReach(tracker, reach_m=1.2, max_z_m=2.3, fps=25.0)
    assert STRIKE_MIN_Z_M == pytest.approx(0.2)
    pos = torch.zeros(n, 3, 3)
    pos[:, 0, :2] = torch.tensor([11.0, 0.0])
    pos[:, 1, :2] = torch.tensor([-11.0, 0.0])
    pos[:, 2] = torch.tensor([-11.4, 0.4, 0.30])
    nxt = pos.clone()
    nxt[:, 2, 0] -= 0.1                                  # on slowly beside him, still in reach
    nxt[0, 2, 2] = 0.15                                  # row 0: falls below a racket
    nxt[1, 2, 2] = 0.45                                  # row 1: rises (off its first bounce)
    nxt[2, 2, 2] = 0.25                                  # row 2: falls, still playable
    pos[3, 2, 2], nxt[3, 2, 2] = 0.05, 0.15              # row 3: rising from its first bounce
    nxt[4, 2, 2] = 0.15
    nxt[4, 2, 0] = pos[4, 2, 0] + 0.6                    # row 4: struck back from low
    tracker.n_bounces[5] = 0                             # row 5: not bounced yet (a volley)
    nxt[5, 2, 2] = 0.15
    assert con.accept(np.arange(n), 10, pos, nxt).tolist() == [False, True, True, True, True,
                                                                True]
    # Given the velocities, a ball whose free fall takes it below a racket within the frame
    # must be struck now: row 2 falls at 3 m/s (0.30 - 0.12 - 0.01 m by the next frame).
    vel = torch.zeros(n, 3, 3)
    vel[:, 2, 0] = -2.5
    vel[:, 2, 2] = 1.0
    vel[2, 2, 2] = -3.0
    assert con.accept(np.arange(n), 10, pos, nxt, vel).tolist() == [False, True, False, True,
                                                                     True, True]
    # A ball passing behind him (toward his back fence) further than a player strikes it,
    # still within reach, has passed him too: 1.15 m behind his centre and 1.17 m from it.
    wide = StrikeInReach(tracker, reach_m=1.5, max_z_m=2.3, fps=25.0, behind_m=STRIKE_BEHIND_M)
    assert STRIKE_BEHIND_M == pytest.approx(1.1)
    assert StrikeInReach(tracker).behind_m is None                   # off by default
    past = pos.clone()
    past[:, 2] = torch.tensor([-11.9, 0.25, 1.0])       # 0.9 m behind him
    on = past.clone()
    on[:, 2, 0] = -12.15                                 # on to 1.15 m behind
    assert wide.accept(np.arange(n), 10, past, on).tolist() == [False] * 5 + [True]
    on[:, 2, 0] = -12.05                                 # 1.05 m behind: still his to strike
    assert wide.accept(np.arange(n), 10, past, on).tolist() == [True] * n
    # Without either (the rule before) only balls leaving the reach count.
    old = StrikeInReach(tracker, reach_m=1.2, max_z_m=2.3, fps=25.0, min_z_m=None)
    assert old.accept(np.arange(n), 10, pos, nxt, vel).tolist() == [True] * n
    on[:, 2, 0] = -12.15
    old = StrikeInReach(tracker, reach_m=1.5, max_z_m=2.3, fps=25.0, min_z_m=None)
    assert old.accept(np.arange(n), 10, past, on).tolist() == [True] * n
    with pytest.raises(ValueError, match="min_z_m"):
        StrikeInReach(tracker, min_z_m=2.5)
    with pytest.raises(ValueError, match="behind_m"):
        StrikeInReach(tracker, behind_m=0.0)


def test_a_forced_strike_is_asked_for_only_where_the_rule_itself_gave_up():
    from types import SimpleNamespace

    from sportsngen.sim.constraints import AllOf, StrikeInReach
    from sportsngen.sim.frame_draws import redraw_rejected

    n = 3     # every row: the receiver due to return a good serve
    tracker = SimpleNamespace(ended=np.zeros(n, dtype=bool), hitter=np.zeros(n, dtype=np.int64),
                              n_bounces=np.ones(n, dtype=np.int64), server_end=np.ones(n),
                              n_shots=np.ones(n, dtype=np.int64))
    pos = torch.zeros(n, 3, 3)
    pos[:, 0, :2] = torch.tensor([11.0, 0.0])
    pos[:, 1, :2] = torch.tensor([-11.0, 0.0])
    pos[:, 2] = torch.tensor([-11.6, 0.6, 1.0])          # 0.85 m from the receiver
    passed = pos.clone()
    passed[:, 2, 0] -= 0.8                               # on past him, unstruck

    class Other:                      # another rule, rejecting row 2 only
        max_tries, offset = 1, 0

        def __init__(self):
            self.told = []

        def accept(self, rows, frame, pos_m, next_pos_m, vel_mps=None):
            return torch.as_tensor(np.asarray(rows) != 2)

        def give_up(self, rows):
            self.told += list(rows)

    class Model:                      # every draw passes rows 0 and 2, keeps row 1 in reach
        def sample_next(self, h, pos_m, *args):
            out = passed[:len(h)].clone()
            out[h[:, 0] == 1] = pos[:1]
            return out

    for force in (False, True):
        rule, other = StrikeInReach(tracker, max_tries=1, force=force), Other()
        con = AllOf(rule, other)
        h = torch.zeros(n, 1)
        h[1, 0] = 1
        zero = torch.zeros_like(pos)
        nxt, drawn, strike = redraw_rejected(Model(), con, np.arange(n), 10, h, pos, zero, zero,
                                        passed.clone(), 1.0, 1.0, None)
        # Row 1 found a frame that keeps the ball in reach; rows 0 and 2 gave up, and each
        # rule is told only the rows it rejected.
        assert drawn.tolist() == [2, 1, 2] and torch.equal(nxt[1], pos[0])
        assert rule.given_up == 2 and other.told == [2]
        assert strike.tolist() == [force, False, force]
    assert StrikeInReach(tracker).strike_rows(np.arange(n)).tolist() == [False] * n


def test_strike_in_reach_runs_in_rollouts_and_changes_nothing_before_a_good_bounce(
        tiny_model_file):
    from sportsngen.errors import ArgumentError

    kw = dict(max_duration_s=1.2, top_p_ball=0.6, contact_odds=True)
    a = _sim(tiny_model_file, **kw).simulate_points("Toy Alpha", "Toy Beta", "hard", 4, seed=0,
                                                    serve_number=1)
    b = _sim(tiny_model_file, strike_in_reach=True, **kw).simulate_points(
        "Toy Alpha", "Toy Beta", "hard", 4, seed=0, serve_number=1)
    assert len(a.rallies) == len(b.rallies)
    # Up to the serve's bounce (the toss and the serve's first frames) both draw the same frames.
    fa = a.frames[a.frames["frame"] < 20].reset_index(drop=True)
    fb = b.frames[b.frames["frame"] < 20].reset_index(drop=True)
    pd.testing.assert_frame_equal(fa, fb)
    # From the server's first rally ball on: nothing changes before the return's first bounce
    # either, and a contact number before the return is refused.
    # The tiny model has no serve head: its nucleus changes nothing; a nucleus outside (0, 1]
    # is refused.
    fs = _sim(tiny_model_file, strike_in_reach=True, top_p_serve=0.5, **kw)
    assert fs.top_p_serve == 0.5
    pd.testing.assert_frame_equal(
        b.frames, fs.simulate_points("Toy Alpha", "Toy Beta", "hard", 4, seed=0,
                                     serve_number=1).frames)
    with pytest.raises(ArgumentError, match="top_p_serve"):
        _sim(tiny_model_file, top_p_serve=0.0)
    # The tiny model has no strike head: forcing a strike where the rule gives up is a no-op.
    f = _sim(tiny_model_file, strike_in_reach=True, strike_in_reach_force=True, **kw)
    ff = f.simulate_points("Toy Alpha", "Toy Beta", "hard", 4, seed=0, serve_number=1)
    pd.testing.assert_frame_equal(b.frames, ff.frames)
    assert (ff.rallies["forced_strikes"] == 0).all() and (b.rallies["forced_strikes"] == 0).all()
    c = _sim(tiny_model_file, strike_in_reach=True, strike_in_reach_from=2, **kw)
    assert c.strike_in_reach_from == 2
    fc = c.simulate_points("Toy Alpha", "Toy Beta", "hard", 4, seed=0, serve_number=1).frames
    pd.testing.assert_frame_equal(fa, fc[fc["frame"] < 20].reset_index(drop=True))
    with pytest.raises(ArgumentError, match="strike_in_reach_from"):
        _sim(tiny_model_file, strike_in_reach=True, strike_in_reach_from=0)


def test_strike_in_reach_m_is_the_rules_reach_in_rollouts(tiny_model_file, monkeypatch):
    from sportsngen.errors import ArgumentError
    from sportsngen.sim import simulator as simulator_module

    reaches = []

    class Recording(simulator_module.StrikeInReach):
        def __init__(self, tracker, **kw):
            reaches.append(kw["reach_m"])
            super().__init__(tracker, **kw)

    monkeypatch.setattr(simulator_module, "StrikeInReach", Recording)
    kw = dict(max_duration_s=0.4, top_p_ball=0.6, strike_in_reach=True)
    _sim(tiny_model_file, **kw).simulate_points("Toy Alpha", "Toy Beta", "hard", 2, seed=0)
    _sim(tiny_model_file, strike_in_reach_m=1.5, **kw).simulate_points(
        "Toy Alpha", "Toy Beta", "hard", 2, seed=0)
    assert reaches == [1.2, 1.5]
    with pytest.raises(ArgumentError, match="strike_in_reach_m"):
        _sim(tiny_model_file, strike_in_reach_m=0.0)


def test_contact_reach_m_is_the_physical_limits_reach_in_rollouts(tiny_model_file, monkeypatch):
    from sportsngen.errors import ArgumentError
    from sportsngen.sim import simulator as simulator_module

    reaches = []

    class Recording(simulator_module.PhysicalLimits):
        def __init__(self, **kw):
            reaches.append(kw["reach_m"])
            super().__init__(**kw)

    monkeypatch.setattr(simulator_module, "PhysicalLimits", Recording)
    kw = dict(max_duration_s=0.4, top_p_ball=0.6)
    on = {**kw, "physical_limits": True}
    _sim(tiny_model_file, **on).simulate_points("Toy Alpha", "Toy Beta", "hard", 2, seed=0)
    _sim(tiny_model_file, contact_reach_m=1.8, **on).simulate_points(
        "Toy Alpha", "Toy Beta", "hard", 2, seed=0)
    _sim(tiny_model_file, contact_reach_m=1.8, physical_limits=False, **kw).simulate_points(
        "Toy Alpha", "Toy Beta", "hard", 2, seed=0)
    assert reaches == [2.5, 1.8]          # the rules' reach by default; no limits, no reach
    with pytest.raises(ArgumentError, match="contact_reach_m"):
        _sim(tiny_model_file, contact_reach_m=0.0)


def test_ball_net_sets_the_centre_of_the_loaded_model_only(tiny_model_file):
    from sportsngen.errors import ArgumentError

    sim = _sim(tiny_model_file)
    assert sim.model.cfg.ball_net is False
    if sim.model.cfg.ball_centre != "physics":
        with pytest.raises(ArgumentError, match="ball_net"):
            _sim(tiny_model_file, ball_net=True)
        sim.model.cfg.ball_centre = "physics"      # as a physics-centre file would load
    net = Simulator(sim.model, sim.event_model, sim.vocab, sim.initial, ball_net=True)
    assert net.model.cfg.ball_net is True
    assert _sim(tiny_model_file).model.cfg.ball_net is False     # each load its own


def test_set_defaults_stores_sampling_defaults_that_from_pretrained_applies(tiny_model_file,
                                                                           tmp_path):
    import shutil

    from sportsngen.errors import ArgumentError

    path = tmp_path / "m.pt"
    shutil.copy(tiny_model_file, path)
    Simulator.set_defaults(path, strike_in_reach=True)
    after = Simulator.set_defaults(path, strike_in_reach_m=1.5)
    assert after == {"strike_in_reach": True, "strike_in_reach_m": 1.5}
    sim = Simulator.from_pretrained(path)
    assert sim.strike_in_reach and sim.strike_in_reach_m == 1.5
    assert Simulator.from_pretrained(path, strike_in_reach_m=1.2).strike_in_reach_m == 1.2
    with pytest.raises(ArgumentError, match="reach_metres"):
        Simulator.set_defaults(path, reach_metres=1.5)


def test_pooled_rally_win_probabilities_do_not_depend_on_the_workers(tiny_model_file):
    from sportsngen.sim.outcome_pool import chunk_jobs, pooled_rally_win_probabilities
    from sportsngen.sim.whatif import rally_win_probabilities

    data = make_toy_rallies(4, seed=3)
    items = [(int(r), f) for r in data.rallies["rally_id"].iloc[:3] for f in (5, 10)]
    # (no physical limits: redrawing the untrained model's frames is most of a rollout's time)
    sim_kw = {"max_duration_s": 1.2, "physical_limits": False}
    kw = dict(n=4, seed=2, chunk_items=4, sim_kwargs=sim_kw, progress=False)
    one = pooled_rally_win_probabilities(str(tiny_model_file), data, items, workers=1, **kw)
    two = pooled_rally_win_probabilities(str(tiny_model_file), data, items, workers=2, **kw)
    assert list(zip(one["rally_id"], one["frame"])) == items
    pd.testing.assert_frame_equal(one, two)
    # Chunk k is one direct call with seed + 7919 k: 6 items in chunks of 4 and 2.
    jobs = chunk_jobs(items, 4, 2, 4)
    assert [(len(j[0]), j[2]) for j in jobs] == [(4, 2), (2, 2 + 7919)]
    sim = _LOAD(str(tiny_model_file), **sim_kw)
    direct = rally_win_probabilities(sim, data, jobs[1][0], n=4, seed=jobs[1][2])
    pd.testing.assert_frame_equal(one.iloc[4:].reset_index(drop=True), direct)
    # Chunks of 0: one call of all the items with the seed itself (in this process: a pool of
    # one spawned worker would cost a start-up and test nothing the two workers did not).
    whole = pooled_rally_win_probabilities(str(tiny_model_file), data, items, workers=1,
                                           **{**kw, "chunk_items": 0})
    pd.testing.assert_frame_equal(whole, rally_win_probabilities(sim, data, items, n=4, seed=2))
