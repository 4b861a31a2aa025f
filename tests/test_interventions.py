"""Forced players' tracks in rollouts and the server interventions built on them."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.eval.diagnostics import serve_strike_frames
from sportsngen.eval.interventions import (
    SERVER_SLOT,
    intervention_outcomes,
    intervention_table,
    server_forcing,
    stopping_track,
)
from sportsngen.model.export import load_model
from sportsngen.sim.rollout import RolloutInputs, rollout
from tests.conftest import tiny_sim


def _inputs(b: int = 3, t0: int = 2) -> RolloutInputs:
    rng = np.random.default_rng(0)
    init = rng.normal(0, 1, (b, t0, 3, 3)).astype(np.float32)
    init[..., 2] = np.abs(init[..., 2])
    return RolloutInputs(init, np.tile([[2, 3, 0]], (b, 1)), np.zeros(b, np.int64),
                         np.zeros(b, np.int64), np.zeros(b, np.int64),
                         np.zeros((b, 7), np.float32))


def test_a_forced_player_takes_his_track_and_the_rest_is_sampled(tiny_model_file):
    model = load_model(tiny_model_file)[0]
    inputs, n = _inputs(), 12
    free = rollout(model, inputs, n, seed=1)
    forced = np.full((3, 8, 3, 3), np.nan, dtype=np.float32)
    track = np.stack([np.linspace(5.0, 6.0, 6), np.linspace(-1.0, 1.0, 6), np.zeros(6)], 1)
    forced[1, 2:, 0] = track                       # rally 1's server, frames 2-7
    got = rollout(model, inputs, n, seed=1, forced_pos_m=forced)
    np.testing.assert_array_equal(got.pos_m[1, 2:8, 0], track.astype(np.float32))
    # Untouched rows and all-NaN forcing draw what a free rollout draws.
    np.testing.assert_allclose(got.pos_m[[0, 2]], free.pos_m[[0, 2]], atol=1e-5)
    nan_only = rollout(model, inputs, n, seed=1, forced_pos_m=np.full((3, n, 3, 3), np.nan))
    np.testing.assert_allclose(nan_only.pos_m, free.pos_m, atol=1e-5)
    # After his forced frames the server is sampled again, and the others react to him.
    assert not np.allclose(got.pos_m[1, 8:, 0], track[-1], atol=1e-3)
    assert not np.allclose(got.pos_m[1, 3:, 1:], free.pos_m[1, 3:, 1:], atol=1e-4)


@pytest.mark.parametrize("bad, match", [
    (np.full((2, 4, 3, 3), np.nan), r"\(3, T, 3, 3\)"),
    (np.full((3, 4, 3), np.nan), r"\(3, T, 3, 3\)"),
])
def test_forced_tracks_of_the_wrong_shape_are_refused(tiny_model_file, bad, match):
    model = load_model(tiny_model_file)[0]
    with pytest.raises(ValueError, match=match):
        rollout(model, _inputs(), 6, forced_pos_m=bad)


def test_forced_tracks_force_whole_players_only(tiny_model_file):
    model = load_model(tiny_model_file)[0]
    f = np.full((3, 6, 3, 3), np.nan)
    f[0, 3, 2] = [0.0, 0.0, 1.0]
    with pytest.raises(ValueError, match="players only"):
        rollout(model, _inputs(), 6, forced_pos_m=f)
    f = np.full((3, 6, 3, 3), np.nan)
    f[0, 3, 0, :2] = 1.0                           # x and y but no height
    with pytest.raises(ValueError, match="all NaN or all finite"):
        rollout(model, _inputs(), 6, forced_pos_m=f)
    f[0, 3, 0, 2] = np.inf
    with pytest.raises(ValueError, match="infinite"):
        rollout(model, _inputs(), 6, forced_pos_m=f)


def test_a_stopping_player_brakes_at_the_cap_and_stands():
    # 5 m/s along (0.6, 0.8) braking at 6 m/s^2: stands after 5/6 s, 25/12 m on.
    got = stopping_track(np.array([[1.0, 2.0, 0.5]]), np.array([[3.0, 4.0, 9.0]]), 30, 25.0)[0]
    first = 5.0 * 0.04 - 3.0 * 0.04 ** 2
    np.testing.assert_allclose(got[0], [1.0 + 0.6 * first, 2.0 + 0.8 * first, 0.5])
    np.testing.assert_allclose(got[-1], [1.0 + 0.6 * 25 / 12, 2.0 + 0.8 * 25 / 12, 0.5])
    speed = np.hypot(*np.diff(got[:, :2], axis=0).T) * 25.0
    assert (np.diff(speed) <= 1e-9).all() and speed[-1] == 0.0
    assert np.abs(np.diff(speed)).max() <= 6.0 / 25.0 + 1e-9
    # A player already standing stays where he is.
    np.testing.assert_array_equal(stopping_track(np.zeros((1, 3)), np.zeros((1, 3)), 4, 25.0),
                                  np.zeros((1, 4, 3)))


def test_server_forcing_arms_on_recorded_serves(truth_data):
    truth = truth_data(40, 4)
    arr = rally_arrays(truth, Vocab.from_data(truth, generic=True))
    keep = serve_strike_frames(truth) + 4
    rec = {int(r): arr.pos_m[s:s + n, SERVER_SLOT] for r, s, n in
           zip(arr.rally_id, arr.start, arr.length)}
    assert server_forcing(truth, "free") == {}
    with pytest.raises(ValueError, match="arm must be"):
        server_forcing(truth, "frozen")
    recorded = server_forcing(truth, "recorded")
    still = server_forcing(truth, "still")
    swapped = server_forcing(truth, "swapped", seed=3)
    assert set(recorded) == set(still) == set(swapped) == set(keep.index)
    speeds = {}
    for rid, f in recorded.items():
        k = int(keep[rid])
        assert np.isnan(f[:k]).all() and np.isnan(f[:, 1:]).all()   # only the server, after k
        n = min(len(f), len(rec[rid]))
        np.testing.assert_allclose(f[k:n, SERVER_SLOT], rec[rid][k:n], atol=1e-6)
        s = still[rid][k:, SERVER_SLOT]
        step = np.hypot(*np.diff(np.concatenate([rec[rid][k - 1:k], s])[:, :2], axis=0).T)
        assert (np.diff(step) <= 1e-6).all() and step[-1] == 0.0
        speeds[rid] = np.round(np.hypot(*np.diff(f[k - 0:, SERVER_SLOT, :2], axis=0).T), 4)
    # Swapped runs are the recorded runs of other serves of the same serve number (their
    # speeds, turned in the plane, are kept), from this serve's last kept frame.
    number = truth.rallies.set_index("rally_id")["serve_number"]
    for serve in (1, 2):
        ids = [r for r in swapped if number[r] == serve]
        moved = {tuple(np.round(np.hypot(*np.diff(swapped[r][int(keep[r]):, SERVER_SLOT, :2],
                                                     axis=0).T), 4)) for r in ids}
        assert moved == {tuple(speeds[r]) for r in ids}
    assert any(not np.allclose(swapped[r], recorded[r], equal_nan=True) for r in swapped)


def test_intervention_table_on_known_outcomes():
    rows = []
    for rid, (box, ret_rec, ret_still) in enumerate([(True, True, False), (True, True, True),
                                                      (True, False, False), (False, False, False),
                                                      (True, True, True)]):
        rows += [{"arm": "recorded", "rally_id": rid, "in_box": box, "returned": ret_rec,
                  "server_speed_mps": 1.0 + rid},
                 {"arm": "still", "rally_id": rid, "in_box": box and rid != 4,
                  "returned": ret_still and rid != 4, "server_speed_mps": 0.0}]
    t = intervention_table(pd.DataFrame(rows), n_boot=200).set_index("arm")
    assert t.loc["recorded", "n_in_box"] == 4 and t.loc["recorded", "returned"] == 0.75
    assert t.loc["recorded", "diff"] == 0.0 and t.loc["recorded", "server_speed_mps"] == 3.0
    # Serves 0-2 are in the box in both arms: one return of three lost.
    assert t.loc["still", "n_pairs"] == 3 and t.loc["still", "diff"] == pytest.approx(-1 / 3)
    assert t.loc["still", "lo"] >= -1.0 and t.loc["still", "hi"] <= 0.0
    assert t.loc["still", "returned"] == pytest.approx(1 / 3)
    with pytest.raises(ValueError, match="no 'free' arm"):
        intervention_table(pd.DataFrame(rows), base="free")


def test_intervention_outcomes_force_the_server_in_rollouts(tiny_model_file, truth_data):
    sim = tiny_sim(tiny_model_file)
    truth = truth_data(40, 4)
    with pytest.warns(UserWarning, match="unknown player"):
        out = intervention_outcomes(sim, truth, arms=("free", "still"), horizon_s=0.8)
    n = len(serve_strike_frames(truth))
    assert out.groupby("arm").size().to_dict() == {"free": n, "still": n}
    still = out[out["arm"] == "still"]["server_speed_mps"].dropna()
    free = out[out["arm"] == "free"]["server_speed_mps"].dropna()
    # (A branch the tiny model's rally ends within 12 frames has no speed to read.)
    assert len(still) > n // 2 and (still == 0.0).all()
    assert (free > 0.0).mean() > 0.5


def test_interventions_command_refuses_bad_input(capsys):
    from sportsngen.eval.__main__ import main

    assert main(["interventions", "--arms", "free", "frozen"]) == 2
    assert "unknown ['frozen']" in capsys.readouterr().err
    assert main(["interventions", "--arms", "free", "still"]) == 2
    assert "must include 'recorded'" in capsys.readouterr().err
    assert main(["interventions", "--boot", "-1"]) == 2
    assert "--boot must be >= 0" in capsys.readouterr().err
    assert main(["interventions", "--points", "5"]) == 2
    assert "--points must be >= 20" in capsys.readouterr().err
