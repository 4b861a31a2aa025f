"""The players' kinematic limit in rollouts (`sportsngen.sim.kinematics`)."""

import pytest
import torch

from sportsngen.errors import ArgumentError
from sportsngen.sim.kinematics import (
    PlayerLimits,
    check_player_rules,
    limit_player_acceleration,
    limit_player_speed,
)

FPS = 25.0


def frames(vel_xy, dv_xy):
    """One row: the players at (0, ±12) moving at `vel_xy` (2, 2), sampled to change their
    velocity by `dv_xy` (2, 2); the ball anywhere."""
    pos = torch.tensor([[[0.0, 12.0, 0.0], [0.0, -12.0, 0.0], [1.0, 2.0, 1.5]]])
    vel = torch.zeros(1, 3, 3)
    vel[0, :2, :2] = torch.tensor(vel_xy)
    vel[0, 2] = torch.tensor([30.0, 0.0, 2.0])
    nxt = pos.clone()
    nxt[0, :2, :2] += (vel[0, :2, :2] + torch.tensor(dv_xy)) / FPS
    nxt[0, 2] = pos[0, 2] + vel[0, 2] / FPS
    return nxt, pos, vel


def limited(nxt, pos, vel, accel_mps2, **rules):
    """`limit_player_acceleration` of one row under `PlayerLimits(accel_mps2, **rules)`."""
    return limit_player_acceleration(nxt, pos, vel, FPS, PlayerLimits(accel_mps2, **rules))


def test_a_change_beyond_the_limit_is_scaled_to_it_in_its_own_direction():
    # Player 0 asks 10 m/s² (0.4 m/s in a frame) at 3-4-5, player 1 2 m/s², within 6.
    nxt, pos, vel = frames([[1.0, 0.0], [0.0, -2.0]], [[0.24, 0.32], [0.08, 0.0]])
    out = limited(nxt, pos, vel, 6.0)
    dv = (out[0, :2, :2] - pos[0, :2, :2]) * FPS - vel[0, :2, :2]
    torch.testing.assert_close(dv[0], torch.tensor([0.144, 0.192]))   # 0.24 m/s, 3-4-5
    torch.testing.assert_close(dv[1], torch.tensor([0.08, 0.0]))
    torch.testing.assert_close(out[0, 2], nxt[0, 2])                  # the ball untouched
    assert (out[0, :2, 2] == 0).all()


def test_a_player_within_the_limit_or_braking_within_it_keeps_his_frame():
    nxt, pos, vel = frames([[5.0, 0.0], [0.0, 0.0]], [[-0.2, 0.0], [0.0, 0.0]])
    out = limited(nxt, pos, vel, 6.0)
    torch.testing.assert_close(out, nxt)
    # Braking beyond it: a stop from 5 m/s takes 0.83 s at 6 m/s², not one frame.
    nxt, pos, vel = frames([[5.0, 0.0], [0.0, 0.0]], [[-5.0, 0.0], [0.0, 0.0]])
    out = limited(nxt, pos, vel, 6.0)
    speed = (out[0, 0, 0] - pos[0, 0, 0]) * FPS
    assert float(speed) == pytest.approx(5.0 - 0.24)


