"""Rallies branched at different frames in one rollout (`RolloutInputs.init_frames`): each row
replays its own recorded frames, then draws from the state a rollout of its own would have."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from sportsngen.data.tokens import rally_arrays
from sportsngen.data.toy import make_toy_rallies
from sportsngen.model.export import load_model
from sportsngen.sim.assemble import PLAN_COLUMNS
from sportsngen.sim.rollout import RolloutInputs, rollout
from tests.conftest import tiny_sim


def _inputs(init: np.ndarray, init_frames=None) -> RolloutInputs:
    b = len(init)
    return RolloutInputs(init, np.tile([[2, 3, 0]], (b, 1)), np.zeros(b, np.int64),
                         np.zeros(b, np.int64), np.zeros(b, np.int64),
                         np.zeros((b, 7), np.float32), init_frames)


def _tracks(b: int, t: int) -> np.ndarray:
    rng = np.random.default_rng(3)
    x = rng.normal(0, 1, (b, t, 3, 3)).astype(np.float32)
    x[..., 2] = np.abs(x[..., 2])
    return x


def _deterministic(model):
    """The model's draws made a fixed function of its output state: a row's frames then
    depend only on what the decoder read, not on the batch's random stream."""
    def sample_next(h, pos, *args, **kwargs):
        return pos + 0.05 * torch.tanh(h[..., :3])
    model.sample_next = sample_next
    return model


def test_each_row_replays_its_frames_then_plays_as_a_rollout_of_its_own(tiny_model_file):
    model = _deterministic(load_model(tiny_model_file)[0])
    tracks = _tracks(3, 9)
    kept = np.array([4, 9, 6])
    init = tracks.copy()
    for i, k in enumerate(kept):
        init[i, k:] = np.nan                   # a row's frames past its own count are unread
    n = 14
    together = rollout(model, _inputs(init, kept), n, seed=1)
    assert together.pos_m.shape == (3, n, 3, 3) and (together.length == n).all()
    for i, k in enumerate(kept):
        # The recorded frames exactly, then the frames its own rollout from them draws.
        np.testing.assert_array_equal(together.pos_m[i, :k], tracks[i, :k])
        alone = rollout(model, _inputs(tracks[i:i + 1, :k]), n, seed=7)
        np.testing.assert_allclose(together.pos_m[i], alone.pos_m[0], atol=1e-4)
    assert together.frames_simulated == 3 * (n - kept.min())
    # Every row's count at the full length is the plain rollout, frame for frame.
    np.testing.assert_array_equal(rollout(model, _inputs(tracks, np.full(3, 9)), n).pos_m,
                                  rollout(model, _inputs(tracks), n).pos_m)


def test_init_frames_are_checked():
    tracks = _tracks(2, 5)
    for bad in (np.array([0, 5]), np.array([3, 6]), np.array([2]), np.array([2.0, 3.0])):
        with pytest.raises(ValueError, match="init_frames"):
            _inputs(tracks, bad)
    holed = tracks.copy()
    holed[1, 2] = np.nan                       # inside row 1's own frames
    with pytest.raises(ValueError, match="NaN"):
        _inputs(holed, np.array([5, 3]))
    holed[1, 2] = tracks[1, 2]
    holed[0, 4] = np.nan                       # past row 0's: never read
    assert len(_inputs(holed, np.array([4, 5]))) == 2


def test_simulator_branches_rallies_at_their_own_frames_to_their_own_caps(tiny_model_file):
    sim = tiny_sim(tiny_model_file)
    data = make_toy_rallies(3, seed=3)
    arr = rally_arrays(data, sim.vocab, unknown="generic")
    kept = np.array([5, 12, 8])
    horizon_s = np.array([0.4, 0.8, 0.2])
    init = np.full((3, kept.max(), 3, 3), np.nan, dtype=np.float32)
    for i, k in enumerate(kept):
        init[i, :k] = arr.pos_m[arr.start[i]:arr.start[i] + k]
    plan = data.rallies.set_index("rally_id").loc[arr.rally_id].reset_index()[PLAN_COLUMNS]
    plan = plan.assign(rally_id=np.arange(3))
    cap_s = kept / sim.fps + horizon_s
    out = sim.simulate_rallies(plan, seed=0, init_pos_m=init, init_frames=kept,
                               max_duration_s=cap_s)
    got = rally_arrays(out, sim.vocab, unknown="generic")
    by_id = dict(zip(got.rally_id.tolist(), range(len(got))))
    for i, k in enumerate(kept):
        g = by_id[i]
        np.testing.assert_allclose(got.pos_m[got.start[g]:got.start[g] + k], init[i, :k],
                                   atol=1e-5)
        # Each rally stops at its own cap (frames seen), not the batch's longest.
        assert k < got.length[g] <= round(cap_s[i] * sim.fps)
    assert got.length[by_id[2]] < round(cap_s[1] * sim.fps)
    with pytest.raises(ValueError, match="init_frames has 2 rows"):
        sim.simulate_rallies(plan, init_pos_m=init, init_frames=kept[:2])
