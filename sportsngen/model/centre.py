"""Where the bins of an object's next-frame offset are centred.

The model predicts each object's next position as a class over bins around a centre, so the
centre decides what it must learn. Players: the current position ("current", the paper) or a
constant-velocity extrapolation ("cv"). The ball (`ModelConfig.ball_centre`):

- ``"current"``: the current position (the paper);
- ``"velocity"``: one frame at the current velocity;
- ``"physics"``: one step of the ball's flight. The acceleration (gravity, drag and Magnus
  together) is read from the last three frames (the second difference), which carries the
  spin without estimating it; where that reading is not a flight (a racket contact or a bounce
  fell among those frames, a toss left the hand, or the track is too noisy: it departs from
  gravity plus drag by more than Magnus could at that speed, `MAX_LIFT_PER_M` |v|^2, capped
  at `MAX_LIFT_MPS2`) the step uses gravity plus drag alone for those frames. A step
  that would end below the ground bounces (`BOUNCE_RESTITUTION`).

Velocities are backward differences (frame t minus frame t-1, times the frame rate), so the
physics step is the exact extrapolation of a constant acceleration:
``p(t+1) = p(t) + v(t) dt + a dt^2`` with ``a = (v(t) - v(t-1)) / dt``. In free flight of the
generated ball the next frame then lies in the centre bin of all three dimensions for almost
every frame (`docs/architecture.md`), and the model spends its capacity on contacts and
bounces, not on re-learning the flight.
"""

from __future__ import annotations

import torch

from sportsngen.model.config import BALL_CENTRES, BALL_FRAMES
from sportsngen.tennis.court import BALL_RADIUS_M

PLAYER_CENTRES = ("current", "cv")
GRAVITY_MPS2 = 9.81
# Drag per metre of a standard ball, rho pi R^2 C_d / (2 m) with air 1.21 kg/m^3, R 33.5 mm,
# 57 g and C_d 0.55 (the generator's values, `sportsngen.synth.physics`): 51 m/s^2 at 50 m/s.
DRAG_PER_M = 0.0206
# Magnus of a rally ball is at most ~15 m/s^2 (8 m/s of topspin at 30 m/s: 6 m/s^2); a second
# difference further than this from gravity plus drag holds a contact or a bounce.
MAX_LIFT_MPS2 = 30.0
# Magnus can do no more than k |v|^2 / 2 for any spin (the generator's lift coefficient
# spin / (2 |spin| + |v|) is under 1/2; k = DRAG_PER_M / C_d): 0.5 m/s^2 for a 5 m/s toss,
# 17 m/s^2 at 30 m/s. A slow ball's second difference beyond that is no flight: read as one,
# a toss's release (the hand stops, the ball flies on) was carried on as a 20-30 m/s^2 "lift"
# that flew the model's own tosses backwards past the server (docs/evaluation.md).
MAX_LIFT_PER_M = DRAG_PER_M / 0.55 / 2.0
# Vertical speed kept by a bounce inside the step (the surfaces' 0.73-0.80; the exact bounce
# is the model's to learn, the centre only has to be near it).
BOUNCE_RESTITUTION = 0.77
# The acceleration axes replace the court's only after a change of velocity this large over
# the last frame: a racket contact or a bounce. Free flight changes it by at most ~4 m/s a
# frame (drag at 70 m/s plus gravity). Binned on axes that follow every frame's change, the
# sampled noise of a rollout's own last frames turned its axes, the next frame followed them,
# and a fine-tune's tosses flew off: 98 of 212 rallies struck no serve (docs/evaluation.md).
MIN_FRAME_DV_MPS = 6.0


def flight_acceleration_mps2(vel_mps: torch.Tensor) -> torch.Tensor:
    """(..., 3) velocities -> gravity plus drag (..., 3), no spin."""
    speed = torch.linalg.vector_norm(vel_mps, dim=-1, keepdim=True)
    acc = -DRAG_PER_M * speed * vel_mps
    acc[..., 2] -= GRAVITY_MPS2
    return acc


def ball_acceleration_mps2(vel_mps: torch.Tensor, prev_vel_mps: torch.Tensor | None,
                           fps: float) -> torch.Tensor:
    """The ball's acceleration over the next frame (..., 3): the track's second difference
    where it reads as flight, else gravity plus drag (module doc)."""
    base = flight_acceleration_mps2(vel_mps)
    if prev_vel_mps is None:
        return base
    track = (vel_mps - prev_vel_mps) * fps
    speed2 = (vel_mps * vel_mps).sum(dim=-1, keepdim=True)
    limit = torch.clamp(MAX_LIFT_PER_M * speed2, max=MAX_LIFT_MPS2)
    flight = torch.linalg.vector_norm(track - base, dim=-1, keepdim=True) <= limit
    # The second difference is the acceleration at frame t - 1; the step (velocity at
    # t - 1/2 to t + 1/2) needs it at frame t, one frame later, by when drag has eased with the
    # speed: uncorrected, a 30 m/s ball's step missed by 1.1 mm, more than the centre bin's
    # half-width (0.9 mm in x at 61 non-uniform bins); corrected, by 0.3 mm.
    eased = track + (base - flight_acceleration_mps2(prev_vel_mps))
    return torch.where(flight, eased, base)