def test_a_change_near_the_limit_is_flat_out_and_one_well_short_is_kept():
    # Player 0 asks 5.5 m/s² (0.22 m/s in a frame) at 3-4-5, player 1 5.0 m/s²; from 0.9 of
    # the 6 m/s² limit (5.4) a change is the limit's, its direction kept.
    nxt, pos, vel = frames([[1.0, 0.0], [0.0, -2.0]], [[0.132, 0.176], [0.2, 0.0]])
    out = limited(nxt, pos, vel, 6.0, full_from_frac=0.9)
    dv = (out[0, :2, :2] - pos[0, :2, :2]) * FPS - vel[0, :2, :2]
    torch.testing.assert_close(dv[0], torch.tensor([0.144, 0.192]))   # 0.24 m/s, 3-4-5
    torch.testing.assert_close(dv[1], torch.tensor([0.2, 0.0]))
    torch.testing.assert_close(out[0, 2], nxt[0, 2])                  # the ball untouched
    # Without it (the default) both are kept; beyond the limit it scales down as before.
    torch.testing.assert_close(limited(nxt, pos, vel, 6.0), nxt)
    nxt, pos, vel = frames([[1.0, 0.0], [0.0, 0.0]], [[0.24, 0.32], [0.0, 0.0]])
    out = limited(nxt, pos, vel, 6.0, full_from_frac=0.9)
    dv = (out[0, :2, :2] - pos[0, :2, :2]) * FPS - vel[0, :2, :2]
    torch.testing.assert_close(dv[0], torch.tensor([0.144, 0.192]))
    torch.testing.assert_close(dv[1], torch.tensor([0.0, 0.0]))       # standing stays
    with pytest.raises(ValueError, match="full_from_frac"):
        limited(nxt, pos, vel, 6.0, full_from_frac=1.5)


def test_the_limit_must_be_positive():
    nxt, pos, vel = frames([[0.0, 0.0], [0.0, 0.0]], [[0.0, 0.0], [0.0, 0.0]])
    with pytest.raises(ValueError, match="accel_mps2 must be positive, got 0.0"):
        limited(nxt, pos, vel, 0.0)


def test_the_player_rules_are_checked_in_one_place_by_their_ranges():
    assert check_player_rules(accel_mps2=6, full_from_frac=1, keep_heading_deg=None) == {
        "accel_mps2": 6.0, "full_from_frac": 1.0, "keep_heading_deg": None}
    assert check_player_rules(keep_heading_deg="179.5") == {"keep_heading_deg": 179.5}
    bad = [({"accel_mps2": 0.0}, "accel_mps2 must be positive, got 0.0"),
           ({"accel_mps2": float("inf")}, "accel_mps2 must be positive, got inf"),
           ({"full_from_frac": 0.0}, r"full_from_frac must be in \(0, 1\], got 0.0"),
           ({"full_from_frac": 1.01}, r"full_from_frac must be in \(0, 1\], got 1.01"),
           ({"keep_heading_deg": 180}, r"keep_heading_deg must be in \(0, 180\), got 180"),
           ({"keep_heading_deg": -1.0}, r"keep_heading_deg must be in \(0, 180\)"),
           ({"keep_heading_deg": "wide"}, "keep_heading_deg must be a number, got 'wide'"),
           ({"top_speed": 1.0}, "not a player rule: 'top_speed'")]
    for values, message in bad:
        with pytest.raises(ArgumentError, match=message):
            check_player_rules(**values)
    with pytest.raises(ArgumentError, match=r"^--flag must be in \(0, 1\], got 2$"):
        check_player_rules({"full_from_frac": "--flag"}, full_from_frac=2)


def test_player_limits_are_checked_once_when_made_and_name_the_callers_option():
    limits = PlayerLimits(6, full_from_frac="0.9", keep_heading_deg=30)
    assert (limits.accel_mps2, limits.full_from_frac, limits.keep_heading_deg) == (6.0, 0.9, 30.0)
    assert isinstance(limits.full_from_frac, float)
    with pytest.raises(AttributeError):
        limits.accel_mps2 = 8.0                                        # frozen: checked once
    with pytest.raises(ArgumentError, match="accel_mps2 must be positive, got None"):
        PlayerLimits(None)
    # From a caller's options: no limit, no limits (the other two checked all the same) ...
    assert PlayerLimits.from_options(None, 0.9, 30.0) is None
    with pytest.raises(ArgumentError, match=r"^--frac must be in \(0, 1\], got 1.5$"):
        PlayerLimits.from_options(None, 1.5, names={"full_from_frac": "--frac"})
    # ... else the limits, a bad one named by the caller's name for it.
    assert PlayerLimits.from_options(5, None, 20) == PlayerLimits(5.0, None, 20.0)
    with pytest.raises(ArgumentError, match=r"^player_accel_mps2 must be positive, got -1$"):
        PlayerLimits.from_options(-1, names={"accel_mps2": "player_accel_mps2"})


