"""A rally strike as landing, net height and spin (`sportsngen.model.strike`)."""

import numpy as np
import pytest
import torch

from sportsngen.model import strike as S
from sportsngen.model.centre import physics_step_m
from sportsngen.tennis.court import BASELINE_X_M, SINGLES_HALF_WIDTH_M

FPS = 25.0


def test_the_court_lines_are_edges_of_the_strike_bins():
    edges = S.strike_edges()
    assert edges.shape == (4, S.STRIKE_BINS + 1)
    assert np.isclose(edges[0], BASELINE_X_M).sum() == 1
    assert np.isclose(edges[1], SINGLES_HALF_WIDTH_M).sum() == 1
    assert np.isclose(edges[1], -SINGLES_HALF_WIDTH_M).sum() == 1
    # A bin's values map back to it; values beyond the range take the outer bins.
    idx = np.array([[0, 5, 50, 95], [47, 20, 13, 60]])
    for u in (0.01, 0.5, 0.99):
        assert (S.strike_bin_index(S.strike_bin_value(idx, np.full(idx.shape, u))) == idx).all()
    far = S.strike_bin_index(np.array([[-50.0, 50.0, -1.0, 9.0]]))
    assert far.tolist() == [[0, S.STRIKE_BINS - 1, 0, S.STRIKE_BINS - 1]]
    # Just inside the baseline and just beyond it fall in different bins.
    a, b = S.strike_bin_index(np.array([[BASELINE_X_M - 1e-6, 0, 1, 0],
                                        [BASELINE_X_M + 1e-6, 0, 1, 0]]))[:, 0]
    assert b == a + 1


def test_the_numpy_flight_is_the_physics_centres_step():
    rng = np.random.default_rng(0)
    n = 200
    v = np.stack([rng.uniform(-35, 35, n), rng.uniform(-8, 8, n), rng.uniform(-8, 8, n)], -1)
    prev = v + rng.normal(0, 0.4, (n, 3))      # flights, and some reads that are no flight
    prev[::5] += rng.normal(0, 8, prev[::5].shape)
    p = np.stack([rng.uniform(-11, 11, n), rng.uniform(-4, 4, n), rng.uniform(2, 4, n)], -1)
    frames = np.stack([p - (v + prev) / FPS, p - v / FPS, p], axis=1)
    ours = S.fly_on(frames, FPS, n_frames=4)
    q = torch.as_tensor(frames)
    for k in range(4):
        vel = (q[:, -1] - q[:, -2]) * FPS
        pv = (q[:, -2] - q[:, -3]) * FPS
        nxt = physics_step_m(q[:, -1], vel, pv, FPS)
        assert np.allclose(ours[:, k], nxt.numpy(), atol=1e-9), k
        q = torch.cat([q[:, 1:], nxt[:, None]], dim=1)


def test_a_solved_launch_lands_where_it_was_asked_and_reads_back_the_same():
    contact = np.array([[11.0, 1.0, 1.0], [-12.5, -2.0, 0.6], [9.0, 3.0, 2.2], [-11.5, 0.5, 0.9]])
    side = np.sign(contact[:, 0])
    # Deep topspin, short cross-court slice, a lob, a ball into the net.
    asked = np.array([[10.5, 2.0, 1.6, -0.16], [6.0, -3.5, 1.1, 0.08],
                      [11.0, 0.0, 6.5, -0.1], [3.0, 1.0, 0.7, -0.15]])
    v0, found = S.solve_launch(contact, side, asked, FPS)
    assert found.all()
    assert (side * v0[:, 0] < 0).all()                  # toward the other half
    frames = S.launch_frames(contact, v0, asked[:, 3], FPS)
    read = S.strike_labels(frames, side, FPS)
    assert np.allclose(read, asked, atol=0.02)
    # The lob flies high and slow; the drive fast.
    speed = np.linalg.norm(v0, axis=-1)
    assert speed[0] > 25 and v0[2, 2] > 8


