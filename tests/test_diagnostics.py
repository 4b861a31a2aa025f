"""Rollout diagnostics (`sportsngen.eval.diagnostics`) and the free-flight residual
(`sportsngen.eval.flight`): hand-made tracks with known answers, generated truth, and a run on
the tiny test model."""

import dataclasses

import numpy as np
import pandas as pd
import pytest
import torch

from sportsngen.eval import diagnostics
from sportsngen.eval.contact_odds import REVERSAL_M, approach_frames, far_probability
from sportsngen.eval.diagnostics import (
    LEAK_READ_POINTS,
    WIDE_SERVE_Y_M,
    DiagnosticsSetup,
    contact_calibration,
    leak_rows_advice,
    leak_rows_summary,
    paired_return_gap,
    run_diagnostics,
    serve_outcomes,
    serve_strike_frames,
    strike_branches,
    truth_leak_aucs,
    truth_points,
    with_rules_serve_outcomes,
)
from sportsngen.eval.flight import (
    MIN_PLAYER_DISTANCE_M,
    centre_bin_share,
    flight_residuals,
    free_flight_frames,
)
from sportsngen.model.centre import flight_acceleration_mps2
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN
from sportsngen.sim import Simulator
from tests.conftest import tiny_sim

FPS = 25.0


def straight_track(n: int = 20, vel=(20.0, 1.0, 0.0), z: float = 2.0) -> np.ndarray:
    """Players far away at the baselines, the ball on a straight line at constant velocity."""
    pos = np.zeros((n, 3, 3))
    pos[:, 0, :2] = (-12.0, 0.0)
    pos[:, 1, :2] = (12.0, 0.0)
    t = np.arange(n) / FPS
    pos[:, 2] = np.array([-6.0, 0.0, z]) + np.outer(t, vel)
    return pos


def test_free_flight_frames_leave_out_the_edges_players_and_ground():
    pos = straight_track()
    ok = free_flight_frames(pos, FPS)
    # frame t needs t - 2 .. t + 1 on the track
    assert not ok[:2].any() and not ok[-1] and ok[2:-1].all()
    near = pos.copy()
    near[10, 1, :2] = near[10, 2, :2] + (MIN_PLAYER_DISTANCE_M - 0.1, 0.0)  # a player at hand
    ok = free_flight_frames(near, FPS)
    assert not ok[9:13].any() and ok[8] and ok[13]
    low = straight_track(z=0.1)                                          # along the ground
    assert not free_flight_frames(low, FPS).any()


def test_residuals_of_a_straight_track_are_zero_for_velocity_and_physics():
    # The physics step reads the track's own acceleration (here none): no gravity imposed.
    res = flight_residuals([straight_track()], FPS, "velocity").residual_m
    assert res.shape == (17, 3)
    np.testing.assert_allclose(res, 0.0, atol=1e-9)
    # A straight line at 20 m/s would need a lift of g, beyond what Magnus can do at that
    # speed: the physics step imposes gravity and drag, and misses by exactly their step.
    res = flight_residuals([straight_track()], FPS, "physics").residual_m
    acc = flight_acceleration_mps2(torch.tensor([20.0, 1.0, 0.0], dtype=torch.float64))
    np.testing.assert_allclose(res, np.tile(-acc.numpy() / FPS ** 2, (17, 1)), atol=1e-9)
    cur = flight_residuals([straight_track()], FPS, "current").residual_m
    np.testing.assert_allclose(cur, np.tile([0.8, 0.04, 0.0], (17, 1)), atol=1e-9)
    cfg = ModelConfig(bin_spacing="nonuniform")
    assert centre_bin_share(np.zeros((4, 3)), cfg) == 1.0
    assert centre_bin_share(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.01]]), cfg) == 0.5