def test_rollout_players_never_change_velocity_faster_than_the_limit():
    """The bundled model's players, rolled out with the limit, keep every frame's change of
    velocity within it; without it their largest is well beyond (about 8 m/s² a frame). The
    rule that keeps a late chaser running (`keep_chasing`) acts after the draw and may add its
    own 6 m/s² along his way to the ball, so it is off here."""
    import numpy as np

    from sportsngen.sim import Simulator

    def largest(sim):
        data = sim.simulate_points("Roger Federer", "Rafael Nadal", "hard", 12, seed=3,
                                   serve_number=1)
        worst = 0.0
        players = data.frames[data.frames["object"] != "ball"]
        for _, g in players.groupby(["rally_id", "object"]):
            xy = g.sort_values("frame")[["x", "y"]].to_numpy(float)
            if len(xy) > 3:
                acc = np.linalg.norm(np.diff(xy, 2, axis=0), axis=-1) * FPS * FPS
                worst = max(worst, float(acc.max()))
        return worst

    kw = dict(max_duration_s=2.5, player_accel_mps2=None, keep_chasing=False)
    assert largest(Simulator.from_pretrained(**kw)) > 7.0
    kw["player_accel_mps2"] = 6.0
    assert largest(Simulator.from_pretrained(**kw)) <= 6.0 + 1e-3
    with pytest.raises(ArgumentError, match="player_accel_mps2"):
        Simulator.from_pretrained(player_accel_mps2=-1.0)
    with pytest.raises(ArgumentError, match="player_accel_full_frac"):
        Simulator.from_pretrained(player_accel_full_frac=0.0)


def test_rollout_players_near_the_limit_run_flat_out_along_their_heading():
    """With the bundled defaults (the limit, flat out from 0.9 of it, along the heading within
    30°) no player's frame changes his velocity by 5.4-5.99 m/s², where the uniform draws
    inside the bins put about a quarter of them, and no running player's flat-out frame turns
    him by 0.5-29.5°, where the x and y draws put a share of them; the chase rule, which acts
    after the draw, is off."""
    import numpy as np

    from sportsngen.sim import Simulator

    def shares(sim):
        data = sim.simulate_points("Roger Federer", "Rafael Nadal", "hard", 12, seed=3,
                                   serve_number=1)
        acc, turn = [], []
        players = data.frames[data.frames["object"] != "ball"]
        for _, g in players.groupby(["rally_id", "object"]):
            v = np.diff(g.sort_values("frame")[["x", "y"]].to_numpy(float), axis=0) * FPS
            dv = np.diff(v, axis=0)
            size, speed = np.linalg.norm(dv, axis=-1), np.linalg.norm(v[:-1], axis=-1)
            acc.append(size * FPS)
            cos = (dv * v[:-1]).sum(-1) / np.maximum(size * speed, 1e-12)
            flat = (size * FPS > 6.0 - 1e-3) & (speed >= 0.5 + 1e-3)
            turn.append(np.degrees(np.arccos(np.clip(cos[flat], -1, 1))))
        acc, turn = np.concatenate(acc), np.concatenate(turn)
        return (((acc >= 5.4 + 1e-3) & (acc < 6.0 - 1e-3)).mean(), (acc > 6.0 - 1e-3).mean(),
                ((turn > 0.5) & (turn < 29.5)).mean(), len(turn))

    kw = dict(max_duration_s=2.5, keep_chasing=False)
    near, full, turned, n = shares(Simulator.from_pretrained(**kw))
    assert near == 0.0 and full > 0.3 and turned == 0.0 and n > 100
    near, full, turned, n = shares(Simulator.from_pretrained(
        player_accel_full_frac=None, player_keep_heading_deg=None, **kw))
    assert near > 0.1 and turned > 0.05 and n > 50


