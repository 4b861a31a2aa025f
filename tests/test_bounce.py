"""The surface's bounce in rollouts (`sportsngen.sim.bounce`) against the generator's flights."""

import numpy as np
import pytest
import torch

from sportsngen.model.centre import read_lift_mps2
from sportsngen.model.inputs import BALL
from sportsngen.sim.bounce import bounce_frames, bouncing_rows, place_bounces, spin_from_lift_mps
from sportsngen.synth.physics import fly
from sportsngen.tennis.court import BALL_RADIUS_M

FPS = 25.0


def _track(pos0, vel0, spin, surface, seconds=1.6):
    """The generator's flight at 25 Hz (T, 3) and its first bounce's time."""
    f = fly(np.array(pos0), np.array(vel0), spin, surface, seconds, max_bounces=2)
    t = np.arange(0.0, min(seconds, f.t_end_s), 1.0 / FPS)
    return f.at(t), f.first_bounce().t_s


def _states(track, k):
    """The rollout's (B=1) position, velocity and previous velocity at frame k, ball only."""
    def obj(p):
        out = torch.zeros(1, 3, 3, dtype=torch.float64)
        out[0, BALL] = torch.as_tensor(p)
        return out
    return (obj(track[k]), obj((track[k] - track[k - 1]) * FPS),
            obj((track[k - 1] - track[k - 2]) * FPS))


@pytest.mark.parametrize("spin", [-4.0, 0.0, 3.0, 8.0])
def test_spin_is_read_back_from_the_generators_magnus(spin):
    track, _ = _track([-11.0, 1.0, 1.0], [28.0, -1.0, 3.0], spin, "hard")
    v = torch.as_tensor((track[1:] - track[:-1]) * FPS)
    lift, flight = read_lift_mps2(v[2:8], v[1:7], FPS)
    assert bool(flight.all())
    read = spin_from_lift_mps(lift, v[2:8]).numpy()
    assert np.abs(read - spin).max() < 0.1 * abs(spin) + 0.1


@pytest.mark.parametrize("surface", ["hard", "clay", "grass"])
@pytest.mark.parametrize("launch", [([-11.5, 2.0, 2.7], [45.0, -4.0, -4.0], 2.0),     # a serve
                                    ([-12.0, -1.0, 1.0], [24.0, 2.0, 6.0], 6.0),     # topspin
                                    ([-12.0, 0.5, 1.0], [20.0, 0.0, 4.0], -4.0)])    # slice
def test_the_bounce_frames_follow_the_generators_bounce(surface, launch):
    track, t_bounce = _track(*launch, surface)
    k = int(np.floor(t_bounce * FPS))               # the frame before the bounce
    pos, vel, prev = _states(track, k)
    assert bool(bouncing_rows(pos, vel, prev, FPS)[0])
    assert not bool(bouncing_rows(*_states(track, k - 1), FPS)[0])
    frames = bounce_frames(pos, vel, prev, FPS, [surface])[0].numpy()
    # Read from the track's frames (a backward difference, the lift from three frames) the
    # bounce lands within 2 cm of the generator's next three frames; the physics centre's own
    # steps (one restitution, the horizontal speed kept) miss the second by 0.16-0.71 m.
    assert np.abs(frames - track[k + 1:k + 4]).max() < 0.02


@pytest.mark.parametrize("surface", ["hard", "clay"])
@pytest.mark.parametrize("launch", [([-12.0, -1.0, 1.0], [24.0, 2.0, 6.0], 6.0),     # topspin
                                    ([-12.0, 0.5, 1.2], [30.0, 0.0, 2.0], 3.0)])     # flatter
def test_the_first_free_step_after_a_bounce_keeps_the_topspin_it_gave(surface, launch):
    """The bounce's friction gives a rally ball topspin, and the rising ball falls faster than
    gravity and drag alone take it. With the bounce's frame and the two after it given, the
    physics centre's first free step reads that spin from three post-bounce frames and flies
    where the generator's ball goes (within a millimetre); from two given frames its reading
    spans the bounce, gravity and drag alone, and the step misses upward by millimetres, which
    the model then carried on as a ball without spin."""
    from sportsngen.model.centre import physics_step_m

    track, t_bounce = _track(*launch, surface)
    k = int(np.floor(t_bounce * FPS))
    pos, vel, prev = _states(track, k)
    given = bounce_frames(pos, vel, prev, FPS, [surface])[0].numpy()
    flown = np.concatenate([track[:k + 1], given])
    step = lambda tr: physics_step_m(*(torch.as_tensor(a)[None] for a in (  # noqa: E731
        tr[-1], (tr[-1] - tr[-2]) * FPS, (tr[-2] - tr[-3]) * FPS)), FPS)[0].numpy()
    after_three = step(flown)
    assert np.abs(after_three - track[k + 4]).max() < 1e-3
    if launch[2] > 5.0:   # a heavy topspin ball; a flat bounce can read as a flight (a lift)
        after_two = step(flown[:-1])                # the free step from the second given frame
        assert after_two[2] - track[k + 3, 2] > 1.5e-3   # no spin read: it flies high