def test_an_impossible_strike_is_reported_not_found():
    contact = np.array([[11.0, 0.0, 1.0]])
    # 11 m beyond the net, crossing it 5 cm above the ground: no flight does that.
    v0, found = S.solve_launch(contact, np.array([1.0]), np.array([[11.0, 0.0, 0.05, -0.2]]),
                               FPS)
    assert not found[0]
    assert np.linalg.norm(v0) <= S.MAX_LAUNCH_MPS + 1e-6


def test_a_strike_is_a_ball_turned_back_from_the_hitters_half_not_a_toss():
    pos = np.array([[11.0, 1.0, 1.0], [11.0, 1.0, 2.5], [-10.0, 0.0, 1.0], [11.0, 1.0, 1.0]])
    vel = np.array([[25.0, 0, 0], [0.0, 0, 3.0], [-20.0, 1.0, 0.0], [-25.0, 0, 0]])
    nxt = pos + np.array([[-1.2, 0, 0.1], [-2.0, 0, 0.1], [0.8, 0, 0], [-1.0, 0, 0]])
    # A return; a serve from its toss; a return at the other end; a ball already going away.
    assert S.is_strike(pos, vel, nxt, FPS).tolist() == [True, False, True, False]


@pytest.fixture(scope="module")
def recorded_strikes():
    from sportsngen.data.tokens import Vocab, rally_arrays
    from sportsngen.eval.diagnostics import DiagnosticsSetup, truth_points

    data = truth_points(DiagnosticsSetup(n_points=60, seed=3))
    arr = rally_arrays(data, Vocab.from_data(data))
    shots = data.shots
    rows = []
    for i, rid in enumerate(arr.rally_id):
        ball = arr.pos_m[arr.start[i]:arr.start[i] + arr.length[i], 2].astype(float)
        vel = np.zeros_like(ball)
        vel[1:] = (ball[1:] - ball[:-1]) * data.fps
        first = int(data.frames.loc[data.frames["rally_id"] == rid, "frame"].min())
        for t in np.flatnonzero(S.is_strike(ball[:-1], vel[:-1], ball[1:], data.fps)):
            if t + 3 >= len(ball):
                continue
            shot = shots[(shots["rally_id"] == rid) & (shots["shot_index"] > 0)
                         & ((shots["frame"] - first - t).abs() <= 1)]
            if len(shot) == 1:
                rows.append((ball[t + 1:t + 4], np.sign(ball[t, 0]),
                             shot[["bounce_x", "bounce_y"]].to_numpy(float)[0]))
    after, side, bounce = (np.array(c) for c in zip(*rows))
    return after, side, bounce, data.fps


def test_recorded_strikes_read_where_the_generator_bounced_them(recorded_strikes):
    after, side, bounce, fps = recorded_strikes
    labels = S.strike_labels(after, side, fps)
    landed = np.isfinite(bounce).all(-1)
    assert landed.sum() > 40
    ok = landed & np.isfinite(labels).all(-1)
    assert ok.mean() > 0.9 * landed.mean()
    read = np.stack([-side * labels[:, 0], -side * labels[:, 1]], -1)[ok]
    err = np.linalg.norm(read - bounce[ok], axis=-1)
    # The physics centre's flight from the strike's first three frames lands where the
    # generator's ball bounced (its own spin model, read from three frames).
    assert np.median(err) < 0.2 and np.percentile(err, 90) < 0.35
    # Rally balls: topspin for most, clear the net, land in the other half.
    assert np.median(labels[ok, 3]) < 0 and np.median(labels[ok, 2]) > 1.0
    assert 4.0 < np.median(labels[ok, 0]) < BASELINE_X_M


def _struck_model():
    from sportsngen.model import SportsNGEN
    from tests.test_model import tiny_cfg

    torch.manual_seed(0)
    return SportsNGEN(tiny_cfg(strike_head=True, ball_centre="physics")).eval()