def test_generated_truth_follows_the_physics_step(truth_data):
    truth = truth_data(30, 3)
    assert set(truth.rallies["server"]) == {"Roger Federer"}
    from sportsngen.data.tokens import Vocab, rally_arrays
    from sportsngen.eval.flight import rally_tracks

    arr = rally_arrays(truth, Vocab.from_data(truth, generic=True))
    s = flight_residuals(rally_tracks(arr.pos_m, arr.start, arr.length), FPS).summary(
        ModelConfig(bin_spacing="nonuniform"))
    assert s["frames"] > 500
    assert max(s["p90_x_mm"], s["p90_y_mm"], s["p90_z_mm"]) < 0.5
    assert s["centre_bin_share"] > 0.95
    vel = flight_residuals(rally_tracks(arr.pos_m, arr.start, arr.length), FPS, "velocity")
    assert vel.summary()["median_z_mm"] > 10.0        # gravity alone: 16 mm a frame


def test_serve_outcomes_agree_with_the_shots_table(truth_data):
    truth = truth_data(40, 4)
    out = serve_outcomes(truth)
    shots = truth.shots
    returned = set(shots.loc[shots["shot_index"] == 1, "rally_id"])
    faults = set(shots.loc[(shots["shot_index"] == 0) & (shots["outcome"] == "error"),
                           "rally_id"])
    assert out["in_box"].sum() > 10
    for rid, row in out.iterrows():
        assert row["returned"] == (rid in returned)
        if rid in faults:
            assert not row["in_box"]
    # The serve's bounce read from the track is the generator's, within 5 cm.
    serve = shots[shots["shot_index"] == 0].set_index("rally_id")
    both = out.index[out["in_box"]]
    gap = (out.loc[both, "bounce_abs_y_m"] - serve.loc[both, "bounce_y"].abs()).abs()
    assert len(both) > 10 and gap.max() < 0.05


def test_rules_serve_outcomes_replace_a_classifier_that_mislabels_serves(truth_data):
    # A rollout's shot outcomes are its event classifier's; the leak check needs the rules'.
    truth = truth_data(40, 4)
    out = serve_outcomes(truth)
    shots = truth.shots.copy()
    serve = shots["shot_index"] == 0
    shots.loc[serve, "outcome"] = "error"         # every serve mislabelled a fault
    wrong = dataclasses.replace(truth, shots=shots)
    fixed = with_rules_serve_outcomes(wrong, out).shots
    fixed_serves = fixed.loc[fixed["shot_index"] == 0].set_index("rally_id")["outcome"]
    expected = out["in_box"].map({True: "in_play", False: "error"})
    assert (fixed_serves.loc[expected.index] == expected).all()
    assert (fixed_serves == "in_play").sum() == int(out["in_box"].sum()) > 10
    # Shots after the serve keep their outcomes.
    later = fixed["shot_index"] > 0
    assert (fixed.loc[later, "outcome"].to_numpy()
            == truth.shots.loc[later, "outcome"].to_numpy()).all()


def test_leak_rows_summary_counts_outside_and_unsure_rows():
    # Four leak rows read (0.30 [0.18, 0.43] sure, 0.61 [0.48, 0.73] unsure, 0.50 inside, 0.65
    # without an interval: sure), one unread (NaN), and a row that is not a leak cell.
    table = pd.DataFrame({
        "signal": ["leak AUC a", "leak AUC b", "leak AUC c", "leak AUC d", "leak AUC e",
                   "branch return share"],
        "model": [0.30, 0.61, 0.50, 0.65, np.nan, 0.9], "data": 0.5, "n": 100,
        "lo": [0.18, 0.48, 0.40, np.nan, np.nan, 0.1], "hi": [0.43, 0.73, 0.60, np.nan,
                                                               np.nan, 0.2]})
    assert leak_rows_summary(table) == ("leak rows outside [0.4, 0.6]: 3 of 4 read (1 unsure: "
                                        "their 95 % interval holds 0.5)")


def test_leak_rows_advice_asks_for_more_points_below_the_reading_size():
    assert leak_rows_advice(400) == ("(at 400 points the leak rows rest on few pairs and move "
                                     "from seed to seed: read them with --points 1600)")
    assert leak_rows_advice(LEAK_READ_POINTS) is None and leak_rows_advice(5000) is None


