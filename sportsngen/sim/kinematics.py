"""The players' kinematic limit in rollouts: a sampled frame changes a player's velocity by at
most what his legs can.

The generator's players change their velocity by at most their acceleration a frame
(`synth.players.Mover`: 6 m/s² for every named player but Isner's 5), so in its tracks no
player's frame-to-frame acceleration exceeds 6.0 m/s². The model's sampled frames do: a
receiver's largest acceleration in the 25 frames after the serve is 8.1 m/s² at the median
(8.4 at the 90th percentile), he is 0.3-0.5 m/s faster than the truth's 10-15 frames after
the serve and reaches more serves than they do (docs/evaluation.md, thirty-seventh part).
`limit_player_acceleration` scales the change of a player's velocity in a sampled frame down
to the limit, keeping its direction: physics the model need not learn. Every frame the model
draws is limited, redraws included (`sim.rollout`); the rule that keeps a late chaser running
(`sim.constraints.KeepChasing`) acts after the draw, raising his speed toward the ball by its
own 6 m/s², and may then take a frame beyond the limit. `limit_player_speed` bounds each
player's speed in a frame by his own top speed read from his record (`sim.top_speed`), every
draw and the chase rule's final frame included (fifty-fourth part).

The generator's players accelerate flat out or well short of it: in version 6.4's tracks
(seed 1, 1,600 points) 62.4 % of the players' frames change velocity by 6.0 m/s² and 0.6 %
by 5.0-5.99. The decoder draws a player's x and y apart, each inside its bin, so the size of
a flat-out change spreads below the limit: 28.3 % of the bundled model's frames fall in
5.0-5.99 and 24.4 % at 6.0. On the serve's receiver that spread is a signal of its own: the
receivers of its aces ran 5.80 m/s² at the twelfth frame against 5.61 on returned serves,
most between 5.5 and 6.0, where every truth receiver of an ace ran 6.0, and the leak check read it
(0.372 on seed 1). `full_from_frac` sets a change of at least `FULL_ACCEL_FROM_FRAC` of the
limit to the limit, its direction kept (docs/evaluation.md, seventy-seventh part).

The same two draws turn a flat-out run: the generator's players accelerate along their heading,
the model's change it by a few degrees a frame (the first-serve receivers of its aces lost
0.051 m/s of speed by the twelfth frame to the angle of their velocity changes, the truth's
none), and the leak check read the spread (0.351 on seed 0). `keep_heading_deg` turns a
flat-out change within that angle of a running player's heading (`HEADING_FROM_MPS`) onto it,
its size kept; a turn wider than that, braking and a start from standing stay as drawn
(docs/evaluation.md, seventy-eighth part).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from sportsngen.errors import ArgumentError
from sportsngen.model.inputs import BALL
from sportsngen.model.packed import kernel_inputs
from sportsngen.sim import constraint_kernel

# A velocity change of at least this share of the limit is flat out: the generator's players'
# frames between it and the limit are 0.3 % of their frames, the bundled model's draws 26 %.
FULL_ACCEL_FROM_FRAC = 0.9
# A flat-out change within this angle of the heading is a run along it (`keep_heading_deg`), for
# players at least this fast: below it the heading is the last frame's jitter.
KEEP_HEADING_DEG = 30.0
HEADING_FROM_MPS = 0.5
# The player rules' parameters and their ranges, as (lowest, highest, highest allowed): the one
# place they are checked, by `PlayerLimits` when made (the `Simulator`'s) and by the flags.
PLAYER_RULE_RANGES = {"accel_mps2": (0.0, math.inf, False),
                      "full_from_frac": (0.0, 1.0, True),
                      "keep_heading_deg": (0.0, 180.0, False)}


def check_player_rules(names: dict[str, str] | None = None, **values: float | None
                       ) -> dict[str, float | None]:
    """The player rules' parameters (`PLAYER_RULE_RANGES`' keys) -> the same as floats, None
    kept (the rule off); an `ArgumentError` names the first out of its range, by `names[key]`
    where given (a flag, say), else by its key."""
    out = {}
    for key, value in values.items():
        if key not in PLAYER_RULE_RANGES:
            raise ArgumentError(f"not a player rule: {key!r} (rules: {list(PLAYER_RULE_RANGES)})")
        if value is None:
            out[key] = None
            continue
        lo, hi, hi_allowed = PLAYER_RULE_RANGES[key]
        label = (names or {}).get(key, key)
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise ArgumentError(f"{label} must be a number, got {value!r}") from None
        inside = lo < number and (number <= hi if hi_allowed else number < hi)
        if not inside:
            bounds = "positive" if hi == math.inf else \
                f"in ({lo:g}, {hi:g}{']' if hi_allowed else ')'}"
            raise ArgumentError(f"{label} must be {bounds}, got {value!r}")
        out[key] = number
    return out


@dataclass(frozen=True)
class PlayerLimits:
    """The rules every sampled player frame obeys, checked once when made (`check_player_rules`)
    rather than on every frame: a velocity change of at most `accel_mps2`, one of at least
    `full_from_frac` of it set to it (None: as drawn), a flat-out one within `keep_heading_deg`
    of a running player's heading turned onto it (None: as drawn)."""

    accel_mps2: float
    full_from_frac: float | None = None
    keep_heading_deg: float | None = None

    def __post_init__(self) -> None:
        checked = check_player_rules(accel_mps2=self.accel_mps2,
                                     full_from_frac=self.full_from_frac,
                                     keep_heading_deg=self.keep_heading_deg)
        if checked["accel_mps2"] is None:
            raise ArgumentError("accel_mps2 must be positive, got None (no limit: no PlayerLimits)")
        for key, value in checked.items():
            object.__setattr__(self, key, value)

    @classmethod
    def from_options(cls, accel_mps2: float | None, full_from_frac: float | None = None,
                     keep_heading_deg: float | None = None,
                     names: dict[str, str] | None = None) -> PlayerLimits | None:
        """The limits of a caller's options, each checked under the caller's own name
        (`names[key]`: a flag, a keyword) -> None where `accel_mps2` is None (the other two
        act only on the limit, but are checked all the same)."""
        checked = check_player_rules(names, accel_mps2=accel_mps2,
                                     full_from_frac=full_from_frac,
                                     keep_heading_deg=keep_heading_deg)
        return None if checked["accel_mps2"] is None else cls(**checked)


