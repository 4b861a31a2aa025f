"""Ball physics: flight, bounce, net and the launch solver (sportsngen.synth.physics)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sportsngen.synth import physics as P
from sportsngen.tennis.court import net_height_m

R = P.BALL_RADIUS_M
G = P.GRAVITY_MPS2


def _exact_parabola(pos0, vel0, t):
    p0, v0 = np.asarray(pos0, float), np.asarray(vel0, float)
    out = p0 + v0 * t[:, None]
    out[:, 2] -= 0.5 * G * t * t
    return out


def test_no_air_gives_the_exact_parabola():
    pos0, vel0 = (-10.0, 1.0, 1.0), (20.0, -3.0, 6.0)
    f = P.fly(pos0, vel0, 12.0, "hard", 3.0, max_bounces=1, aero=P.NO_AIR)  # spin has no effect
    t_land = (6.0 + math.sqrt(36.0 + 2 * G * (1.0 - R))) / G
    ev = f.first_bounce()
    assert ev is not None and f.stop_reason == "bounces"
    assert ev.t_s == pytest.approx(t_land, abs=1e-9)
    np.testing.assert_allclose(ev.pos_m, _exact_parabola(pos0, vel0, np.array([t_land]))[0],
                               atol=1e-8)
    t = np.linspace(0.0, t_land, 57)
    np.testing.assert_allclose(f.at(t), _exact_parabola(pos0, vel0, t), atol=1e-9)
    np.testing.assert_allclose(f.vel_mps[0], vel0)


def test_drag_shortens_and_spin_bends_the_flight():
    pos0, vel0 = (-11.0, 0.0, 1.0), (25.0, 0.0, 5.0)

    def land_x(spin, aero=P.DEFAULT_AERO):
        return P.fly(pos0, vel0, spin, "hard", 5.0, 1, aero=aero).first_bounce().pos_m[0]

    no_air, drag_only = land_x(0.0, P.NO_AIR), land_x(0.0, P.Aero(lift_scale=0.0))
    flat, top, back = land_x(0.0), land_x(10.0), land_x(-8.0)
    assert drag_only < no_air - 3.0           # drag costs metres at 25 m/s
    assert flat == pytest.approx(drag_only)    # no spin, no lift
    assert top < flat - 1.0
    assert back > flat + 1.0


def test_step_error_is_tiny_against_a_fine_step():
    pos0, vel0 = (-11.5, 0.5, 0.9), (30.0, 1.0, 4.0)
    coarse = P.fly(pos0, vel0, 9.0, "clay", 3.0, 2)
    fine = P.fly(pos0, vel0, 9.0, "clay", 3.0, 2, step_s=0.001)
    for a, b in zip(coarse.events, fine.events):
        assert np.linalg.norm(a.pos_m - b.pos_m) < 1e-4
    t = np.linspace(0.0, min(coarse.t_end_s, fine.t_end_s), 200)
    assert np.abs(coarse.at(t) - fine.at(t)).max() < 1e-3


def test_bounce_values():
    hard = P.SURFACE_BOUNCE["hard"]
    out, spin = P.bounce(np.array([0.0, 0.0, -5.0]), 0.0, "hard")
    np.testing.assert_allclose(out, [0.0, 0.0, 5.0 * hard.restitution])
    assert spin == 0.0
    # Skidding low ball (slides throughout): u loses mu (1 + e) |vz|, spin gains that / 0.55.
    out, spin = P.bounce(np.array([30.0, 0.0, -4.0]), 0.0, "hard")
    lost = hard.friction * (1 + hard.restitution) * 4.0
    np.testing.assert_allclose(out, [30.0 - lost, 0.0, 4.0 * hard.restitution])
    assert spin == pytest.approx(lost / P.BALL_INERTIA_FACTOR)
    # Steep topspin ball grips: leaves rolling (speed == spin), direction kept in 3-D.
    out, spin = P.bounce(np.array([6.0, 8.0, -9.0]), 8.0, "hard")
    assert math.hypot(out[0], out[1]) == pytest.approx(spin)
    assert out[1] / out[0] == pytest.approx(8.0 / 6.0)
    # Slice slows more than topspin on the same incoming ball, and bounces with less spin.
    top, s_top = P.bounce(np.array([20.0, 0.0, -8.0]), 8.0, "grass")
    sl, s_sl = P.bounce(np.array([20.0, 0.0, -8.0]), -8.0, "grass")
    assert sl[0] < top[0] and s_sl < s_top


def test_bounce_loses_energy():
    rng = np.random.default_rng(3)
    for surface in P.SURFACE_BOUNCE:
        for _ in range(200):
            v_in = np.array([rng.uniform(-40, 40), rng.uniform(-10, 10), rng.uniform(-20, -0.5)])
            spin = rng.uniform(-15, 15)
            v_out, spin_out = P.bounce(v_in, spin, surface)
            # kinetic energy / (m/2): translation + I w^2 / m = 0.55 (R w)^2
            e_in = v_in @ v_in + P.BALL_INERTIA_FACTOR * spin ** 2
            e_out = v_out @ v_out + P.BALL_INERTIA_FACTOR * spin_out ** 2
            assert e_out < e_in
            assert v_out[2] > 0


def test_unknown_surface_lists_known_ones():
    with pytest.raises(ValueError, match=r"'ice'.*\['clay', 'grass', 'hard'\]"):
        P.fly((0, 0, 1), (1, 0, 0), 0.0, "ice", 1.0)
    with pytest.raises(ValueError, match="clay"):
        P.bounce(np.array([1.0, 0.0, -1.0]), 0.0, "carpet")


def test_bad_input_errors():
    with pytest.raises(ValueError, match="below the ground"):
        P.fly((0, 0, -0.5), (1, 0, 0), 0.0, "hard", 1.0)
    with pytest.raises(ValueError, match="moving down"):
        P.bounce(np.array([1.0, 0.0, 2.0]), 0.0, "hard")
    with pytest.raises(ValueError, match="speed_mps"):
        P.solve_launch((-11, 0, 1), (8, 0), -3.0, 0.0)
    f = P.fly((-11, 0, 1), (20, 0, 3), 0.0, "hard", 1.0)
    with pytest.raises(ValueError, match="outside the flight"):
        f.at(np.array([0.5, 1.5]))


def test_max_bounces_stop_when_and_rolling():
    f = P.fly((-11, 0, 1), (15, 0, 6), 5.0, "hard", 10.0, max_bounces=2)
    assert [e.kind for e in f.events] == ["bounce", "bounce"] and f.stop_reason == "bounces"
    assert f.t_end_s == f.events[-1].t_s
    f = P.fly((-11, 0, 1), (25, 0, 4), 0.0, "hard", 10.0, stop_when=lambda t, p, v: p[0] > 0.0)
    assert f.stop_reason == "stop_when" and 0.0 < f.pos_m[-1, 0] < 0.6
    assert (f.pos_m[:-1, 0] <= 0.0).all()
    # Bounces die out into rolling; the ball then slows to rest and stays on the ground.
    f = P.fly((-11, 0, 1), (3, 0, 2), 0.0, "clay", 8.0, max_bounces=50)
    assert f.stop_reason == "t_max" and f.t_end_s == pytest.approx(8.0)
    assert len(f.events) >= 3 and f.pos_m[-1, 2] == pytest.approx(R)
    np.testing.assert_allclose(f.vel_mps[-1], 0.0)


def test_net_hit_drops_dead_on_the_hitters_side():
    f = P.fly((-8.0, 1.0, 0.6), (25.0, 0.0, 0.5), 0.0, "hard", 3.0)
    assert f.events[0].kind == "net"
    ev = f.events[0]
    assert ev.pos_m[0] == pytest.approx(-R) and ev.pos_m[2] - R < net_height_m(ev.pos_m[1])
    assert (f.pos_m[:, 0] <= -R + 1e-9).all()
    assert f.first_bounce().pos_m[0] < 0
    assert np.linalg.norm(ev.vel_out_mps) < 0.35 * np.linalg.norm(ev.vel_in_mps)


def _crossing_heights(f: P.Flight):
    """(y, z) where the densely sampled flight crosses x = 0."""
    t = np.linspace(0.0, f.t_end_s, 4000)
    p = f.at(t)
    i = np.flatnonzero(np.sign(p[:-1, 0]) * np.sign(p[1:, 0]) < 0)
    w = p[i, 0] / (p[i, 0] - p[i + 1, 0])
    return p[i, 1] + w * (p[i + 1, 1] - p[i, 1]), p[i, 2] + w * (p[i + 1, 2] - p[i, 2])


def test_random_flights_never_below_ground_or_through_the_net():
    rng = np.random.default_rng(7)
    n_net = n_over = 0
    for _ in range(150):
        side = rng.choice([-1.0, 1.0])
        pos0 = (side * rng.uniform(0.5, 13.0), rng.uniform(-5, 5), rng.uniform(R, 3.2))
        speed, elev = rng.uniform(3, 60), math.radians(rng.uniform(-20, 50))
        az = rng.uniform(-0.6, 0.6) + (math.pi if side > 0 else 0.0)
        vel0 = speed * np.array([math.cos(elev) * math.cos(az), math.cos(elev) * math.sin(az),
                                 math.sin(elev)])
        f = P.fly(pos0, vel0, rng.uniform(-15, 15), str(rng.choice(list(P.SURFACE_BOUNCE))),
                  3.0, max_bounces=3)
        assert (f.pos_m[:, 2] >= R - 1e-9).all()
        assert (f.at(np.linspace(0, f.t_end_s, 1000))[:, 2] >= R - 1e-6).all()
        ys, zs = _crossing_heights(f)
        assert (zs > net_height_m(ys)).all() if len(ys) else True
        n_over += len(ys)
        if any(e.kind == "net" for e in f.events):
            n_net += 1
            t_net = next(e.t_s for e in f.events if e.kind == "net")
            after = f.pos_m[f.t_s >= t_net, 0]
            assert (np.sign(after) == side).all()
    assert n_net >= 5 and n_over >= 20  # both cases were exercised


def _shot_grid():
    """(contact, target, spin) of serves and groundstrokes from both ends, all across the net."""
    shots = []
    for end in (-1.0, 1.0):
        for y_c, ty in ((-0.8, 3.8), (-0.8, 0.3), (0.4, -2.0), (0.6, -3.9)):  # diagonal boxes
            for spin in (0.0, 4.0, 12.0, -5.0):
                shots.append(((end * 11.9, y_c, 2.85), (-end * 5.8, ty), spin))
        for c in ((11.2, -3.0, 1.0), (12.8, 2.5, 0.5), (7.0, 0.0, 1.3), (2.5, 1.0, 1.6)):
            for t in ((10.5, 3.5), (8.0, -3.8), (4.0, 0.5), (11.2, 0.0)):
                for spin in (6.0, 10.0, 2.0, -7.0):
                    shots.append(((end * c[0], c[1], c[2]), (-end * t[0], t[1]), spin))
    return shots


def test_solver_lands_on_target_and_clears_the_net():
    clearance, errors = 0.2, []
    for contact, target, spin in _shot_grid():
        v_max = P.max_speed_to_land(contact, target, spin, clearance)
        assert v_max > 8.0, (contact, target, spin)
        for speed, lob in ((min(v_max - 0.1, 70.0), False), (0.88 * min(v_max, 70.0), False),
                           (0.88 * min(v_max, 70.0), True)):
            vel = P.solve_launch(contact, target, speed, spin, net_clearance_m=clearance,
                                 lob=lob)
            if lob and vel is None:  # a lob that fast may fly too far
                continue
            assert vel is not None, (contact, target, speed, spin, lob)
            assert np.linalg.norm(vel) == pytest.approx(speed)
            f = P.fly(contact, vel, spin, "hard", 8.0, max_bounces=1)
            ev = f.first_bounce()
            assert [e.kind for e in f.events] == ["bounce"]
            errors.append(np.linalg.norm(ev.pos_m[:2] - np.asarray(target)))
            ys, zs = _crossing_heights(f)
            assert len(ys) == 1  # every target is across the net
            assert zs[0] - R >= net_height_m(ys[0]) + clearance - 0.01
            low = P.solve_launch(contact, target, speed, spin, clearance)
            assert (vel[2] > low[2] + 0.5) if lob else True
    assert len(errors) > 2 * len(_shot_grid())
    assert max(errors) < 0.05 and np.median(errors) < 0.01


def test_infeasible_requests_return_none():
    # too slow to reach the far baseline
    assert P.solve_launch((-11.9, 0.0, 1.0), (11.0, 0.0), 8.0, 0.0) is None
    # too fast to drop a flat ball from waist height onto the service line over the net
    assert P.solve_launch((-11.9, 0.0, 1.0), (6.0, 0.0), 45.0, 0.0) is None
    # the same shot is fine at a moderate speed, and slowly as a lob
    assert P.solve_launch((-11.9, 0.0, 1.0), (6.0, 0.0), 20.0, 5.0) is not None
    assert P.solve_launch((-11.9, 0.0, 1.0), (6.0, 0.0), 20.0, 5.0, lob=True) is not None


def test_max_speed_to_land_is_the_feasibility_edge():
    contact, target = (-11.9, 0.5, 1.0), (9.5, -2.0)
    for spin in (0.0, 10.0):
        v_max = P.max_speed_to_land(contact, target, spin, net_clearance_m=0.1)
        assert 20.0 < v_max < 75.0
        assert P.solve_launch(contact, target, v_max - 0.2, spin, 0.1) is not None
        assert P.solve_launch(contact, target, v_max + 0.2, spin, 0.1) is None
    assert (P.max_speed_to_land(contact, target, 10.0) >
            P.max_speed_to_land(contact, target, 0.0) + 3.0)  # topspin drops in faster
    # a bounce on the hitter's own side never meets the net
    assert P.max_speed_to_land((-11.9, 0.0, 1.0), (-5.0, 0.0), 0.0) == math.inf


def test_bounce_speed_ratio_orders_clay_grass_hard():
    rng = np.random.default_rng(11)
    shots = []
    for i in range(60):
        if i % 3 == 0:
            contact = (-11.9, rng.uniform(0.2, 1.0), rng.uniform(2.6, 3.0))
            target = (rng.uniform(4.0, 6.1), -rng.uniform(0.3, 3.8))
            speed, spin = rng.uniform(38, 55), rng.uniform(0, 12)
        else:
            contact = (rng.uniform(-12.5, -10.5), rng.uniform(-3.5, 3.5), rng.uniform(0.7, 1.3))
            target = (rng.uniform(6.5, 10.5), rng.uniform(-3.5, 3.5))
            speed, spin = rng.uniform(20, 32), rng.choice([rng.uniform(4, 14), -5.0])
        vel = P.solve_launch(contact, target, speed, spin)
        if vel is not None:
            shots.append((contact, vel, spin))
    assert len(shots) >= 45
    medians = {}
    for surface in ("clay", "grass", "hard"):
        ratios = [P.speed_after_bounce_ratio(P.fly(c, v, s, surface, 4.0, 1)) for c, v, s in shots]
        assert max(ratios) < 1.0  # first bounces of typical shots always lose speed
        medians[surface] = np.median(ratios)
    assert medians["clay"] < medians["grass"] - 0.01
    assert medians["grass"] < medians["hard"] - 0.01
    with pytest.raises(ValueError, match="no bounce"):
        P.speed_after_bounce_ratio(P.fly((-11, 0, 1), (20, 0, 5), 0.0, "hard", 0.1))


def test_court_pace_ratings_order_surfaces():
    cpr = {k: v.court_pace_rating for k, v in P.SURFACE_BOUNCE.items()}
    assert cpr["clay"] < 30 < cpr["hard"] < cpr["grass"]


def test_heavy_backspin_checks_back_and_never_passes_through_the_net():
    f = P.fly((-3.0, 0.0, 1.0), (6.0, 0.0, 3.0), -15.0, "clay", 3.0, max_bounces=3)
    first = f.first_bounce()
    assert first.pos_m[0] > 0 and first.vel_out_mps[0] < 0  # bounced over there, came back
    assert first.spin_out_mps > 0  # same rotation: topspin relative to its new direction
    ys, zs = _crossing_heights(f)
    assert len(ys) >= 1 and (zs > net_height_m(ys)).all()
    # A ball rolling along the ground stops against the net.
    f = P.fly((-3.0, 0.0, R), (5.0, 0.0, 0.0), 0.0, "hard", 3.0)
    assert f.pos_m[:, 0].max() == pytest.approx(-R) and f.events == []