def _strike_frames_after_rounding(data):
    """serve_strike_frames, checked against the ball, -> per hitter the (min, max) frames it
    adds to the shots table's rounded contact frame."""
    strike = serve_strike_frames(data)
    serves = data.shots[data.shots["shot_index"] == 0].set_index("rally_id")
    first = data.frames.groupby("rally_id")["frame"].min()
    ball = data.frames[data.frames["object"] == "ball"].set_index(["rally_id", "frame"])["x"]
    for rid, f in strike.items():
        x0 = abs(serves.loc[rid, "contact_x"])
        assert x0 - abs(ball[(rid, first[rid] + f)]) > 0.01        # left the racket
        assert x0 - abs(ball[(rid, first[rid] + f - 1)]) < 0.01    # not yet, a frame before
    late = strike - (serves["frame"] - first).reindex(strike.index)
    return {h: (int(g.min()), int(g.max())) for h, g in late.groupby(serves["hitter"])}


def test_a_serves_strike_frame_is_the_first_past_the_racket(monkeypatch):
    # The generator strikes each player's serves at one fraction of a frame: Sharapova's before
    # the shots table's frame (the ball there has left), Williams' 0.16 of a frame after it (the
    # ball there is still on the toss), so her strike is the next frame.
    from sportsngen.synth import cycle, generate_matches

    data = generate_matches([("Serena Williams", "Maria Sharapova")], "hard", 12, seed=0)
    assert _strike_frames_after_rounding(data) == {"Maria Sharapova": (0, 0),
                                                   "Serena Williams": (1, 1)}
    # Serves anywhere in their frame, as real tracking has them: either, for both.
    monkeypatch.setattr(cycle, "SERVE_PHASE", True)
    data = generate_matches([("Serena Williams", "Maria Sharapova")], "hard", 12, seed=0)
    assert set(_strike_frames_after_rounding(data).values()) == {(0, 1)}


def test_serve_outcomes_of_a_bounce_just_past_the_last_frame(monkeypatch):
    # The rules may round a cut-off rally's last bounce to the frame after its last one.
    import sportsngen.eval.diagnostics as diagnostics

    truth = truth_points(DiagnosticsSetup(n_points=20, seed=4))
    real = diagnostics.analyse_rally_data(truth)
    length = truth.frames.groupby("rally_id")["frame"].nunique()
    shifted = real.copy()
    shifted["bounce_frames"] = [[int(length[rid])] + list(b[1:]) if len(b) else b
                                for rid, b in zip(shifted.index, shifted["bounce_frames"])]
    monkeypatch.setattr(diagnostics, "analyse_rally_data", lambda data: shifted)
    out = serve_outcomes(truth)
    arr_len = {rid: int(n) for rid, n in length.items()}
    moved = out.loc[out["bounce_frame"] >= 0]
    assert len(moved) > 5 and moved["moved_m"].notna().all()
    assert all(row.bounce_frame == arr_len[rid] for rid, row in moved.iterrows())


def test_paired_return_gap_on_known_serves():
    import pandas as pd

    truth = pd.DataFrame({"in_box": [True] * 4, "returned": [True, True, True, False]},
                         index=[10, 11, 12, 13])
    branch = pd.DataFrame({"in_box": [True, True, False, True],
                           "returned": [True, False, False, False]}, index=[0, 1, 2, 3])
    order = pd.Series([10, 11, 12, 13], index=[0, 1, 2, 3])
    gap, lo, hi = paired_return_gap(branch, truth, order, n_boot=200, seed=0)
    assert gap == pytest.approx(1 / 3 - 3 / 4)
    assert lo <= gap <= hi and hi - lo > 0.2
    same, lo, hi = paired_return_gap(truth.set_axis([0, 1, 2, 3]), truth, order, 50, 0)
    assert same == 0.0 and lo == 0.0 and hi == 0.0


