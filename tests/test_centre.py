"""The bins' centres (`sportsngen.model.centre`): the ball's physics step against the
generator's own flights, and its fallbacks at contacts and bounces."""

import numpy as np
import pytest
import torch

from sportsngen.model.centre import (
    BALL_RADIUS_M,
    DRAG_PER_M,
    GRAVITY_MPS2,
    MAGNUS_PER_M,
    MAX_LIFT_MPS2,
    MAX_LIFT_PER_M,
    ball_acceleration_mps2,
    ball_centre_m,
    flight_acceleration_mps2,
    magnus_scale,
    net_cord_m,
    object_centres_m,
    physics_step_m,
    turned_lift_mps2,
)
from sportsngen.model.config import ModelConfig
from sportsngen.synth.physics import DEFAULT_AERO, fly

FPS = 25.0


def track(flight, n_frames: int) -> torch.Tensor:
    """Frames of a flight at 25 Hz (n, 3)."""
    return torch.as_tensor(flight.at(np.arange(n_frames) / FPS), dtype=torch.float32)


def miss_m(pos: torch.Tensor, mode: str, net: bool = False) -> torch.Tensor:
    """|next frame - centre| (n - 3, 3) for frames 2 .. n - 2 of a track."""
    vel = (pos[1:] - pos[:-1]) * FPS           # backward differences of frames 1 ..
    c = ball_centre_m(pos[2:-1], vel[1:-1], vel[:-2], FPS, mode, net)
    return (pos[3:] - c).abs()


def test_drag_and_magnus_constants_are_the_generators():
    assert DRAG_PER_M == pytest.approx(DEFAULT_AERO.k_per_m * DEFAULT_AERO.drag_coefficient,
                                       rel=0.01)
    assert MAGNUS_PER_M == pytest.approx(DEFAULT_AERO.k_per_m * DEFAULT_AERO.lift_scale,
                                         rel=0.01)


@pytest.mark.parametrize("spin_mps", [0.0, 8.0, -4.0])
def test_physics_step_follows_a_spinning_flight_to_a_millimetre(spin_mps):
    # A rally ball with top- or backspin, before its bounce: constant velocity misses by
    # centimetres (gravity alone moves it 1.6 cm a frame), the physics step by < 1 mm.
    f = fly([-12.0, 1.0, 1.0], [30.0, -2.0, 4.0], spin_mps, "hard", 0.6, max_bounces=1)
    pos = track(f, 14)
    assert float(pos[:, 2].min()) > 0.3                       # no bounce in these frames
    assert float(miss_m(pos, "physics").max()) < 0.4e-3
    assert float(miss_m(pos, "velocity")[:, 2].min()) > 0.01
    assert float(miss_m(pos, "current")[:, 0].min()) > 0.5


def eased(vel: torch.Tensor, prev: torch.Tensor) -> torch.Tensor:
    """The track's acceleration carried a frame on: gravity plus drag at frame t's velocity,
    the lift read from the track (at frame t - 1, the mean velocity) turned with it."""
    lift = (vel - prev) * FPS - flight_acceleration_mps2(0.5 * (prev + vel))
    return flight_acceleration_mps2(1.5 * vel - 0.5 * prev) + turned_lift_mps2(lift, prev, vel)


def test_lift_across_the_flight_turns_with_the_velocity_sideways_is_kept_along_is_dropped():
    prev = torch.tensor([30.0, 0.0, 0.0])
    vel = torch.tensor([29.6, 0.0, -0.4])                 # one frame of a dipping rally ball
    turned = turned_lift_mps2(torch.tensor([0.0, 0.0, 6.0]), prev, vel)
    # Still across the flight, leaning forward as the ball dips, its size the generator's
    # Magnus at the new speed for the spin that gives 6 m/s^2 at 30 m/s: k |v|^2 s / (2 s + |v|).
    assert abs(float(turned @ vel)) / float(vel.norm()) < 0.06
    assert float(turned[0]) > 0.1
    c = 6.0 / (MAGNUS_PER_M * 30.0 ** 2)
    spin = c * 30.0 / (1.0 - 2.0 * c)
    w = float(vel.norm())
    expect = MAGNUS_PER_M * w * w * spin / (2.0 * spin + w)
    assert float(turned.norm()) == pytest.approx(expect, rel=1e-4)
    assert expect < 6.0 * w / 30.0          # less than in proportion to |v| (the old size)
    # Sideways: kept as read. Along the flight (Magnus has none, drag is the step's): dropped.
    assert torch.allclose(turned_lift_mps2(torch.tensor([0.0, 0.5, 0.0]), prev, vel),
                          torch.tensor([0.0, 0.5, 0.0]), atol=1e-6)
    assert torch.allclose(turned_lift_mps2(torch.tensor([2.0, 0.0, 0.0]), prev, vel),
                          torch.zeros(3), atol=0.02)
    # A rising flight: the part along (30, 0, 10) goes, the part across it stays.
    up = torch.tensor([30.0, 0.0, 10.0])
    push = 0.1 * up + torch.tensor([-1.0, 0.0, 3.0])
    assert torch.allclose(turned_lift_mps2(push, up, up), torch.tensor([-1.0, 0.0, 3.0]),
                          atol=1e-5)
    # The same in any horizontal direction: a flight along -y.
    turned_y = turned_lift_mps2(torch.tensor([0.0, 0.0, 6.0]), torch.tensor([0.0, -30.0, 0.0]),
                                torch.tensor([0.0, -29.6, -0.4]))
    assert torch.allclose(turned_y, turned[[1, 0, 2]] * torch.tensor([1.0, -1.0, 1.0]),
                          atol=1e-5)