def test_a_flat_out_change_near_a_runners_heading_runs_along_it():
    # Player 0 runs at 3 m/s along x and asks the full 0.24 m/s at 20° off it: it is turned
    # onto his heading, its size kept. Player 1 runs at 2 m/s along -y and turns 45° flat out:
    # a turn wider than 30° stays as drawn.
    c20, s20 = 0.24 * torch.cos(torch.deg2rad(torch.tensor(20.0))), \
        0.24 * torch.sin(torch.deg2rad(torch.tensor(20.0)))
    h45 = 0.24 / 2 ** 0.5
    nxt, pos, vel = frames([[3.0, 0.0], [0.0, -2.0]], [[c20, s20], [h45, -h45]])
    out = limited(nxt, pos, vel, 6.0, keep_heading_deg=30.0)
    dv = (out[0, :2, :2] - pos[0, :2, :2]) * FPS - vel[0, :2, :2]
    torch.testing.assert_close(dv[0], torch.tensor([0.24, 0.0]))
    torch.testing.assert_close(dv[1], torch.tensor([h45, -h45]))
    torch.testing.assert_close(out[0, 2], nxt[0, 2])                  # the ball untouched
    # Kept as drawn: a change short of the limit, a player slower than 0.5 m/s, braking.
    for vel_xy, dv_xy in (([[3.0, 0.0], [0.0, 0.0]], [[0.19, 0.05], [0.0, 0.0]]),
                          ([[0.4, 0.0], [0.0, 0.0]], [[c20, s20], [0.0, 0.0]]),
                          ([[3.0, 0.0], [0.0, 0.0]], [[-c20, s20], [0.0, 0.0]])):
        nxt, pos, vel = frames(vel_xy, dv_xy)
        torch.testing.assert_close(limited(nxt, pos, vel, 6.0, keep_heading_deg=30.0), nxt)
    # With full_from_frac a change drawn at 0.9 of the limit is first set to it, then turned.
    nxt, pos, vel = frames([[3.0, 0.0], [0.0, 0.0]], [[0.9 * c20, 0.9 * s20], [0.0, 0.0]])
    out = limited(nxt, pos, vel, 6.0, full_from_frac=0.9, keep_heading_deg=30.0)
    dv = (out[0, 0, :2] - pos[0, 0, :2]) * FPS - vel[0, 0, :2]
    torch.testing.assert_close(dv, torch.tensor([0.24, 0.0]))
    for bad in (0.0, 180.0, -5.0):
        with pytest.raises(ValueError, match="keep_heading_deg"):
            limited(nxt, pos, vel, 6.0, keep_heading_deg=bad)


def test_the_bundled_defaults_are_the_modules_constants():
    from sportsngen.sim import Simulator
    from sportsngen.sim.kinematics import FULL_ACCEL_FROM_FRAC, KEEP_HEADING_DEG

    sim = Simulator.from_pretrained()
    assert sim.player_accel_full_frac == FULL_ACCEL_FROM_FRAC
    assert sim.player_keep_heading_deg == KEEP_HEADING_DEG
    with pytest.raises(ArgumentError, match="player_keep_heading_deg"):
        Simulator.from_pretrained(player_keep_heading_deg=180.0)
    with pytest.raises(ArgumentError, match=r"player_accel_full_frac must be in \(0, 1\]"):
        Simulator.from_pretrained(player_accel_full_frac=0.0)


def test_a_step_beyond_a_players_top_speed_is_scaled_to_it_in_its_own_direction():
    # Player 0 steps at 7.5 m/s (4.5-6.0) against his 6.0; player 1 at 5.0 within his 6.3.
    nxt, pos, vel = frames([[4.5, 6.0], [0.0, -5.0]], [[0.0, 0.0], [0.0, 0.0]])
    out = limit_player_speed(nxt, pos, FPS, torch.tensor([[6.0, 6.3]]))
    step = (out[0, :2, :2] - pos[0, :2, :2]) * FPS
    torch.testing.assert_close(step[0], torch.tensor([3.6, 4.8]))      # 6.0 m/s, 3-4-5
    torch.testing.assert_close(step[1], torch.tensor([0.0, -5.0]))
    torch.testing.assert_close(out[0, 2], nxt[0, 2])                  # the ball untouched
    with pytest.raises(ValueError, match="top_speed_mps"):
        limit_player_speed(nxt, pos, FPS, torch.tensor([6.0, 6.3]))