def test_run_diagnostics_on_the_tiny_model(tiny_model_file):
    sim = tiny_sim(tiny_model_file)
    with pytest.warns(UserWarning, match="unknown player"):
        table = run_diagnostics(sim, DiagnosticsSetup(n_points=24, seed=1, leak_boot=5))
    signals = list(table["signal"])
    assert signals[0] == "branch return share (serves in the box)"
    assert signals[1] == "branch return share minus recorded (paired)"
    assert signals[2] == "branch return share, server stopped, minus free (paired)"
    stopped = table.iloc[2]
    # Paired on the serves in the box in both arms: no more than were branched.
    assert stopped["n"] <= table.iloc[1]["n"] and stopped["data"] == 0.0
    if stopped["n"]:
        assert -1.0 <= stopped["lo"] <= stopped["model"] <= stopped["hi"] <= 1.0
    assert "contact probability within reach (returned serves)" in signals
    assert "expected / recorded contacts (ball tokens)" in signals
    assert any(s.startswith("leak AUC ace_vs_returned") for s in signals)
    # The same cells on the model's own serves, in the same order.
    branch_cells = [s[len("leak AUC "):] for s in signals if s.startswith("leak AUC ")
                    and not s.startswith("leak AUC (own serves)")]
    own_cells = [s[len("leak AUC (own serves) "):] for s in signals
                 if s.startswith("leak AUC (own serves)")]
    assert own_cells == branch_cells and len(own_cells) == 16
    data_side = table.set_index("signal")["data"]
    assert data_side["free-flight residual p90 z (mm)"] < 0.5
    assert 0.5 < data_side["branch return share (serves in the box)"] <= 1.0
    shares = table[table["signal"].str.contains("share|still|own serves|probability") &
                   ~table["signal"].str.contains("minus")]
    # The untrained model may land no branch serve in the box (a NaN share), not more.
    assert shares["model"].dropna().between(0, 1).all()
    own = table[table["signal"].str.startswith("own serves")].set_index("signal")
    assert list(own.index) == ["own serves struck", "own serves struck from the server's place",
                               "own serves in the box", "own serves in the box, first serves",
                               "own serves in the box, second serves",
                               "own serves wide (serves in the box)",
                               "own serves returned (serves in the box)"]
    # First and second serves split the serves.
    assert own.at["own serves in the box, first serves", "n"] + \
        own.at["own serves in the box, second serves", "n"] == own.at["own serves in the box", "n"]
    assert 0.0 < own.at["own serves wide (serves in the box)", "data"] < 1.0
    # Every recorded serve is played again, as many as were branched.
    paired = table.set_index("signal").at["branch return share minus recorded (paired)", "n"]
    assert (own["n"].iloc[:3] == paired).all() and own["data"].iloc[0] == 1.0
    assert own["model"].iloc[1] <= own["model"].iloc[0]    # from his place: a subset
    assert 0.0 < data_side["own serves in the box"] <= 1.0
    coupling = table[table["signal"].str.startswith("server speed at strike + 9")]
    assert list(coupling["signal"]) == [
        f"server speed at strike + 9, one step: {what} ({n} serves)"
        for what in ("corr with serve speed", "m/s per 10 m/s of serve",
                     "m/s per 10 m/s of the ball's pace, path held")
        for n in ("first", "second")]
    assert coupling["model"].iloc[:2].dropna().between(-1, 1).all() and coupling["n"].sum() > 0
    # The pace rows draw the recorded serves again (a re-flown ball may keep a branch the
    # rules had ended, or end one); the record's server plans his run at the strike.
    n_serves = own.at["own serves in the box, first serves", "n"], \
        own.at["own serves in the box, second serves", "n"]
    assert (coupling["n"].iloc[4:].to_numpy() <= np.array(n_serves)).all()
    assert coupling["n"].iloc[4:].sum() > 0 and (coupling["data"].iloc[4:] == 0.0).all()
    third = table.set_index("signal").loc["branch third-shot share (returns in play)"]
    assert 0.8 < third["data"] <= 1.0          # the generator's servers answer their returns
    # An untrained model may keep none of its branched returns in play (n = 0), not more.
    assert 0 <= third["n"] <= table.set_index("signal").at[
        "branch returns still in play (returns in play)", "n"]
    leak = table[table["signal"].str.startswith("leak")]
    assert {"lo", "hi"} <= set(table.columns)
    assert leak.loc[leak["n"] < 30, "model"].isna().all()
    assert leak["data"].dropna().between(0.4, 0.6).all()   # the record's own cells
    ok = leak[leak["n"] >= 30]
    assert ((ok["lo"] <= ok["model"]) & (ok["model"] <= ok["hi"])).all()