def test_the_lift_keeps_its_spin_as_the_ball_slows():
    # The generator's lift across the flight, k |v|^2 s / (2 s + |v|), is `across` times the
    # |v|-long direction: across = k |v| s / (2 s + |v|).
    for spin, u, w in ((4.0, 20.0, 13.0), (8.0, 30.0, 29.0), (0.5, 25.0, 10.0)):
        across = torch.tensor(MAGNUS_PER_M * u * spin / (2 * spin + u))
        want = MAGNUS_PER_M * w * spin / (2 * spin + w) / float(across)
        got = float(magnus_scale(across, torch.tensor(u), torch.tensor(w)))
        assert got == pytest.approx(want, rel=1e-5)
    # Little spin: in proportion to |v| / |v| = 1 (the small-spin limit); a reading beyond any
    # spin is capped, never inverted to an infinite one.
    assert float(magnus_scale(torch.tensor(1e-6), torch.tensor(20.0), torch.tensor(13.0))) == \
        pytest.approx(1.0, abs=1e-4)
    huge = float(magnus_scale(torch.tensor(100.0), torch.tensor(20.0), torch.tensor(13.0)))
    assert np.isfinite(huge) and 13.0 / 20.0 < huge < 1.0


@pytest.mark.parametrize("spin_mps, vel_mps", [
    (8.0, [28.0, -2.0, 5.0]), (-4.0, [28.0, -2.0, 5.0]), (15.0, [28.0, -2.0, 5.0]),
    (8.0, [14.0, 0.5, 9.0]), (-4.0, [14.0, 0.5, 9.0]), (-6.0, [14.0, 0.5, 9.0])])
def test_a_flight_flown_by_the_step_alone_stays_on_the_generators(spin_mps, vel_mps):
    # Given three frames, the step alone flies a rally ball 17-37 frames and a slow high ball
    # 38-50 to the last frame above 0.3 m and misses the generator's by under a centimetre.
    # With the lift's size in proportion to |v| it missed by 4-21 cm and 9-29 cm (the slow
    # ball's spin grew as it slowed); carried unturned, 25-40 cm.
    f = fly([-12.0, 1.0, 1.0], vel_mps, spin_mps, "hard", 3.0, max_bounces=1)
    pos = track(f, min(60, int(float(f.t_s[-1]) * FPS))).double()
    flown = list(pos[:3])
    while len(flown) < len(pos) and float(pos[len(flown), 2]) > 0.3:
        v, pv = (flown[-1] - flown[-2]) * FPS, (flown[-2] - flown[-3]) * FPS
        flown.append(physics_step_m(flown[-1], v, pv, FPS))
    last = len(flown) - 1
    assert last >= 15
    assert float(torch.linalg.vector_norm(flown[last] - pos[last])) < 0.01


