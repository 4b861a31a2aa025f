"""Sampling constraints for rollouts: rejection of sampled frames (see `rollout.Constraint`).

`PhysicalLimits` keeps rollouts on the physically possible side of the two checks a learned
model breaks most: the ball going below the ground and the ball passing through the net. A
sampled frame that does either is drawn again from the same distribution (so the frame comes
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

BALL = 2
NET_STOP_M = 0.05               # a ball stopped by the net rests this far from its plane


class PhysicalLimits:
    """Reject a sampled frame whose ball is below the ground, or crossed the net's plane
    below the cord since the previous frame. Tolerances in metres."""

    def __init__(self, ground_tol_m: float = 0.02, net_tol_m: float = 0.02,
                 max_tries: int = 20):
        self.ground_tol_m = ground_tol_m
        self.net_tol_m = net_tol_m
        self.max_tries = max_tries
        self.offset = 0
        self.given_up = 0
        self.projected = 0

    def accept(self, rows: np.ndarray, frame: int, pos_m: torch.Tensor,
               next_pos_m: torch.Tensor) -> torch.Tensor:
        a, b = pos_m[:, BALL], next_pos_m[:, BALL]
        ok = b[:, 2] >= -self.ground_tol_m
        crossed = (a[:, 0] * b[:, 0]) < 0
        if bool(crossed.any()):
            frac = a[:, 0] / (a[:, 0] - b[:, 0] + 1e-12)
            y = a[:, 1] + frac * (b[:, 1] - a[:, 1])
            z = a[:, 2] + frac * (b[:, 2] - a[:, 2])
            sag = (torch.clamp(y.abs(), max=NET_POST_Y_M) / NET_POST_Y_M) ** 2
            cord = NET_HEIGHT_CENTRE_M + (NET_HEIGHT_POST_M - NET_HEIGHT_CENTRE_M) * sag
            ok &= ~crossed | (z >= cord - self.net_tol_m)
        return ok

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

    def accept(self, rows, frame, pos_m, next_pos_m) -> torch.Tensor:
        ok = self.parts[0].accept(rows, frame, pos_m, next_pos_m)
        for c in self.parts[1:]:
            ok = ok & c.accept(rows, frame, pos_m, next_pos_m)
        return ok

    def give_up(self, rows) -> None:
        for c in self.parts:
            c.give_up(rows)

    def project(self, pos_m, next_pos_m):
        for c in self.parts:
            if hasattr(c, "project"):
                next_pos_m = c.project(pos_m, next_pos_m)
        return next_pos_m