def test_the_records_leak_cells_stand_beside_the_rollouts(truth_data):
    """`truth_leak_aucs` reads each cell of a table (in its order) on the recorded points: the
    check's own AUC where 30 pairs or more, else blank; the causal generator's serve cells
    within 0.4-0.6."""
    from sportsngen.eval.leaks import check_leaks

    truth = truth_data(80, 5)
    rec = check_leaks(truth, n_boot=0)
    cells = rec[rec["pair"].isin(diagnostics.SERVE_PAIRS)].iloc[::-1].reset_index(drop=True)
    got = truth_leak_aucs(rec, cells)
    enough = cells["n_pairs"].to_numpy() >= diagnostics.MIN_LEAK_PAIRS
    assert 0 < enough.sum() < len(cells)
    np.testing.assert_array_equal(got[enough], cells["auc"].to_numpy()[enough])
    assert np.isnan(got[~enough]).all()
    assert ((got[enough] >= 0.4) & (got[enough] <= 0.6)).all()


def test_strike_branches_count_every_serve_at_every_branch_point(tiny_model_file):
    sim = tiny_sim(tiny_model_file)
    truth = truth_points(DiagnosticsSetup(n_points=24, seed=1))
    with pytest.warns(UserWarning, match="unknown player"):
        table = strike_branches(sim, truth, after_frames=(-1, 3))
    assert list(table["after"].unique()) == ["-1", "3", "recorded"]
    rec = table[table["after"] == "recorded"].set_index("serve_number")
    out = serve_outcomes(truth)
    number = truth.rallies.set_index("rally_id")["serve_number"].reindex(out.index)
    for serve, g in out.groupby(number.to_numpy()):
        assert rec.at[serve, "n"] == len(g)
        assert rec.at[serve, "in_box"] == pytest.approx(g["in_box"].mean())
        box = g[g["in_box"]]
        wide = (box["bounce_abs_y_m"] > WIDE_SERVE_Y_M).mean() if len(box) else float("nan")
        assert rec.at[serve, "wide"] == pytest.approx(wide, nan_ok=True)
    # Every recorded serve is branched at each point (none is too short for 3 frames more).
    per_point = table.groupby("after")["n"].sum()
    assert (per_point == per_point["recorded"]).all()
    assert table["in_box"].between(0, 1).all()
    assert table["wide"].dropna().between(0, 1).all() and table["wide"].notna().any()


def test_diagnose_command_refuses_bad_input(tmp_path, capsys):
    from sportsngen.eval.__main__ import main

    assert main(["diagnose", "--points", "5"]) == 2
    assert "--points must be >= 20" in capsys.readouterr().err
    assert main(["diagnose", "--model", str(tmp_path / "none.pt")]) == 2
    assert "no model file" in capsys.readouterr().err
    assert main(["diagnose", "--top-p-ball", "0"]) == 2
    assert "--top-p-ball must be in (0, 1]" in capsys.readouterr().err
    assert main(["diagnose", "--boot", "-1"]) == 2
    assert "--boot must be >= 0" in capsys.readouterr().err
    assert main(["strikes", "--shots", "0", "2"]) == 2
    assert "--shots count contacts after the serve" in capsys.readouterr().err
    assert main(["strikes", "--model", str(tmp_path / "none.pt")]) == 2
    assert "no model file" in capsys.readouterr().err
    for command in ("serves", "strike-draws"):
        assert main([command, "--draws", "0"]) == 2
        assert "--draws must be >= 1" in capsys.readouterr().err


def test_strike_draws_command_refuses_a_model_without_a_strike_head(tiny_model_file, capsys):
    from sportsngen.eval.__main__ import main

    assert main(["strike-draws", "--model", str(tiny_model_file), "--points", "20"]) == 2
    assert "no strike head" in capsys.readouterr().err


