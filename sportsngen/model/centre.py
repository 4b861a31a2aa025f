"""Where the bins of an object's next-frame offset are centred.

The model predicts each object's next position as a class over bins around a centre, so the
centre decides what it must learn. Players: the current position ("current", the paper) or a
constant-velocity extrapolation ("cv"). The ball (`ModelConfig.ball_centre`):

- ``"current"``: the current position (the paper);
- ``"velocity"``: one frame at the current velocity;
- ``"physics"``: one step of the ball's flight. The acceleration (gravity, drag and Magnus
  together) is read from the last three frames (the second difference), which carries the
  spin without estimating it: gravity and drag are taken at the new velocity and the rest,
  the lift, loses any part along the velocity (Magnus has none), is turned with the
  velocity and sized as the generator's Magnus at the spin it reads as (`turned_lift_mps2`).
  Where that reading is not a
  flight (a racket contact or a bounce fell among those frames, a toss left the hand, or the
  track is too noisy: it departs from gravity plus drag by more than Magnus could at that
  speed, `MAX_LIFT_PER_M` |v|^2, capped at `MAX_LIFT_MPS2`) the step uses gravity plus drag
  alone for those frames. A step that would end below the ground bounces
  (`BOUNCE_RESTITUTION`); with the net (`ModelConfig.ball_net`), a step whose ball meets
  the net below the cord drops dead on the hitter's side as the generator's does
  (`net_step_m`).

Velocities are backward differences (frame t minus frame t-1, times the frame rate), so the
physics step is the exact extrapolation of a constant acceleration:
``p(t+1) = p(t) + v(t) dt + a dt^2`` with ``a = (v(t) - v(t-1)) / dt``. In free flight of the
generated ball the next frame then lies in the centre bin of all three dimensions for almost
every frame (`docs/architecture.md`), and the model spends its capacity on contacts and
bounces, not on re-learning the flight.
"""

from __future__ import annotations

import torch

from sportsngen.model.config import BALL_CENTRES
from sportsngen.tennis.court import (
    BALL_RADIUS_M,
    NET_HEIGHT_CENTRE_M,
    NET_HEIGHT_POST_M,
    NET_POST_Y_M,
)

PLAYER_CENTRES = ("current", "cv")
GRAVITY_MPS2 = 9.81
# Drag per metre of a standard ball, rho pi R^2 C_d / (2 m) with air 1.21 kg/m^3, R 33.5 mm,
# 57 g and C_d 0.55 (the generator's values, `sportsngen.synth.physics`): 51 m/s^2 at 50 m/s.
DRAG_PER_M = 0.0206
# Magnus of a rally ball is at most ~15 m/s^2 (8 m/s of topspin at 30 m/s: 6 m/s^2); a second
# difference further than this from gravity plus drag holds a contact or a bounce.
MAX_LIFT_MPS2 = 30.0
# The generator's Magnus: k C_L |v|^2 across the flight, k = rho pi R^2 / (2 m) = DRAG_PER_M /
# C_d, C_L = -spin / (2 |spin| + |v|) (`sportsngen.synth.physics`).
MAGNUS_PER_M = DRAG_PER_M / 0.55
# Magnus can do no more than k |v|^2 / 2 for any spin (the lift coefficient is under 1/2):
# 0.5 m/s^2 for a 5 m/s toss, 17 m/s^2 at 30 m/s. A slow ball's second difference beyond that
# is no flight: read as one, a toss's release (the hand stops, the ball flies on) was carried
# on as a 20-30 m/s^2 "lift" that flew the model's own tosses backwards past the server
# (docs/evaluation.md).
MAX_LIFT_PER_M = MAGNUS_PER_M / 2.0
# A lift read as a coefficient at or above 1/2 (a noisy track) is taken at this one rather
# than inverted to an infinite spin.
MAX_LIFT_COEFFICIENT = 0.45
# Vertical speed kept by a bounce inside the step (the surfaces' 0.73-0.80; the exact bounce
# is the model's to learn, the centre only has to be near it).
BOUNCE_RESTITUTION = 0.77
# A ball that meets the net keeps this share of its speed towards it, backwards, and
# `NET_KEEP_ACROSS` of the rest (the generator's net, `sportsngen.synth.physics`).
NET_REBOUND = 0.1
NET_KEEP_ACROSS = 0.3