def physics_step_m(pos_m: torch.Tensor, vel_mps: torch.Tensor,
                   prev_vel_mps: torch.Tensor | None, fps: float) -> torch.Tensor:
    """The ball's position one frame on (..., 3) from its position, velocity and previous
    velocity (..., 3), bounced off the ground if the step ends below it."""
    acc = ball_acceleration_mps2(vel_mps, prev_vel_mps, fps)
    nxt = pos_m + vel_mps / fps + acc / (fps * fps)
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
                  prev_vel_mps: torch.Tensor | None, fps: float, mode: str) -> torch.Tensor:
    """Centre of the ball's bins (..., 3) by `mode` (one of `BALL_CENTRES`)."""
    if mode == "physics":
        return physics_step_m(pos_m, vel_mps, prev_vel_mps, fps)
    if mode == "velocity":
        return pos_m + vel_mps / fps
    if mode == "current":
        return pos_m
    raise ValueError(f"ball centre must be one of {BALL_CENTRES}, got {mode!r}")


def object_centres_m(pos_m: torch.Tensor, vel_mps: torch.Tensor,
                     prev_vel_mps: torch.Tensor | None, fps: float, player_mode: str,
                     ball_mode: str, ball: int) -> torch.Tensor:
    """Centres of all objects (..., N, 3): players by `player_mode`, object `ball` by
    `ball_mode`."""
    out = player_centre_m(pos_m, vel_mps, fps, player_mode).clone()
    prev = None if prev_vel_mps is None else prev_vel_mps[..., ball, :]
    out[..., ball, :] = ball_centre_m(pos_m[..., ball, :], vel_mps[..., ball, :], prev, fps,
                                      ball_mode)
    return out


def ball_frame_axes(vel_mps: torch.Tensor, prev_vel_mps: torch.Tensor | None,
                    mode: str) -> torch.Tensor | None:
    """Axes (..., 3, 3) (rows e1, e2, e3, orthonormal) the ball's offsets are binned in, or
    None for the court's own axes.

    ``"acceleration"``: after a racket contact or a bounce (the last frame's change of
    velocity at least `MIN_FRAME_DV_MPS`), e1 along that change, e2 the court's y made
    perpendicular to it (x where e1 lies within 25 degrees of y), e3 = e1 x e2; the court's
    axes otherwise. After a contact the next offset (velocity centre) is the contact's own
    offset again, scaled by the unknown time of the contact inside its frame, plus gravity: on
    the court's axes the head must keep y and z in proportion to x to fly the ball where the
    contact aimed it, and models that did not landed 50 % of their serves in the box against
    the data's 69 % (docs/evaluation.md); along e1 that is one number and the other two stay
    near zero."""
    if mode == "court" or prev_vel_mps is None:
        if mode not in BALL_FRAMES:
            raise ValueError(f"ball frame must be one of {BALL_FRAMES}, got {mode!r}")
        return None
    if mode != "acceleration":
        raise ValueError(f"ball frame must be one of {BALL_FRAMES}, got {mode!r}")
    dv = vel_mps - prev_vel_mps
    norm = torch.linalg.vector_norm(dv, dim=-1, keepdim=True)
    court = torch.eye(3, dtype=vel_mps.dtype, device=vel_mps.device).expand(
        *vel_mps.shape[:-1], 3, 3)
    e1 = dv / norm.clamp_min(1e-9)
    y_axis = torch.zeros_like(e1)
    y_axis[..., 1] = 1.0
    x_axis = torch.zeros_like(e1)
    x_axis[..., 0] = 1.0
    ref = torch.where(e1[..., 1:2].abs() < 0.9, y_axis, x_axis)
    e2 = ref - (ref * e1).sum(dim=-1, keepdim=True) * e1
    e2 = e2 / torch.linalg.vector_norm(e2, dim=-1, keepdim=True).clamp_min(1e-9)
    axes = torch.stack([e1, e2, torch.linalg.cross(e1, e2)], dim=-2)
    return torch.where((norm >= MIN_FRAME_DV_MPS)[..., None], axes, court)


def to_ball_frame(offset_m: torch.Tensor, axes: torch.Tensor | None) -> torch.Tensor:
    """Court-frame offsets (..., 3) -> their coordinates on `axes` (None: unchanged)."""
    return offset_m if axes is None else (axes @ offset_m[..., None])[..., 0]


def from_ball_frame(coords_m: torch.Tensor, axes: torch.Tensor | None) -> torch.Tensor:
    """Inverse of `to_ball_frame`."""
    return coords_m if axes is None else (axes.transpose(-1, -2) @ coords_m[..., None])[..., 0]
