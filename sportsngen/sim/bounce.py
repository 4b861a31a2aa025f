"""The ball's bounce in rollouts, given by the surface's physics instead of drawn by the model.

The physics centre (`model.centre`) bounces a step with one vertical restitution and keeps the
horizontal speed, so the model must learn from its bins how much of it a surface takes away:
the generator's clay keeps 0.605 of a serve's horizontal speed (median of the bounces faster
than 28 m/s, interquartile 0.59-0.61), the bundled model's rollouts 0.664 (0.61-0.71), and its
simulated receivers meet a faster ball later (docs/evaluation.md, thirty-sixth part). The
bounce is physics the game fixes, so here it is taken from the generator's own bounce
(`synth.physics`: restitution, ploughing, Coulomb friction on the contact point's slip): where
the ball's flight reaches the ground inside the next frame, that frame and the two after are
the flight flown on through the surface's bounce from the current state, with the spin read
from the lift of the track's last three frames (`model.centre.read_lift_mps2`, inverted
through the generator's Magnus). The model then draws the flight on from a clean post-bounce
track, as it does after a strike's launch frames, and the physics centre reads the spin the
bounce gave from three post-bounce frames (`FRAMES`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from sportsngen.model.centre import (
    MAGNUS_PER_M,
    MAX_LIFT_COEFFICIENT,
    ball_acceleration_mps2,
    lift_direction,
    read_lift_mps2,
)
from sportsngen.model.inputs import BALL
from sportsngen.model.packed import kernel_inputs
from sportsngen.synth.physics import fly
from sportsngen.tennis.court import BALL_RADIUS_M

# The bounce's frame and the two after it. The second after is given too because the physics
# centre reads the ball's spin from its last three frames: with two given, the first free step
# after a bounce read the bounce itself (no flight: gravity and drag alone) and the next read a
# lift half made of the model's own draw, so the topspin the bounce gives a ball (the
# generator's friction on the contact point) was mostly lost: on the bundled file's clay
# rollouts the rising ball fell at a median 10.8 m/s^2 where the generator's falls at 12.5, and
# its rally balls were met above 1.05 m four times as often (docs/evaluation.md, fiftieth part).
FRAMES = 3


def spin_from_lift_mps(lift_mps2: torch.Tensor, vel_mps: torch.Tensor) -> torch.Tensor:
    """The generator's spin (m/s, > 0 topspin) of balls at velocity `vel_mps` (N, 3) whose lift
    reads `lift_mps2` (N, 3): its part across the flight in the velocity's vertical plane is
    k C_L |v|^2 with C_L = -spin / (2 |spin| + |v|) (`synth.physics`), inverted."""
    speed = torch.linalg.vector_norm(vel_mps, dim=-1)
    across = (lift_mps2 * lift_direction(vel_mps)).sum(-1) / \
        (speed * speed).clamp_min(1e-9)                            # = k C_L |v|
    cl = (across / (MAGNUS_PER_M * speed.clamp_min(1e-6))).clamp(-MAX_LIFT_COEFFICIENT,
                                                              MAX_LIFT_COEFFICIENT)
    return -torch.sign(cl) * cl.abs() * speed / (1.0 - 2.0 * cl.abs())


def bouncing_rows(pos_m: torch.Tensor, vel_mps: torch.Tensor, prev_vel_mps: torch.Tensor,
                  fps: float) -> torch.Tensor:
    """(B,) bool: the ball (`pos_m` etc. (B, 3, 3), `BALL` the ball's row) falls and its flight
    (gravity, drag and the lift read from the track) reaches the ground inside the next
    frame."""
    p, v = pos_m[:, BALL], vel_mps[:, BALL]
    acc = ball_acceleration_mps2(v, prev_vel_mps[:, BALL], fps)
    dt = 1.0 / fps
    if kernel_inputs(p, v, acc):
        # The torch lines below in numpy (float32, the scalars as torch casts them): a
        # rollout frame's few rows cost a quarter.
        pz, vz, az, dt32 = p[:, 2].numpy(), v[:, 2].numpy(), acc[:, 2].numpy(), np.float32(dt)
        z = pz + vz * dt32 + az * dt32 * dt32
        return torch.from_numpy((vz < 0) & (z < np.float32(BALL_RADIUS_M)) & np.isfinite(z))
    z_next = p[:, 2] + v[:, 2] * dt + acc[:, 2] * dt * dt
    return (v[:, 2] < 0) & (z_next < BALL_RADIUS_M) & torch.isfinite(z_next)


def bounce_frames(pos_m: torch.Tensor, vel_mps: torch.Tensor, prev_vel_mps: torch.Tensor,
                  fps: float, surfaces: Sequence[str]) -> torch.Tensor:
    """The ball's next `FRAMES` frames (B, FRAMES, 3) flown through the bounce on each row's
    surface from the current frame: the velocity at the frame is the backward difference
    carried half a frame on by the track's acceleration, the spin is read from its lift
    (`spin_from_lift_mps`; none where the last three frames are no flight)."""
    p, v, pv = pos_m[:, BALL], vel_mps[:, BALL], prev_vel_mps[:, BALL]
    acc = ball_acceleration_mps2(v, pv, fps)
    v_now = (v + 0.5 * acc / fps).double()
    lift, flight = read_lift_mps2(v, pv, fps)
    spin = torch.where(flight[:, 0], spin_from_lift_mps(lift.double(), v_now), 0.0).cpu().numpy()
    v_now = v_now.cpu().numpy()
    start = p.double().cpu().numpy()
    start[:, 2] = np.maximum(start[:, 2], BALL_RADIUS_M)
    times = np.arange(1, FRAMES + 1) / fps
    out = np.empty((len(start), FRAMES, 3))
    for i in range(len(start)):
        f = fly(start[i], v_now[i], float(spin[i]), surfaces[i], times[-1] + 1e-6,
                max_bounces=2)
        out[i] = f.at(np.minimum(times, f.t_end_s))
    return torch.as_tensor(out, dtype=pos_m.dtype, device=pos_m.device)


def place_bounces(nxt: torch.Tensor, plan: torch.Tensor, pos_m: torch.Tensor,
                  vel_mps: torch.Tensor, prev_vel_mps: torch.Tensor, fps: float,
                  surfaces: np.ndarray, live: np.ndarray,
                  placed: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """Where the ball bounces inside the next frame and no launch is being followed (`plan`,
    (B, 2, 3), NaN where none, as the rollout keeps it, and not `placed` (B,) bool: the frame
    just put down was planned), the sampled frame `nxt` (B, 3, 3) replaced by the surface's
    bounce (`bounce_frames`) and its next `FRAMES` - 1 frames planned;
    `surfaces`: each batch row's surface name as first given, `live` the live rows' indices
    into it. The frame after a bounce is planned because its backward velocity mixes the fall
    and the rise: read as a state, it bounced the ball again (rollouts' serves read 1 m long by
    the rules, 10 % of them); the one after that so the spin is read from the bounce's own
    frames (`FRAMES`)."""
    if plan.shape[1] < FRAMES - 1:
        raise ValueError(f"the plan holds {plan.shape[1]} frames; a bounce gives {FRAMES - 1} "
                         "after the sampled one")
    rows = bouncing_rows(pos_m, vel_mps, prev_vel_mps, fps) & torch.isnan(plan[:, 0, 0])
    if placed is not None:
        rows &= ~placed
    idx = torch.nonzero(rows).flatten()
    if len(idx) == 0:
        return nxt, plan
    frames = bounce_frames(pos_m[idx], vel_mps[idx], prev_vel_mps[idx], fps,
                           [str(s) for s in surfaces[live[idx.cpu().numpy()]]])
    nxt, plan = nxt.clone(), plan.clone()
    nxt[idx, BALL] = frames[:, 0]
    plan[idx, :FRAMES - 1] = frames[:, 1:]
    return nxt, plan