def flight_acceleration_mps2(vel_mps: torch.Tensor) -> torch.Tensor:
    """(..., 3) velocities -> gravity plus drag (..., 3), no spin."""
    speed = torch.linalg.vector_norm(vel_mps, dim=-1, keepdim=True)
    acc = -DRAG_PER_M * speed * vel_mps
    acc[..., 2] -= GRAVITY_MPS2
    return acc


def read_lift_mps2(vel_mps: torch.Tensor, prev_vel_mps: torch.Tensor,
                   fps: float) -> tuple[torch.Tensor, torch.Tensor]:
    """The lift (spin's acceleration) read from the track's second difference and carried to
    the current frame (`turned_lift_mps2`), and (..., 1) bool where that reading is a flight
    (module doc; elsewhere the lift means nothing)."""
    base = flight_acceleration_mps2(vel_mps)
    track = (vel_mps - prev_vel_mps) * fps
    speed2 = (vel_mps * vel_mps).sum(dim=-1, keepdim=True)
    limit = torch.clamp(MAX_LIFT_PER_M * speed2, max=MAX_LIFT_MPS2)
    flight = torch.linalg.vector_norm(track - base, dim=-1, keepdim=True) <= limit
    lift = track - flight_acceleration_mps2(0.5 * (prev_vel_mps + vel_mps))
    return turned_lift_mps2(lift, prev_vel_mps, vel_mps), flight


def ball_acceleration_mps2(vel_mps: torch.Tensor, prev_vel_mps: torch.Tensor | None,
                           fps: float) -> torch.Tensor:
    """The ball's acceleration over the next frame (..., 3): the track's second difference
    where it reads as flight, else gravity plus drag (module doc). Float32 CPU tensors
    outside autograd take the compiled kernel (`flight_kernel.acceleration_rows`, as
    `physics_step_m`)."""
    rows = _kernel_rows(vel_mps, prev_vel_mps)
    if rows is not None:
        from sportsngen.model.flight_kernel import acceleration_rows

        shape, (vel, prev) = rows
        out = torch.empty(len(vel), 3, dtype=torch.float32)
        acceleration_rows(vel, vel if prev is None else prev, prev is not None, float(fps),
                          out.numpy())
        return out.reshape(shape)
    return ball_acceleration_mps2_torch(vel_mps, prev_vel_mps, fps)


def ball_acceleration_mps2_torch(vel_mps: torch.Tensor, prev_vel_mps: torch.Tensor | None,
                                 fps: float) -> torch.Tensor:
    """`ball_acceleration_mps2` in torch operations (any device, dtype and autograd)."""
    base = flight_acceleration_mps2(vel_mps)
    if prev_vel_mps is None:
        return base
    # The second difference is the acceleration at frame t - 1, where the velocity is the
    # mean of the two; the step (velocity at t - 1/2 to t + 1/2) needs it at frame t, one frame
    # later, by when drag has eased with the speed: uncorrected, a 30 m/s ball's step missed by
    # 1.1 mm, more than the centre bin's half-width (0.9 mm in x at 61 non-uniform bins);
    # corrected, by 0.3 mm.
    lift, flight = read_lift_mps2(vel_mps, prev_vel_mps, fps)
    at_t = flight_acceleration_mps2(1.5 * vel_mps - 0.5 * prev_vel_mps)
    return torch.where(flight, at_t + lift, base)


def lift_direction(vel_mps: torch.Tensor) -> torch.Tensor:
    """(..., 3) the direction Magnus lift takes for a ball spinning about its horizontal axis
    across the flight: perpendicular to the velocity, in its vertical plane, |v| long."""
    vu = torch.linalg.vector_norm(vel_mps[..., :2], dim=-1, keepdim=True)
    u_hat = vel_mps[..., :2] / vu.clamp_min(1e-6)
    return torch.cat([-vel_mps[..., 2:3] * u_hat, vu], dim=-1)