def _incoming_then_launch(asked: np.ndarray):
    """A ball coming to the +x half at 25 m/s for three frames, struck at the third toward
    `asked` (4,): (6, 3) frames."""
    before = np.array([[9.0 - 1.0 * k, 1.0, 1.0] for k in (2, 1, 0)])
    before[:, 0] = 11.0 - np.array([2.0, 1.0, 0.0])
    side = np.array([1.0])
    v0, found = S.solve_launch(before[-1:], side, asked[None], FPS)
    assert found.all()
    return np.concatenate([before, S.launch_frames(before[-1:], v0, asked[None, 3], FPS)[0]])


def test_strike_targets_find_the_strike_and_its_bins():
    model = _struck_model()
    asked = np.array([9.7, -1.3, 1.45, -0.137])
    ball = torch.as_tensor(_incoming_then_launch(asked), dtype=torch.float32)
    pos = torch.zeros(1, 6, 3, 3)
    pos[0, :, 2] = ball
    vel = torch.zeros_like(pos)
    vel[:, 1:] = (pos[:, 1:] - pos[:, :-1]) * FPS
    vel[:, 0] = vel[:, 1]
    nxt = torch.cat([pos[:, 1:], pos[:, -1:]], dim=1)
    has_next = torch.tensor([[True] * 5 + [False]])
    mask, bins = model.strike_targets(pos[:, :5], vel[:, :5], nxt[:, :5], has_next[:, :5])
    assert mask.tolist() == [[False, False, True, False, False]]
    assert bins[0, 2].tolist() == S.strike_bin_index(asked[None]).tolist()[0]
    h = torch.randn(1, 5, 3, model.cfg.d_model)
    nll = model.strike_nll(h, mask, bins)
    assert nll[0, 2] > 0 and (nll[0, [0, 1, 3, 4]] == 0).all()


def test_a_sampled_strike_is_placed_on_its_solved_flight(monkeypatch):
    from sportsngen.sim.rollout import _follow_strikes

    model = _struck_model()
    asked = np.array([10.2, 2.1, 1.7, -0.12])
    want = torch.as_tensor(S.strike_bin_index(asked[None]))
    monkeypatch.setattr(model.strike_head, "sample", lambda h, top_p, gen: want.expand(len(h), 4))
    ball = _incoming_then_launch(asked)
    pos = torch.zeros(2, 3, 3)
    pos[:, 2] = torch.as_tensor(ball[2], dtype=torch.float32)
    vel = torch.zeros_like(pos)
    vel[:, 2] = torch.as_tensor((ball[2] - ball[1]) * FPS, dtype=torch.float32)
    nxt = pos.clone()
    nxt[0, 2] += torch.tensor([-1.1, 0.0, 0.1])      # the model's draw: a strike
    nxt[1, 2] += torch.tensor([-0.9, 0.0, 0.0])      # ... and one the ball flies on through
    nxt[1, 2, 0] = pos[1, 2, 0] + 0.9
    h = torch.randn(2, 3, model.cfg.d_model)
    g = torch.Generator().manual_seed(0)
    plan = torch.full((2, 2, 3), float("nan"))
    out, plan = _follow_strikes(model, h, pos, vel, nxt, plan, g)
    assert torch.equal(out[1], nxt[1]) and torch.isnan(plan[1]).all()
    frames = [out[0, 2].double().numpy()]
    # The next two frames come from the plan whatever the model draws.
    prev = pos
    for _ in range(2):
        vel, prev = (out - prev) * FPS, out
        out, plan = _follow_strikes(model, h, out, vel, out.clone(), plan, g)
        frames.append(out[0, 2].double().numpy())
    assert torch.isnan(plan).all()
    read = S.strike_labels(np.array(frames)[None], np.array([1.0]), FPS)
    assert S.strike_bin_index(read).tolist() == want.tolist()