def test_place_bounces_replaces_only_unplanned_bouncing_rows():
    track, t_bounce = _track([-11.5, 2.0, 2.7], [45.0, -4.0, -4.0], 2.0, "clay")
    k = int(np.floor(t_bounce * FPS))
    rows = [_states(track, k), _states(track, k), _states(track, k - 5), _states(track, k)]
    pos, vel, prev = (torch.cat([r[i] for r in rows]).float() for i in range(3))
    nxt = pos.clone()
    plan = torch.full((4, 2, 3), float("nan"))
    plan[1, 0] = 1.0                                  # row 1 follows a launch
    placed = torch.tensor([False, False, False, True])   # row 3's frame was a planned one
    out, new_plan = place_bounces(nxt, plan, pos, vel, prev, FPS,
                                  np.array(["hard", "clay", "clay", "hard"]),
                                  np.array([1, 0, 2, 3]), placed)
    # Row 0 is batch row 1 as first given: clay.
    want = bounce_frames(pos[:1], vel[:1], prev[:1], FPS, ["clay"])[0]
    assert torch.allclose(out[0, BALL], want[0]) and torch.allclose(new_plan[0], want[1:])
    assert torch.equal(out[1:], nxt[1:])
    assert torch.equal(new_plan[1, 0], plan[1, 0])
    assert torch.isnan(new_plan[2]).all() and torch.isnan(new_plan[3]).all()


def test_rollout_serves_land_where_their_flight_takes_them_with_the_surfaces_bounce():
    """In the bundled model's rollouts with the surface's bounce, the rules read every serve's
    bounce where the flight after its launch lands (the frame after a bounce, read as a state,
    bounced the ball again and moved the rules' reading up to a metre), and the ball leaves the
    ground as the generator's clay sends it: horizontal speed kept 0.55-0.66 on a serve."""
    from sportsngen.data.tracking import RallyData  # noqa: F401  (the simulator's output)
    from sportsngen.model.strike import flight_outcome, fly_on
    from sportsngen.sim import Simulator

    sim = Simulator.from_pretrained(max_duration_s=1.8, physical_bounce=True)
    data = sim.simulate_points("Novak Djokovic", "Andy Murray", "clay", 24, seed=1,
                               serve_number=1)
    serves = data.shots[data.shots["shot_index"] == 0].set_index("rally_id")
    ball = data.frames[data.frames["object"] == "ball"]
    checked = 0
    for rid, g in ball.groupby("rally_id"):
        if rid not in serves.index or not np.isfinite(serves.at[rid, "bounce_x"]):
            continue
        b = g.sort_values("frame")[["x", "y", "z"]].to_numpy(float)
        a = int(serves.at[rid, "frame"])
        after = b[a + 1:a + 4][None]
        track = np.concatenate([after, fly_on(after, FPS)], axis=1)
        land = flight_outcome(track, np.sign(b[a:a + 1, 0]))[0]
        assert abs(abs(serves.at[rid, "bounce_x"]) - abs(land[0])) < 0.03
        k = a + 1 + int(np.argmax(np.diff(b[a + 1:, 2]) > 0))     # the first frame rising
        if k + 2 >= len(b):
            continue
        h_in = np.hypot(*(b[k - 1, :2] - b[k - 2, :2]))
        h_out = np.hypot(*(b[k + 2, :2] - b[k + 1, :2]))
        assert 0.55 < h_out / h_in < 0.66
        checked += 1
    assert checked >= 15


def test_the_surfaces_bounce_needs_a_model_that_plans_frames(tiny_model_file):
    from sportsngen.errors import ArgumentError
    from sportsngen.sim import Simulator

    sim = Simulator.from_pretrained(tiny_model_file)
    assert sim.physical_bounce is False
    assert sim.model.strike_head is None and sim.model.serve_head is None
    with pytest.raises(ArgumentError, match="physical_bounce"):
        Simulator.from_pretrained(tiny_model_file, physical_bounce=True)


def test_the_numpy_reading_of_a_bounce_is_the_torch_one(monkeypatch):
    """`bouncing_rows`' numpy lines against its torch ones: balls falling and rising at every
    height around the ground, flights and jolts, and heights a float32 step from the radius."""
    import sportsngen.sim.bounce as bounce

    g = torch.Generator().manual_seed(3)
    n = 20000
    pos, vel, prev = (torch.zeros(n, 3, 3) for _ in range(3))
    pos[:, 2, 2] = torch.empty(n).uniform_(-0.05, 0.6, generator=g)
    vel[:, 2] = torch.randn(n, 3, generator=g) * torch.tensor([20.0, 4.0, 8.0])
    prev[:, 2] = vel[:, 2] + torch.randn(n, 3, generator=g) * 0.5
    # z_next exactly at the radius's float32 neighbours: a still ball (no fall, no flight).
    r = np.float32(BALL_RADIUS_M)
    pos[:3, 2, 2] = torch.tensor([np.nextafter(r, 0), r, np.nextafter(r, 1)])
    vel[:3, 2], prev[:3, 2] = torch.tensor([0.0, 0.0, -1e-30]), 0.0
    fast = bouncing_rows(pos, vel, prev, FPS)
    monkeypatch.setattr(bounce, "kernel_inputs", lambda *t: False)
    ref = bouncing_rows(pos, vel, prev, FPS)
    assert torch.equal(fast, ref)
    assert 0.05 < ref.float().mean() < 0.5