def magnus_ratio(coefficient, speed_from_mps, speed_to_mps):
    """The factor on `lift_direction` of a ball whose lift coefficient |C_L| is `coefficient`
    (< 1/2) at speed `speed_from_mps` (> 0) when its speed becomes `speed_to_mps` at the same
    spin: the generator's Magnus is k C_L |v| `lift_direction` with C_L = -spin / (2 |spin| +
    |v|), so the factor goes as |v| / (2 |spin| + |v|). Plain arithmetic: numpy arrays or
    tensors (the strike's numpy flight shares it)."""
    two_spin = 2.0 * coefficient * speed_from_mps / (1.0 - 2.0 * coefficient)
    return speed_to_mps * (two_spin + speed_from_mps) / \
        (speed_from_mps * (two_spin + speed_to_mps) + 1e-12)


def lift_coefficient(across: torch.Tensor, speed_mps: torch.Tensor) -> torch.Tensor:
    """|C_L| of a ball whose lift across the flight is `across` (...) times `lift_direction`
    at speed `speed_mps` (> 0), capped at `MAX_LIFT_COEFFICIENT`."""
    return (across.abs() / (MAGNUS_PER_M * speed_mps)).clamp(max=MAX_LIFT_COEFFICIENT)


def magnus_scale(across: torch.Tensor, speed_from_mps: torch.Tensor,
                 speed_to_mps: torch.Tensor) -> torch.Tensor:
    """How the lift across the flight, `across` (...) times `lift_direction` at speed
    `speed_from_mps`, scales when the ball's speed becomes `speed_to_mps` at the same spin
    (`magnus_ratio`, the spin read back by `lift_coefficient`)."""
    u = speed_from_mps.clamp_min(1e-6)
    return magnus_ratio(lift_coefficient(across, u), u, speed_to_mps)


