"""Sampling constraints for rollouts: rejection of sampled frames (see `rollout.Constraint`).

`PhysicalLimits` keeps rollouts on the physically possible side of the checks a learned model
breaks most: the ball going below the ground, the ball passing through the net and (with
`reach_m`) the ball struck back with no player near it. A
sampled frame that does any of these is drawn again from the same distribution (so the frame comes
from the model's distribution restricted to the possible set, renormalised), up to `max_tries`
times; the count of redraws is reported per rally, and a rally whose frame could not be fixed
is then corrected by the court's solid objects (`PhysicalLimits.project`: the net stops the
ball, the ground holds it) and the rules judge it from there. This goes beyond the paper,
which flags such rallies after the fact (about 20 % of them); the unconstrained rate is one
switch away (`Simulator(physical_limits=False)`).
"""

from __future__ import annotations

import numpy as np
import torch

from sportsngen.tennis.court import NET_HEIGHT_CENTRE_M, NET_HEIGHT_POST_M, NET_POST_Y_M
from sportsngen.tennis.rally import (
    CONTACT_MAX_Z_M,
    CONTACT_REACH_M,
    NET_ZONE_M,
    SHOT_MIN_VX_MPS,
)

BALL = 2
NET_STOP_M = 0.05               # a ball stopped by the net rests this far from its plane


class PhysicalLimits:
    """Reject a sampled frame whose ball is below the ground, or crossed the net's plane
    below the cord since the previous frame, or (`reach_m` not None) reverses along x, as a
    racket sends it back, while no player is within `reach_m` of it (horizontally; the rally
    rules' reach by default) or it is higher than a racket reaches. A reversal at the net is
    left alone: the net sends balls back. Tolerances in metres.

    Why the reach: a model unsure on which frame a player strikes the ball spreads the
    contact over frames. A nucleus (top-p under 1) cuts a contact whose frame holds less than
    1 - top-p of the probability, and receivers let serves they reach fly past; drawn at the
    model's own odds instead (`contact_odds`), 22.5 % of a fine-tune's rallies had a ball
    struck back from 2.5 m or more away (docs/evaluation.md). Rejecting only the impossible
    contacts lets the possible ones happen at the model's rate."""

    def __init__(self, ground_tol_m: float = 0.02, net_tol_m: float = 0.02,
                 max_tries: int = 20, reach_m: float | None = CONTACT_REACH_M,
                 fps: float = 25.0):
        self.ground_tol_m = ground_tol_m
        self.fps = float(fps)
        self.net_tol_m = net_tol_m
        self.reach_m = reach_m
        self.max_tries = max_tries
        self.offset = 0
        self.given_up = 0
        self.projected = 0

    def accept(self, rows: np.ndarray, frame: int, pos_m: torch.Tensor,
               next_pos_m: torch.Tensor, vel_mps: torch.Tensor | None = None) -> torch.Tensor:
        a, b = pos_m[:, BALL], next_pos_m[:, BALL]
        ok = b[:, 2] >= -self.ground_tol_m
        if self.reach_m is not None and vel_mps is not None:
            ok &= ~self.struck_out_of_reach(pos_m, next_pos_m, vel_mps)
        crossed = (a[:, 0] * b[:, 0]) < 0
        if bool(crossed.any()):
            frac = a[:, 0] / (a[:, 0] - b[:, 0] + 1e-12)
            y = a[:, 1] + frac * (b[:, 1] - a[:, 1])
            z = a[:, 2] + frac * (b[:, 2] - a[:, 2])
            sag = (torch.clamp(y.abs(), max=NET_POST_Y_M) / NET_POST_Y_M) ** 2
            cord = NET_HEIGHT_CENTRE_M + (NET_HEIGHT_POST_M - NET_HEIGHT_CENTRE_M) * sag
            ok &= ~crossed | (z >= cord - self.net_tol_m)
        return ok

    def struck_out_of_reach(self, pos_m: torch.Tensor, next_pos_m: torch.Tensor,
                            vel_mps: torch.Tensor) -> torch.Tensor:
        """(B,) bool: the sampled frame reverses the ball along x (each way at least the
        rules' `SHOT_MIN_VX_MPS`) away from the net, with no player within `reach_m` of it or
        the ball above `CONTACT_MAX_Z_M`."""
        ball = pos_m[:, BALL]
        vx_in = vel_mps[:, BALL, 0]
        vx_out = (next_pos_m[:, BALL, 0] - ball[:, 0]) * self.fps
        reverse = (vx_in * vx_out < 0) & (vx_in.abs() > SHOT_MIN_VX_MPS) & \
            (vx_out.abs() > SHOT_MIN_VX_MPS)
        gap = torch.linalg.vector_norm(pos_m[:, :BALL, :2] - ball[:, None, :2], dim=-1)
        near = (gap.min(dim=1).values <= self.reach_m) & (ball[:, 2] <= CONTACT_MAX_Z_M)
        return reverse & ~near & (ball[:, 0].abs() >= NET_ZONE_M)

    def give_up(self, rows: np.ndarray) -> None:
        self.given_up += len(rows)

    def project(self, pos_m: torch.Tensor, next_pos_m: torch.Tensor) -> torch.Tensor:
        """The court's solid objects, for frames no redraw could fix: a ball that would pass
        through the net stops at it (on the side it came from, at the height it met the
        net), and a ball below the ground is lifted onto it. The rally-end rules then judge the
        ball at the net as a net ball."""
        out = next_pos_m.clone()
        a, b = pos_m[:, BALL], out[:, BALL]
        crossed = (a[:, 0] * b[:, 0]) < 0
        frac = a[:, 0] / (a[:, 0] - b[:, 0] + 1e-12)
        y = a[:, 1] + frac * (b[:, 1] - a[:, 1])
        z = a[:, 2] + frac * (b[:, 2] - a[:, 2])
        sag = (torch.clamp(y.abs(), max=NET_POST_Y_M) / NET_POST_Y_M) ** 2
        cord = NET_HEIGHT_CENTRE_M + (NET_HEIGHT_POST_M - NET_HEIGHT_CENTRE_M) * sag
        stop = crossed & (z < cord - self.net_tol_m)
        b[stop, 0] = torch.sign(a[stop, 0]) * NET_STOP_M
        b[stop, 1] = y[stop]
        b[stop, 2] = z[stop].clamp(min=0.0)
        b[:, 2] = b[:, 2].clamp(min=0.0)
        self.projected += int(stop.sum())
        return out


class AllOf:
    """Several constraints at once: a frame must satisfy all of them."""

    def __init__(self, *constraints):
        self.parts = [c for c in constraints if c is not None]
        self.max_tries = max(c.max_tries for c in self.parts)

    @property
    def offset(self) -> int:
        return self.parts[0].offset

    @offset.setter
    def offset(self, value: int) -> None:
        for c in self.parts:
            c.offset = value

    def accept(self, rows, frame, pos_m, next_pos_m, vel_mps=None) -> torch.Tensor:
        ok = self.parts[0].accept(rows, frame, pos_m, next_pos_m, vel_mps)
        for c in self.parts[1:]:
            ok = ok & c.accept(rows, frame, pos_m, next_pos_m, vel_mps)
        return ok

    def give_up(self, rows) -> None:
        for c in self.parts:
            c.give_up(rows)

    def project(self, pos_m, next_pos_m):
        for c in self.parts:
            if hasattr(c, "project"):
                next_pos_m = c.project(pos_m, next_pos_m)
        return next_pos_m