def test_acceleration_reads_the_track_in_flight_and_falls_back_at_a_contact():
    vel = torch.tensor([[30.0, 0.0, 2.0], [30.0, 0.0, 2.0]])
    # In flight: the second difference (Magnus included), eased as drag eases.
    flight_prev = vel[:1] - torch.tensor([[-19.0, 0.0, -12.0]]) / FPS
    acc = ball_acceleration_mps2(vel[:1], flight_prev, FPS)
    assert torch.allclose(acc, eased(vel[:1], flight_prev), atol=1e-4)
    assert float((acc - torch.tensor([[-19.0, 0.0, -12.0]])).abs().max()) < 2.0
    # A racket contact between the frames (the velocity reversed): gravity and drag only.
    contact_prev = torch.tensor([[-25.0, 0.0, -3.0]])
    acc = ball_acceleration_mps2(vel[:1], contact_prev, FPS)
    speed = float(torch.linalg.vector_norm(vel[0]))
    expect = torch.tensor([[-DRAG_PER_M * speed * 30.0, 0.0,
                            -DRAG_PER_M * speed * 2.0 - GRAVITY_MPS2]])
    assert torch.allclose(acc, expect, atol=1e-4)
    # Without the earlier velocity (the rally's first frames): gravity and drag.
    assert torch.allclose(ball_acceleration_mps2(vel, None, FPS), flight_acceleration_mps2(vel))


@pytest.mark.parametrize("speed_mps", [5.0, 20.0, 45.0])
def test_lift_threshold_is_what_magnus_can_do_at_that_speed(speed_mps):
    # 5 m/s (a toss): 0.47 m/s^2; 20 m/s: 7.5 m/s^2; 45 m/s: capped at MAX_LIFT_MPS2.
    limit = min(MAX_LIFT_PER_M * speed_mps ** 2, MAX_LIFT_MPS2)
    assert limit == pytest.approx({5.0: 0.468, 20.0: 7.49, 45.0: 30.0}[speed_mps], abs=0.01)
    vel = torch.tensor([[speed_mps, 0.0, 0.0]])
    for extra, taken in ((0.9 * limit, True), (1.1 * limit, False)):
        prev = vel - (flight_acceleration_mps2(vel) + torch.tensor([[0.0, 0.0, extra]])) / FPS
        acc = ball_acceleration_mps2(vel, prev, FPS)
        expect = eased(vel, prev) if taken else flight_acceleration_mps2(vel)
        assert torch.allclose(acc, expect, atol=1e-3)


def test_magnus_bound_is_the_generators_largest_lift():
    # Topspin 100 m/s (far beyond any shot) at 30 m/s: the lift approaches, never passes, it.
    f = fly([-12.0, 0.0, 1.0], [30.0, 0.0, 3.0], 100.0, "hard", 0.3, max_bounces=1)
    pos = track(f, 5).double()
    vel = (pos[1:] - pos[:-1]) * FPS
    lift = (vel[1:] - vel[:-1]) * FPS - flight_acceleration_mps2(vel[1:]).double()
    speed2 = (vel[1:] ** 2).sum(-1)
    ratio = torch.linalg.vector_norm(lift, dim=-1) / speed2
    assert float(ratio.max()) < MAX_LIFT_PER_M and float(ratio.min()) > 0.8 * MAX_LIFT_PER_M


def test_a_step_into_the_ground_bounces():
    pos = torch.tensor([[0.0, 0.0, 0.1]])
    vel = torch.tensor([[20.0, 0.0, -5.0]])          # 0.2 m down in a frame: below the ground
    c = ball_centre_m(pos, vel, None, FPS, "physics")
    assert float(c[0, 2]) > BALL_RADIUS_M
    assert float(c[0, 0]) == pytest.approx(0.8 - DRAG_PER_M * float(vel.norm()) * 20.0 / 625,
                                           abs=1e-4)
    rising = ball_centre_m(pos, -vel * torch.tensor([1.0, 1.0, -1.0]), None, FPS, "physics")
    assert float(rising[0, 2]) > 0.1                 # going up: no bounce


@pytest.mark.parametrize("x0_m, z0_m, vz_mps", [(-8.0, 0.9, 0.0), (-7.93, 0.6, 0.5),
                                                (7.0, 0.5, 2.0), (7.0, 1.0, -1.0)])