def test_rollout_players_never_run_faster_than_their_top_speed(tiny_model_file, tmp_path):
    """A file with a top-speed table: with `player_top_speed` no player's frame is faster than
    his row (the chase rule's hold included), without it the tiny model's draws are."""
    import shutil

    import numpy as np

    from sportsngen.model.export import update_extra
    from sportsngen.sim import Simulator
    from sportsngen.sim.top_speed import TopSpeeds

    path = shutil.copy(tiny_model_file, tmp_path / "with_top_speed.pt")
    update_extra(path, top_speed=TopSpeeds(2.0, {"Toy Alpha": 1.5}).to_dict())

    def fastest(sim):
        data = sim.simulate_points("Toy Alpha", "Toy Gamma", "hard", 8, seed=2, serve_number=1)
        players = data.frames[data.frames["object"] != "ball"]
        out = {}
        for (_, who), g in players.groupby(["rally_id", "object"]):
            xy = g.sort_values("frame")[["x", "y"]].to_numpy(float)
            v = np.linalg.norm(np.diff(xy, axis=0), axis=-1) * FPS
            out[who] = max(out.get(who, 0.0), float(v.max()) if len(v) else 0.0)
        return out

    kw = dict(max_duration_s=1.5, keep_chasing=True)
    free = fastest(Simulator.from_pretrained(path, **kw))
    assert max(free.values()) > 2.5
    sim = Simulator.from_pretrained(path, player_top_speed=True, **kw)
    assert sim.top_speeds == TopSpeeds(2.0, {"Toy Alpha": 1.5})
    capped = fastest(sim)
    assert capped["Toy Alpha"] <= 1.5 + 1e-3 and capped["Toy Gamma"] <= 2.0 + 1e-3


@pytest.mark.parametrize("rules", [{}, {"full_from_frac": 0.85},
                                   {"full_from_frac": 0.85, "keep_heading_deg": 10.0}])
def test_the_compiled_limits_are_the_torch_ones(monkeypatch, rules):
    """`sim.constraint_kernel`'s limits against the torch operations, on players walking,
    running, braking and turning: the same float32 frames."""
    from sportsngen.sim import kinematics
    from sportsngen.sim.kinematics import (
        PlayerLimits,
        limit_player_acceleration,
        limit_player_speed,
    )

    g = torch.Generator().manual_seed(4)
    n = 5000
    pos = torch.randn(n, 3, 3, generator=g) * 5
    vel = torch.randn(n, 3, 3, generator=g) * 3
    vel[::6] = 0.0                                           # standing
    nxt = pos + vel / 25 + torch.randn(n, 3, 3, generator=g) * 0.012
    top = torch.empty(n, 2).uniform_(3.0, 7.0, generator=g)
    lim = PlayerLimits(accel_mps2=6.0, **rules)
    fast = limit_player_acceleration(nxt, pos, vel, 25.0, lim)
    fast_top = limit_player_speed(nxt, pos, 25.0, top)
    with monkeypatch.context() as m:
        m.setattr(kinematics, "kernel_inputs", lambda *t: False)
        slow = limit_player_acceleration(nxt, pos, vel, 25.0, lim)
        slow_top = limit_player_speed(nxt, pos, 25.0, top)
    assert (fast - slow).abs().max() < 1e-5
    assert ((fast - nxt).abs() > 1e-4).any(dim=-1).any(dim=-1).float().mean() > 0.2  # limited
    assert torch.equal(fast[:, 2], nxt[:, 2])                                  # the ball as drawn
    assert (fast_top - slow_top).abs().max() < 1e-5
    assert ((fast_top - nxt).abs() > 1e-4).any() and torch.equal(fast_top[:, 2], nxt[:, 2])