def split_lift(lift_mps2: torch.Tensor, along_vel_mps: torch.Tensor,
               across_vel_mps: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """A lift (..., 3) without its part along `along_vel_mps`, split into its part across the
    flight of `across_vel_mps` in that velocity's vertical plane, as a coefficient (..., 1) on
    its `lift_direction`, and the sideways rest (..., 3)."""
    a2 = (along_vel_mps * along_vel_mps).sum(-1, keepdim=True).clamp_min(1e-6)
    lift = lift_mps2 - (lift_mps2 * along_vel_mps).sum(-1, keepdim=True) / a2 * along_vel_mps
    v2 = (across_vel_mps * across_vel_mps).sum(-1, keepdim=True).clamp_min(1e-6)
    d = lift_direction(across_vel_mps)
    across = (lift * d).sum(-1, keepdim=True) / v2
    return across, lift - across * d


def turned_lift_mps2(lift_mps2: torch.Tensor, prev_vel_mps: torch.Tensor,
                     vel_mps: torch.Tensor) -> torch.Tensor:
    """The lift read between `prev_vel_mps` and `vel_mps`, carried on a frame: its part along
    the velocity is dropped, its part across the flight in the velocity's vertical plane
    (`lift_direction`) turns with the velocity and changes size with its speed as the
    generator's Magnus does at the spin it reads as (`magnus_scale`), and the rest (sideways)
    is kept.
    The generator's Magnus is perpendicular to the velocity. Carried unturned, a ball flown by
    the step alone kept its lift pointing where it pointed at the start: recorded returns flown
    on from three frames after the contact landed a median 0.22 m (p90 0.33 m) from the
    generator's bounce; turned, 0.03 m (0.09 m); sized as |v|^2, 0.36 m (docs/evaluation.md,
    issue 17, seventh part). Sized in proportion to |v| (the small-spin limit), one frame's
    error was far below a bin but a rollout flies its own frames: over a slow ball's flight
    (a lob, a drop shot) the lift kept more of its size than the spin gives, the spin read at
    the bounce had grown (median 0.9 m/s from three frames after the contact to the bounce on
    the clay check, the generator's 0.02) and a slice died on the clay (fortieth part). Why
    drop the part along the velocity: Magnus has none and drag is the step's own, so in the
    generator's flights it reads 0.01-0.02 m/s^2, but read from a model's own strike frames it
    held a forward push (median 0.5-1.9, p90 3.3-4.1 m/s^2 in the bundled model's rollouts)
    that the step then carried to the bounce: less drag, rally balls flying long (tenth
    part)."""
    # The lift is read at the frame between the two velocities (their mean): its part along
    # the velocity there is what Magnus cannot give.
    across, side = split_lift(lift_mps2, 0.5 * (prev_vel_mps + vel_mps), prev_vel_mps)
    scale = magnus_scale(across, torch.linalg.vector_norm(prev_vel_mps, dim=-1, keepdim=True),
                         torch.linalg.vector_norm(vel_mps, dim=-1, keepdim=True))
    return side + across * scale * lift_direction(vel_mps)


def net_cord_m(y_m: torch.Tensor) -> torch.Tensor:
    """Height of the net cord at lateral positions `y_m` (`tennis.court.net_height_m` for
    tensors: the centre strap's 0.914 m rising as a parabola to 1.07 m at the posts)."""
    sag = (torch.clamp(y_m.abs(), max=NET_POST_Y_M) / NET_POST_Y_M) ** 2
    return NET_HEIGHT_CENTRE_M + (NET_HEIGHT_POST_M - NET_HEIGHT_CENTRE_M) * sag


def net_step_m(pos_m: torch.Tensor, vel_mps: torch.Tensor, acc_mps2: torch.Tensor,
               nxt_m: torch.Tensor, fps: float) -> torch.Tensor:
    """The step `pos_m` -> `nxt_m` with the net in the way: where the ball's leading surface
    reaches the net's plane within the step (its centre at |x| = R, on the side it comes
    from) with its bottom below the cord, the ball is there at that moment and flies the
    rest of the frame back at `NET_REBOUND` of its speed towards the net, `NET_KEEP_ACROSS`
    of the rest, under gravity (the generator's net). Elsewhere `nxt_m` unchanged.

    Why: without it the centre flew a ball low into the net straight through it, and the net
    hit was a large offset the model had to draw on the one frame it happens; under the
    ball's nucleus that draw was often cut, and 252 of 1,304 rallies of a check without
    physical limits sent a ball through the net (docs/evaluation.md, twenty-third part)."""
    side = torch.where(pos_m[..., 0] >= 0, 1.0, -1.0)
    gap = side * pos_m[..., 0] - BALL_RADIUS_M           # how far the ball is from touching
    travel = side * (pos_m[..., 0] - nxt_m[..., 0])     # how far it goes towards the net
    # When: the share of the frame at which it touches, along the step's parabola (the
    # backward difference is the velocity half a frame back, module doc), from the straight
    # line's share and one Newton step.
    dt = 1.0 / fps
    v0 = vel_mps + 0.5 * dt * acc_mps2
    frac = (gap / travel.clamp_min(1e-9)).clamp(0.0, 1.0)
    to_plane = side * (pos_m[..., 0] + v0[..., 0] * frac * dt
                       + 0.5 * acc_mps2[..., 0] * (frac * dt) ** 2) - BALL_RADIUS_M
    speed = side * (v0[..., 0] + acc_mps2[..., 0] * frac * dt) * dt
    frac = (frac - to_plane / torch.where(speed < 0, speed, -1e-9)).clamp(0.0, 1.0)[..., None]
    at = pos_m + v0 * frac * dt + 0.5 * acc_mps2 * (frac * dt) ** 2
    hit = ((side * pos_m[..., 0] > 0) & (travel > 0) & (travel >= gap)
           & (at[..., 2] - BALL_RADIUS_M < net_cord_m(at[..., 1])))
    v_at = v0 + acc_mps2 * frac * dt
    back = torch.stack([-NET_REBOUND * v_at[..., 0], NET_KEEP_ACROSS * v_at[..., 1],
                        NET_KEEP_ACROSS * v_at[..., 2]], dim=-1)
    rest_s = (1.0 - frac) / fps
    after = at + back * rest_s
    after[..., 2] = after[..., 2] - 0.5 * GRAVITY_MPS2 * rest_s[..., 0] ** 2
    return torch.where(hit[..., None], after, nxt_m)


def physics_step_m(pos_m: torch.Tensor, vel_mps: torch.Tensor,
                   prev_vel_mps: torch.Tensor | None, fps: float,
                   net: bool = False) -> torch.Tensor:
    """The ball's position one frame on (..., 3) from its position, velocity and previous
    velocity (..., 3), with `net` stopped by the net if it meets it below the cord
    (`net_step_m`), and bounced off the ground if the step ends below it.

    Float32 CPU tensors outside autograd take the compiled kernel
    (`flight_kernel.physics_rows`, the same arithmetic per ball): in torch the step is some
    150 tensor operations whose dispatch, not arithmetic, was a tenth of a rollout frame at
    one rally. Elsewhere (a GPU, float64, gradients) `physics_step_m_torch`, the reference."""
    rows = _kernel_rows(pos_m, vel_mps, prev_vel_mps)
    if rows is None:
        return physics_step_m_torch(pos_m, vel_mps, prev_vel_mps, fps, net)
    from sportsngen.model.flight_kernel import physics_rows

    shape, (pos, vel, prev) = rows
    out = torch.empty(len(pos), 3, dtype=torch.float32)
    physics_rows(pos, vel, vel if prev is None else prev, prev is not None, float(fps),
                 bool(net), out.numpy())
    return out.reshape(shape)


def _kernel_rows(*tensors: torch.Tensor | None):
    """(..., 3) tensors (None: absent) -> (their broadcast shape, their (n, 3) float32 arrays,
    None where absent) when all are float32 CPU tensors outside autograd, the compiled
    kernels' (`flight_kernel`) input; None otherwise."""
    given = [t for t in tensors if t is not None]
    if not all(t.device.type == "cpu" and t.dtype == torch.float32 and not t.requires_grad
               for t in given):
        return None
    if any(t.shape != given[0].shape for t in given):
        given = list(torch.broadcast_tensors(*given))
    flat = iter([t.reshape(-1, 3).contiguous().numpy() for t in given])
    return given[0].shape, [None if t is None else next(flat) for t in tensors]


def physics_step_m_torch(pos_m: torch.Tensor, vel_mps: torch.Tensor,
                         prev_vel_mps: torch.Tensor | None, fps: float,
                         net: bool = False) -> torch.Tensor:
    """`physics_step_m` in torch operations (any device, dtype and autograd)."""
    acc = ball_acceleration_mps2_torch(vel_mps, prev_vel_mps, fps)
    nxt = pos_m + vel_mps / fps + acc / (fps * fps)
    if net:
        nxt = net_step_m(pos_m, vel_mps, acc, nxt, fps)
    z = nxt[..., 2]
    below = (z < BALL_RADIUS_M) & (vel_mps[..., 2] < 0)
    bounced = BALL_RADIUS_M + BOUNCE_RESTITUTION * (BALL_RADIUS_M - z)
    return torch.cat([nxt[..., :2], torch.where(below, bounced, z)[..., None]], dim=-1)


def player_centre_m(pos_m: torch.Tensor, vel_mps: torch.Tensor, fps: float,
                    mode: str) -> torch.Tensor:
    """Centre of a player's (or, with the legacy modes, any object's) bins."""
    if mode == "current":
        return pos_m
    if mode == "cv":
        return pos_m + vel_mps / fps
    raise ValueError(f"bin centre must be one of {PLAYER_CENTRES}, got {mode!r}")


def ball_centre_m(pos_m: torch.Tensor, vel_mps: torch.Tensor,
                  prev_vel_mps: torch.Tensor | None, fps: float, mode: str,
                  net: bool = False) -> torch.Tensor:
    """Centre of the ball's bins (..., 3) by `mode` (one of `BALL_CENTRES`; `net`: the
    physics step meets the net)."""
    if mode == "physics":
        return physics_step_m(pos_m, vel_mps, prev_vel_mps, fps, net)
    if mode == "velocity":
        return pos_m + vel_mps / fps
    if mode == "current":
        return pos_m
    raise ValueError(f"ball centre must be one of {BALL_CENTRES}, got {mode!r}")


def object_centres_m(pos_m: torch.Tensor, vel_mps: torch.Tensor,
                     prev_vel_mps: torch.Tensor | None, fps: float, player_mode: str,
                     ball_mode: str, ball: int, ball_net: bool = False) -> torch.Tensor:
    """Centres of all objects (..., N, 3): players by `player_mode`, object `ball` by
    `ball_mode` (with the net where `ball_net`)."""
    out = player_centre_m(pos_m, vel_mps, fps, player_mode).clone()
    prev = None if prev_vel_mps is None else prev_vel_mps[..., ball, :]
    out[..., ball, :] = ball_centre_m(pos_m[..., ball, :], vel_mps[..., ball, :], prev, fps,
                                      ball_mode, ball_net)
    return out