def test_a_step_into_the_net_drops_dead_as_the_generators_ball(x0_m, z0_m, vz_mps):
    # The generator's ball meets the net below the cord: on the frame it hits, the step puts
    # it within 12 mm of the generator's (0 in most; flown through, 0.3-0.5 m off); on the
    # next, whose backward difference mixes the ball's speed before and after, within 0.1 m
    # (as after a bounce, the model's to learn); and never through the net.
    vx = 25.0 if x0_m < 0 else -25.0
    f = fly([x0_m, 0.5, z0_m], [vx, 1.0, vz_mps], 5.0, "hard", 0.76, max_bounces=3)
    assert f.events[0].kind == "net"
    pos = track(f, int(f.t_s[-1] * FPS) + 1)
    hit = int(f.events[0].t_s * FPS)                 # the last frame before the net
    miss = miss_m(pos, "physics", net=True).max(dim=-1).values  # row k: frame k + 3
    assert float(miss[hit - 2]) < 0.012
    assert float(miss[hit - 1]) < 0.1
    assert float(miss[: hit - 2].max()) < 1e-3
    side = np.sign(x0_m)
    vel = (pos[1:] - pos[:-1]) * FPS
    c = ball_centre_m(pos[2:-1], vel[1:-1], vel[:-2], FPS, "physics", net=True)
    assert bool((side * c[:, 0] > 0).all())          # never through the net
    # Without the net (files trained before it) the step flies through: 0.3-0.5 m off.
    assert float(miss_m(pos, "physics").max(dim=-1).values[hit - 2]) > 0.25


def test_the_net_step_follows_the_cord_and_only_balls_heading_for_it():
    pos = torch.tensor([[-0.3, 0.0, 0.914 + BALL_RADIUS_M + 0.01],   # clears the strap
                        [-0.3, 6.0, 1.02 + BALL_RADIUS_M],           # the cord is higher here
                        [-0.3, 0.0, 0.5]])                           # flies away from the net
    vel = torch.tensor([[25.0, 0.0, 0.0], [25.0, 0.0, 0.0], [-25.0, 0.0, 0.0]])
    c = physics_step_m(pos, vel, None, FPS, net=True)
    assert c[0, 0] > 0.6 and c[2, 0] < -1.2
    assert c[1, 0] < 0                                # at y = 6 m the cord is 1.05 m: a hit
    assert physics_step_m(pos, vel, None, FPS)[1, 0] > 0.6    # no net: flies through
    assert float(net_cord_m(torch.tensor([0.0, 6.4, -9.0]))[0]) == pytest.approx(0.914)
    assert net_cord_m(torch.tensor([6.4, -9.0])).tolist() == pytest.approx([1.07, 1.07])


def test_object_centres_mix_player_and_ball_modes():
    pos = torch.zeros(2, 3, 3)
    pos[:, 2, 2] = 1.0
    vel = torch.ones(2, 3, 3)
    c = object_centres_m(pos, vel, vel, FPS, "cv", "current", ball=2)
    assert torch.allclose(c[:, :2], pos[:, :2] + vel[:, :2] / FPS)
    assert torch.equal(c[:, 2], pos[:, 2])
    with pytest.raises(ValueError, match="ball centre"):
        ball_centre_m(pos[:, 2], vel[:, 2], None, FPS, "magnus")


def test_model_files_saved_before_ball_centre_keep_their_centre():
    assert ModelConfig.from_dict({"bin_centre": "cv"}).ball_centre == "velocity"
    assert ModelConfig.from_dict({"bin_centre": "current"}).ball_centre == "current"
    assert ModelConfig.from_dict({"bin_centre": "cv", "ball_centre": "physics"}).ball_centre \
        == "physics"
    with pytest.raises(ValueError, match="ball_centre"):
        ModelConfig(ball_centre="spin")
    # ... and files saved before the net was in the step fly through it
    assert ModelConfig.from_dict({"bin_centre": "cv", "ball_centre": "physics"}).ball_net \
        is False
    with pytest.raises(ValueError, match="ball_net"):
        ModelConfig(ball_centre="velocity", ball_net=True)


@pytest.mark.parametrize("ball_net", [False, True])
def test_the_decoders_centres_meet_the_net_as_its_config_says(ball_net):
    from sportsngen.model import SportsNGEN
    model = SportsNGEN(ModelConfig(d_model=16, n_layers=1, n_heads=2, bin_centre="cv",
                                   ball_centre="physics", ball_net=ball_net))
    pos = torch.tensor([[[-5.0, 0.0, 0.0], [5.0, 0.0, 0.0], [-0.3, 0.0, 0.5]]])
    vel = torch.tensor([[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [25.0, 0.0, 0.0]]])
    ball_x = float(model.centres(pos, vel)[0, 2, 0])
    assert (ball_x < 0) if ball_net else (ball_x > 0.6)



def test_ball_bins_have_one_source_of_ranges():
    assert ModelConfig().ball_bin_half_ranges_m == pytest.approx((3.2, 1.6, 1.6))
    assert ModelConfig(fps=50.0).ball_bin_half_ranges_m == pytest.approx((1.6, 0.8, 0.8))