def test_contact_probability_is_the_heads_mass_beyond_the_reversal():
    # The head's mass on the contact bins against 20,000 draws from it.
    torch.manual_seed(0)
    model = SportsNGEN(ModelConfig(d_model=32, n_layers=1, n_heads=2,
                                   bin_spacing="nonuniform")).eval()
    h = torch.randn(4, 32)
    with torch.no_grad():
        p = far_probability(model, h)
        # 20,000 draws of each state in one batch (row r is state r % 4).
        draws = model.ball_head.sample(h.repeat(20_000, 1),
                                       generator=torch.Generator().manual_seed(0))
    seen = (model.ball_bins.value(draws)[..., 0].abs() > REVERSAL_M).float()
    seen = seen.reshape(20_000, 4).mean(0)
    assert torch.allclose(p, seen, atol=0.015)
    assert ((p > 0.05) & (p < 0.99)).all()


def test_approach_frames_of_ground_strokes_and_a_volley():
    # serve 10, bounce 30, return 40, bounce 60, shot 70, volley 80 (no bounce between)
    assert approach_frames([10, 40, 70, 80], [30, 60, 95]) == [(1, 31, 40), (2, 61, 70),
                                                               (3, 73, 80)]
    assert approach_frames([10], [30]) == []


def test_contact_calibration_sums_the_odds_it_is_given(tiny_model_file, monkeypatch):
    """With P(contact) 0.5 on every token the answers are known: over a return's approach of
    n tokens (after the bounce, up to the recorded contact) 1 - 0.5^n, before it
    1 - 0.5^(n-1); expected contacts are half the scored tokens."""
    sim = Simulator.from_pretrained(tiny_model_file, max_retries=0)
    truth = truth_points(DiagnosticsSetup(n_points=30, seed=2))
    out = serve_outcomes(truth)
    monkeypatch.setattr(diagnostics, "window_contact_probabilities",
                        lambda model, windows, batch_size=32:
                        np.full((len(windows), model.cfg.window_frames), 0.5, np.float32))
    cal = contact_calibration(sim, truth)
    ret = out[out["returned"] & (out["return_frame"] < sim.model.cfg.window_frames - 1)]
    n = (ret["return_frame"] - ret["bounce_frame"]).to_numpy(float)
    assert cal["returns"] == len(ret) > 3
    assert cal["return_approach"] == pytest.approx(np.mean(1 - 0.5 ** n), abs=1e-9)
    assert cal["return_before"] == pytest.approx(np.mean(1 - 0.5 ** (n - 1)), abs=1e-9)
    # Every rally's serve is struck inside its first window; no shot reverses the ball twice.
    assert len(truth.rallies) <= cal["contacts"] <= 2 * len(truth.shots)
    windows = diagnostics.first_windows(sim, truth).windows.values()
    tokens = sum(int(w["has_next"].sum()) for w in windows)
    assert cal["ratio"] == pytest.approx(0.5 * tokens / cal["contacts"], rel=1e-6)
    assert cal["early_contacts"] < cal["contacts"]


def test_diagnose_exact_leaks_reaches_the_leak_check(monkeypatch):
    """`--exact-leaks` sets `DiagnosticsSetup.leak_exact`, whose resolution ({}: exact floats)
    the rollouts' leak check gets; by default None, the check's own resolution."""
    from sportsngen.eval import __main__ as cli

    assert diagnostics.DiagnosticsSetup().leak_resolution is None
    assert diagnostics.DiagnosticsSetup(leak_exact=True).leak_resolution == {}
    got = {}

    def fake_table(args, name, compute, notes=None, **setup_kw):
        got.update(setup_kw)
        return 0

    monkeypatch.setattr(cli, "_run_model_table", fake_table)
    assert cli.main(["diagnose", "--exact-leaks"]) == 0
    assert got == {"leak_boot": 200, "leak_exact": True}
    assert cli.main(["diagnose", "--boot", "7"]) == 0
    assert got == {"leak_boot": 7, "leak_exact": False}
    seen = []
    monkeypatch.setattr(diagnostics, "check_leaks",
                        lambda data, **kw: seen.append(kw["resolution"]) or pd.DataFrame(
                            columns=["pair", "role", "feature", "k", "auc", "n_pairs", "lo",
                                     "hi"]))
    record = pd.DataFrame(columns=["pair", "role", "feature", "k", "auc", "n_pairs"])
    for exact in (True, False):
        diagnostics.leak_table_rows(None, record, diagnostics.DiagnosticsSetup(leak_exact=exact))
    assert seen == [{}, None]