def limit_player_acceleration(next_pos_m: torch.Tensor, pos_m: torch.Tensor,
                              vel_mps: torch.Tensor, fps: float,
                              limits: PlayerLimits) -> torch.Tensor:
    """Sampled next frames `next_pos_m` (B, 3, 3) from positions `pos_m` with velocities
    `vel_mps` (B, 3, 3) -> the same frames with each player's horizontal velocity change
    (next - pos) * fps - vel scaled down to at most `limits.accel_mps2` / fps, its direction
    kept; the ball and players within the limit unchanged. With `limits.full_from_frac` a
    change of at least that fraction of the limit is set to the limit (`FULL_ACCEL_FROM_FRAC`);
    with `limits.keep_heading_deg` a flat-out change that near a running player's heading is
    turned onto it."""
    full_from_frac, keep_heading_deg = limits.full_from_frac, limits.keep_heading_deg
    if kernel_inputs(next_pos_m, pos_m, vel_mps):
        out = np.empty(next_pos_m.shape, dtype=np.float32)
        nan = np.float32("nan")
        constraint_kernel.accel_rows(
            next_pos_m.numpy(), pos_m.numpy(), vel_mps.numpy(), np.float32(fps),
            np.float32(limits.accel_mps2 / fps),
            nan if full_from_frac is None else np.float32(full_from_frac),
            nan if keep_heading_deg is None else np.float32(math.cos(math.radians(
                keep_heading_deg))), np.float32(HEADING_FROM_MPS), out)
        return torch.from_numpy(out)
    step = next_pos_m[:, :BALL, :2] - pos_m[:, :BALL, :2]
    dv = step * fps - vel_mps[:, :BALL, :2]
    norm = dv.norm(dim=-1, keepdim=True)
    limit = limits.accel_mps2 / fps
    over = norm > limit if full_from_frac is None else norm >= full_from_frac * limit
    scale = torch.where(over, limit / norm.clamp_min(1e-12), torch.ones_like(norm))
    dv = dv * scale
    if keep_heading_deg is not None:
        vel = vel_mps[:, :BALL, :2]
        speed = vel.norm(dim=-1, keepdim=True)
        size = dv.norm(dim=-1, keepdim=True)
        cos = (dv * vel).sum(-1, keepdim=True) / (speed * size).clamp_min(1e-12)
        along = (speed >= HEADING_FROM_MPS) & (size >= limit * (1 - 1e-6)) \
            & (cos >= math.cos(math.radians(keep_heading_deg)))
        dv = torch.where(along, vel / speed.clamp_min(1e-12) * size, dv)
    out = next_pos_m.clone()
    out[:, :BALL, :2] = pos_m[:, :BALL, :2] + (vel_mps[:, :BALL, :2] + dv) / fps
    return out


def limit_player_speed(next_pos_m: torch.Tensor, pos_m: torch.Tensor, fps: float,
                       top_speed_mps: torch.Tensor) -> torch.Tensor:
    """Sampled next frames `next_pos_m` (B, 3, 3) from positions `pos_m` -> the same frames
    with each player's horizontal step scaled down to at most his top speed `top_speed_mps`
    (B, 2: server, receiver; `sim.top_speed`) over a frame, its direction kept; the ball and
    players within their speed unchanged."""
    if top_speed_mps.shape != (len(pos_m), BALL):
        raise ValueError(f"top_speed_mps must be (B, {BALL}), got {tuple(top_speed_mps.shape)}")
    if kernel_inputs(next_pos_m, pos_m, top_speed_mps):
        out = np.empty(next_pos_m.shape, dtype=np.float32)
        constraint_kernel.speed_rows(next_pos_m.numpy(), pos_m.numpy(), np.float32(fps),
                                     top_speed_mps.numpy(), out)
        return torch.from_numpy(out)
    step = next_pos_m[:, :BALL, :2] - pos_m[:, :BALL, :2]
    norm = step.norm(dim=-1, keepdim=True)
    limit = top_speed_mps[..., None].to(step.dtype) / fps
    scale = torch.where(norm > limit, limit / norm.clamp_min(1e-12), torch.ones_like(norm))
    out = next_pos_m.clone()
    out[:, :BALL, :2] = pos_m[:, :BALL, :2] + step * scale
    return out
