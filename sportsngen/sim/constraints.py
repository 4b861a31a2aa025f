"""Sampling constraints for rollouts: rejection of sampled frames (see `frame_draws.Constraint`).

`PhysicalLimits` keeps rollouts on the physically possible side of the checks a learned model
breaks most: the ball going below the ground, the ball passing through the net and (with
`reach_m`) the ball struck back, or braked or turned in the air, with no player near it.
`StrikeInReach` adds the rule of the game the model breaks most: a player never lets a good
ball pass within his reach. A sampled frame that does any of these is drawn again from the
same distribution (so the frame comes from the model's distribution restricted to the
possible set, renormalised), up to `max_tries` times; the count of redraws is reported per
rally, and a rally whose frame could not be fixed is then corrected by the court's solid
objects (`PhysicalLimits.project`: the net stops the ball, the ground holds it) and the rules
judge it from there. This goes beyond the paper, which flags such rallies after the fact
(about 20 % of them); the unconstrained rate is one switch away
(`Simulator(physical_limits=False)`).
"""

from __future__ import annotations

import numpy as np
import torch

from sportsngen.model.centre import GRAVITY_MPS2, net_cord_m
from sportsngen.model.forecast import (
    HORIZON_S,
    PLAYABLE_Z_M,
    STEP_S,
    ball_forecast,
    forecast_rows,
    nearest_playable,
)
from sportsngen.model.packed import kernel_inputs
from sportsngen.sim import constraint_kernel
from sportsngen.tennis.court import (
    FENCE_X_M,
    FENCE_Y_M,
)
from sportsngen.tennis.rally import (
    CONTACT_MAX_Z_M,
    CONTACT_REACH_M,
    NET_ZONE_M,
    SHOT_MIN_VX_MPS,
    awaiting_return,
)

BALL = 2
NET_STOP_M = 0.05               # a ball stopped by the net rests this far from its plane
# A good ball this near a player (his centre to the ball, horizontally) and no higher is his to
# strike: the generator's players reach 1.7-1.95 m (`synth.profiles`); measured on its tracks
# in docs/evaluation.md (tenth part).
STRIKE_REACH_M = 1.2
STRIKE_MAX_Z_M = 2.3            # the generator's highest groundstroke contact (`synth.shot`)
# ... and a good ball falling below this within his reach has passed him: the generator's
# players strike no rally ball lower (0.16 m the lowest of 79,380 in `synthetic_named`, 0.1 %
# under 0.34 m), so one falling lower is on its way to a second bounce.
STRIKE_MIN_Z_M = PLAYABLE_Z_M[0]
# Optional (`behind_m`): one this far behind his centre (toward his back fence) has passed him;
# the generator's players strike rally balls at most 1.10 m behind their centre (99 % within
# 0.77 m; 2,078 strikes of Djokovic v Murray on clay). Measured not to help the checks
# (docs/evaluation.md, thirty-fourth part): off by default.
STRIKE_BEHIND_M = 1.1
# A ball in the air whose velocity changes by more than this in one frame has met something:
# on generated flights away from both players the change is 0.64 m/s a frame (median) and 3.1
# at the 99th percentile, a racket's tens. The rollouts' balls that braked in mid-air far from
# both players went from a median 23 m/s to 9 m/s in a frame (docs/evaluation.md,
# twenty-first part).
JOLT_MPS = 6.0
JOLT_MIN_Z_M = 0.1              # a flight that would come this low within the frame may bounce
# A bounce keeps 0.53-0.87 of the ball's speed along the ground (1st-99th percentiles over
# 17,571 bounces of generated points); less than this in one frame is not a bounce.
BOUNCE_MIN_KEEP = 0.45
# `KeepChasing`: a player this near the point where he could strike the ball has reached it
# (the generator's players strike 0.75-0.99 m from their centre, medians by shot), and one
# this fast is running flat out (the generator's fastest, 7-8 m/s).
CHASE_REACH_M = 1.0
# Where a player meets a ball whose bounce carries it above a racket (`KeepChasing.band_m`):
# the generator's players strike rally balls at 0.73-1.02 m and returns at 1.15-1.44 m (10th-
# 90th percentiles, Djokovic v Murray on clay, 1,500 points), about its comfortable 1.0 m.
HIGH_BALL_BAND_M = (0.5, 1.4)
CHASE_MAX_SPEED_MPS = 7.0
# ... and a late player's speed toward the ball rises at least this much a second (the
# generator's players accelerate at 5-6 m/s², `synth/data/profiles.json`).
CHASE_ACCEL_MPS2 = 6.0


def reverses(vx_in: torch.Tensor, vx_out: torch.Tensor) -> torch.Tensor:
    """(B,) bool: the ball's x velocity reverses, at least the rules' `SHOT_MIN_VX_MPS` each
    way (a racket sends it back)."""
    return (vx_in * vx_out < 0) & (vx_in.abs() > SHOT_MIN_VX_MPS) & \
        (vx_out.abs() > SHOT_MIN_VX_MPS)


def free_fall_z_m(ball_m: torch.Tensor, vel_mps: torch.Tensor, fps: float) -> torch.Tensor:
    """(B,) the height of balls at `ball_m` (B, 3) moving at `vel_mps` (B, 3) one frame on,
    falling freely (gravity alone: within a frame drag and lift move it by millimetres)."""
    dt = 1.0 / fps
    return ball_m[:, 2] + vel_mps[:, 2] * dt - 0.5 * GRAVITY_MPS2 * dt * dt


def ball_jolted(pos_m: torch.Tensor, next_pos_m: torch.Tensor, vel_mps: torch.Tensor,
                fps: float) -> torch.Tensor:
    """(B,) bool: inside the fences, the ball changes velocity by more than `JOLT_MPS` between
    `pos_m` and `next_pos_m` (B, 3, 3) where falling freely it would not come down to
    `JOLT_MIN_Z_M` (a bounce inside the frame is left alone), or at any height loses more of
    its speed along the ground than a bounce can (keeps less than `BOUNCE_MIN_KEEP` of it,
    from over `JOLT_MPS`). `PhysicalLimits.jolted`, `StrikeInReach.passes`."""
    ball, nxt = pos_m[:, BALL], next_pos_m[:, BALL]
    v_in = vel_mps[:, BALL]
    change = torch.linalg.vector_norm((nxt - ball) * fps - v_in, dim=-1)
    low = free_fall_z_m(ball, v_in, fps)
    inside = (ball[:, 0].abs() < FENCE_X_M - 1.0) & (ball[:, 1].abs() < FENCE_Y_M - 1.0)
    along_in = torch.linalg.vector_norm(v_in[:, :2], dim=-1)
    along_out = torch.linalg.vector_norm(nxt[:, :2] - ball[:, :2], dim=-1) * fps
    braked = (along_in > JOLT_MPS) & (along_out < BOUNCE_MIN_KEEP * along_in)
    in_air = (change > JOLT_MPS) & (low > JOLT_MIN_Z_M) & (ball[:, 2] > JOLT_MIN_Z_M)
    return (in_air | braked) & inside


def contact_reaches(tracker, rows, return_reach_m: float | None, rows_m: np.ndarray | None,
                    reach_m: float, rally_rows_m: np.ndarray | None = None) -> np.ndarray:
    """(rows,) the reach of each row's next contact: the return's where it is the return (each
    row's own in `rows_m` (B,), indexed like the tracker, else `return_reach_m`); else the
    rally ball's own where `rally_rows_m` (B, K) holds a reach per contact (contact k in column
    k mod K), `reach_m` where not."""
    rows = np.asarray(rows)
    n_shots = tracker.n_shots[rows]
    ret = rows_m[rows] if rows_m is not None else \
        (reach_m if return_reach_m is None else return_reach_m)
    rally = reach_m if rally_rows_m is None else \
        rally_rows_m[rows, np.asarray(n_shots) % rally_rows_m.shape[1]]
    return np.where(awaiting_return(n_shots), ret, rally)


def _per_row(value: np.ndarray | float, n: int) -> np.ndarray:
    """A reach (one value or one a row) as (n,) float64, the kernels' input."""
    return np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)))


class PhysicalLimits:
    """Reject a sampled frame whose ball is below the ground, or crossed the net's plane
    below the cord since the previous frame, or (`reach_m` not None) reverses along x, as a
    racket sends it back, or changes its velocity in the air as only something solid can
    (`jolted`), while no player is within `reach_m` of it (horizontally; the rally rules'
    reach by default) or it is higher than a racket reaches. A reversal at the net is left
    alone: the net sends balls back. Tolerances in metres.

    Why the reach: a model unsure on which frame a player strikes the ball spreads the
    contact over frames. A nucleus (top-p under 1) cuts a contact whose frame holds less than
    1 - top-p of the probability, and receivers let serves they reach fly past; drawn at the
    model's own odds instead (`contact_odds`), 22.5 % of a fine-tune's rallies had a ball
    struck back from 2.5 m or more away (docs/evaluation.md). Rejecting only the impossible
    contacts lets the possible ones happen at the model's rate.

    `return_reach_m` (with the rollout's rally `tracker`): the reach of the return, the contact
    after the serve (the tracker's `n_shots` is 1), where it is not `reach_m`. The generator's
    receivers return 0-17 % of the good serves that pass 1.5-1.8 m from them (they are late for
    a serve), its rally players 76-96 % of such rally balls; at one reach for both, a check's
    receivers returned half of those serves (docs/evaluation.md, thirty-fifth part)."""

    def __init__(self, ground_tol_m: float = 0.02, net_tol_m: float = 0.02,
                 max_tries: int = 20, reach_m: float | None = CONTACT_REACH_M,
                 fps: float = 25.0, tracker=None, return_reach_m: float | None = None):
        if return_reach_m is not None and (tracker is None or reach_m is None
                                           or not return_reach_m > 0):
            raise ValueError(f"return_reach_m needs a tracker and a reach_m and must be "
                             f"positive, got {return_reach_m}")
        self.ground_tol_m = ground_tol_m
        self.fps = float(fps)
        self.net_tol_m = net_tol_m
        self.reach_m = reach_m
        self.tracker = tracker
        self.return_reach_m = None if return_reach_m is None else float(return_reach_m)
        # (B,) per rollout row, where each serve draws its receiver's own (`sim.reach_table`;
        # set with a tracker): replaces `return_reach_m`; and (B, K) a reach per rally ball
        # (`contact_reaches`), drawn from the player due's row: replaces `reach_m` there.
        self.return_reach_rows_m: np.ndarray | None = None
        self.rally_reach_rows_m: np.ndarray | None = None
        self.max_tries = max_tries
        self.offset = 0
        self.given_up = 0
        self.projected = 0

    def accept(self, rows: np.ndarray, frame: int, pos_m: torch.Tensor,
               next_pos_m: torch.Tensor, vel_mps: torch.Tensor | None = None) -> torch.Tensor:
        if kernel_inputs(pos_m, next_pos_m, vel_mps):
            check = self.reach_m is not None and vel_mps is not None
            out = np.empty(len(pos_m), dtype=np.bool_)
            constraint_kernel.physical_rows(
                pos_m.numpy(), next_pos_m.numpy(), (pos_m if vel_mps is None else vel_mps).numpy(),
                _per_row(self._reach_rows(rows) if check else 0.0, len(pos_m)), check,
                self.ground_tol_m, self.net_tol_m, self.fps, JOLT_MPS, JOLT_MIN_Z_M,
                BOUNCE_MIN_KEEP, out)
            return torch.from_numpy(out)
        a, b = pos_m[:, BALL], next_pos_m[:, BALL]
        ok = b[:, 2] >= -self.ground_tol_m
        if self.reach_m is not None and vel_mps is not None:
            ok &= ~self.struck_out_of_reach(pos_m, next_pos_m, vel_mps, self._reach(rows, b))
        crossed = (a[:, 0] * b[:, 0]) < 0
        if bool(crossed.any()):
            frac = a[:, 0] / (a[:, 0] - b[:, 0] + 1e-12)
            y = a[:, 1] + frac * (b[:, 1] - a[:, 1])
            z = a[:, 2] + frac * (b[:, 2] - a[:, 2])
            ok &= ~crossed | (z >= net_cord_m(y) - self.net_tol_m)
        return ok

    def _reach_rows(self, rows: np.ndarray) -> np.ndarray | float:
        """The reach of each row's next contact (`contact_reaches`), one value where all
        rows share it."""
        if self.return_reach_m is None and self.return_reach_rows_m is None \
                and self.rally_reach_rows_m is None:
            return self.reach_m
        return contact_reaches(self.tracker, rows, self.return_reach_m,
                               self.return_reach_rows_m, self.reach_m, self.rally_reach_rows_m)

    def _reach(self, rows: np.ndarray, ball: torch.Tensor) -> torch.Tensor | float:
        reach = self._reach_rows(rows)
        return reach if isinstance(reach, float) else \
            torch.as_tensor(reach, device=ball.device, dtype=ball.dtype)

    def struck_out_of_reach(self, pos_m: torch.Tensor, next_pos_m: torch.Tensor,
                            vel_mps: torch.Tensor,
                            reach_m: torch.Tensor | float | None = None) -> torch.Tensor:
        """(B,) bool: away from the net, with no player within `reach_m` of the ball (default
        the constraint's; a tensor (B,) per row) or the ball above `CONTACT_MAX_Z_M`, the
        sampled frame reverses the ball along x (each way at least the rules'
        `SHOT_MIN_VX_MPS`) or, in the air, changes its velocity as only something solid can
        (`jolted`)."""
        reach_m = self.reach_m if reach_m is None else reach_m
        ball = pos_m[:, BALL]
        vx_in = vel_mps[:, BALL, 0]
        vx_out = (next_pos_m[:, BALL, 0] - ball[:, 0]) * self.fps
        reverse = reverses(vx_in, vx_out) | self.jolted(pos_m, next_pos_m, vel_mps)
        gap = torch.linalg.vector_norm(pos_m[:, :BALL, :2] - ball[:, None, :2], dim=-1)
        near = (gap.min(dim=1).values <= reach_m) & (ball[:, 2] <= CONTACT_MAX_Z_M)
        return reverse & ~near & (ball[:, 0].abs() >= NET_ZONE_M)

    def jolted(self, pos_m: torch.Tensor, next_pos_m: torch.Tensor,
               vel_mps: torch.Tensor) -> torch.Tensor:
        """(B,) bool: inside the fences, the ball changes velocity by more than `JOLT_MPS`
        in the sampled frame where falling freely it would not come down to `JOLT_MIN_Z_M`
        (a bounce inside the frame is left alone), or at any height loses more of its speed
        along the ground than a bounce can (keeps less than `BOUNCE_MIN_KEEP` of it, from
        over `JOLT_MPS`).

        Why: the model's contact region (a first-axis offset of more than half a metre) was
        drawn where no player could strike; the reversals were rejected, and among the
        redraws the contacts that only slowed the ball passed, so 15 % of a check's rallies
        had a ball braking in mid-air (a serve 40 m/s to 13 m/s past the net, then landing
        2.6 m short of where it was served to)."""
        return ball_jolted(pos_m, next_pos_m, vel_mps, self.fps)

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
        stop = crossed & (z < net_cord_m(y) - self.net_tol_m)
        b[stop, 0] = torch.sign(a[stop, 0]) * NET_STOP_M
        b[stop, 1] = y[stop]
        b[stop, 2] = z[stop].clamp(min=0.0)
        b[:, 2] = b[:, 2].clamp(min=0.0)
        self.projected += int(stop.sum())
        return out


class StrikeInReach:
    """Reject a sampled frame in which a good ball leaves the reach of the player due to strike
    it, unstruck: the ball has bounced once inside his court (the rally tracker's state), is
    within `reach_m` of him (horizontally) and no higher than `max_z_m` now, and in the sampled
    frame it is horizontally out of that reach, or falls below a racket (`min_z_m`), without
    being sent back (`passes`). The frame is drawn again from the model's distribution, so the
    player strikes (or keeps the ball in reach) as the model would, given that he does; after
    `max_tries` the pass stands.

    Why: real players, and the generator's, play every good ball they can reach. Teacher-forced
    on recorded states, the model gives a contact 0.66-0.75 of the time over an approach
    (`sportsngen.eval.diagnostics`), and in rollouts a server lets 10 % of the returns that
    pass him fly by (the branch third-shot share, 0.90 against the data's 0.98), which is most
    of what the simulated servers lose (docs/evaluation.md, tenth part). The rule removes a
    decision the game does not leave open and leaves the shot itself to the model.

    `tracker`: the rollout's `RallyTracker`, indexed like the rollout's rows (`rows` of
    `accept`); it has seen every frame up to the current one. `from_shot`: the first contact
    the rule asks for, counted from the serve (0): 1 the return, 2 the server's first rally
    ball. From the return it took the model's aces below the truth's; from shot 2 it leaves
    the serve and the return to the model and makes the servers' failures at rally lengths 2,
    4 and 6 the truth's (docs/evaluation.md, eleventh part).

    `return_reach_m`: the reach for the return (the contact after the serve), where it is not
    `reach_m`: the generator's receivers return 87-93 % of the good serves that pass 1.2-1.5 m
    from them, all nearer ones (docs/evaluation.md, thirty-fifth part).

    `force`: where the rule gives up (no draw in `2 * max_tries` keeps the ball in reach or
    strikes it), the ball is struck anyway from where it is, by the model's strike head
    (`strike_rows` names the rows; the rollout places the strike). Without it the pass stands:
    the rule gave up 17 times in 200 points of the bundled file (docs/evaluation.md,
    seventeenth part)."""

    def __init__(self, tracker, reach_m: float = STRIKE_REACH_M, max_z_m: float = STRIKE_MAX_Z_M,
                 max_tries: int = 20, fps: float = 25.0, from_shot: int = 1,
                 force: bool = False, min_z_m: float | None = STRIKE_MIN_Z_M,
                 behind_m: float | None = None, return_reach_m: float | None = None):
        if not reach_m > 0 or not max_z_m > 0:
            raise ValueError(f"reach_m and max_z_m must be positive, got {reach_m}, {max_z_m}")
        if min_z_m is not None and not 0 <= min_z_m < max_z_m:
            raise ValueError(f"min_z_m must lie in [0, max_z_m), got {min_z_m}")
        if behind_m is not None and not behind_m > 0:
            raise ValueError(f"behind_m must be positive, got {behind_m}")
        self.min_z_m = None if min_z_m is None else float(min_z_m)
        self.behind_m = None if behind_m is None else float(behind_m)
        if int(from_shot) < 1:
            raise ValueError(f"from_shot counts contacts after the serve (>= 1), got {from_shot}")
        self.from_shot = int(from_shot)
        self.tracker = tracker
        self.reach_m = float(reach_m)
        if return_reach_m is not None and not return_reach_m > 0:
            raise ValueError(f"return_reach_m must be positive, got {return_reach_m}")
        self.return_reach_m = None if return_reach_m is None else float(return_reach_m)
        # (B,) and (B, K) per rollout row, as `PhysicalLimits`' rows.
        self.return_reach_rows_m: np.ndarray | None = None
        self.rally_reach_rows_m: np.ndarray | None = None
        self.max_z_m = float(max_z_m)
        self.max_tries = max_tries
        self.fps = float(fps)
        self.offset = 0
        self.given_up = 0
        self.force = bool(force)

    def due(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(rows,) bool: the ball of these rallies has had its good bounce and is still to be
        struck; and the role (0 server, 1 receiver) of the player due to strike it."""
        t = self.tracker
        due = ~t.ended[rows] & (t.hitter[rows] >= 0) & (t.n_bounces[rows] == 1) & \
            (t.n_shots[rows] >= self.from_shot)
        return due, 1 - np.clip(t.hitter[rows], 0, 1)

    def accept(self, rows: np.ndarray, frame: int, pos_m: torch.Tensor,
               next_pos_m: torch.Tensor, vel_mps: torch.Tensor | None = None) -> torch.Tensor:
        rows = np.asarray(rows)
        due, role = self.due(rows)
        if not due.any():
            return torch.ones(len(rows), dtype=torch.bool, device=pos_m.device)
        end = np.where(role == 0, 1, -1) * self.tracker.server_end[rows]
        dev = pos_m.device
        reach = None
        if self.return_reach_m is not None or self.return_reach_rows_m is not None \
                or self.rally_reach_rows_m is not None:
            reach = torch.as_tensor(contact_reaches(self.tracker, rows, self.return_reach_m,
                                                    self.return_reach_rows_m, self.reach_m,
                                                    self.rally_reach_rows_m),
                                    device=dev, dtype=pos_m.dtype)
        return ~(torch.as_tensor(due, device=dev) & self.passes(
            pos_m, next_pos_m, torch.as_tensor(role, device=dev),
            torch.as_tensor(end, device=dev, dtype=pos_m.dtype), vel_mps, reach))

    def passes(self, pos_m: torch.Tensor, next_pos_m: torch.Tensor, role: torch.Tensor,
               end: torch.Tensor, vel_mps: torch.Tensor | None = None,
               reach_m: torch.Tensor | None = None) -> torch.Tensor:
        """(B,) bool: between `pos_m` and `next_pos_m` (B, 3, 3) the ball leaves the reach of
        player `role` (B,), whose baseline is at sign `end` (B,) of x, without being sent back
        toward the net, or (given the velocities `vel_mps`) is jolted in his reach without
        being sent back (`ball_jolted`: braked in mid-air beside him, a ball then left hanging
        within his reach until the rally's end rules called it an ace; docs/evaluation.md,
        twenty-sixth part), or (`min_z_m` not None) falls below `min_z_m` within his reach,
        in the sampled frame or, given the velocities, by its free fall within the frame: a
        ball he lets drop that low has passed him as surely as one that left his reach (such
        balls, slowed by the clay and falling beside the server for a second bounce, were 96
        of the 248 good balls left unanswered in a 500-point check; docs/evaluation.md,
        thirty-fourth part), or (`behind_m` not None) is further than `behind_m` behind him
        (toward his back fence) in the sampled frame. Within reach: horizontally within
        `reach_m` and no higher than `max_z_m`; leaving: horizontally beyond `reach_m` in the
        sampled frame (a ball rising above a racket is left to come down). `reach_m` (B,): each
        row's reach where it is not the rule's."""
        reach = self.reach_m if reach_m is None else reach_m
        if kernel_inputs(pos_m, next_pos_m, vel_mps, reach_m):
            out = np.empty(len(pos_m), dtype=np.bool_)
            nan = float("nan")
            constraint_kernel.passes_rows(
                pos_m.numpy(), next_pos_m.numpy(), (pos_m if vel_mps is None else vel_mps).numpy(),
                vel_mps is not None, role.numpy(), end.double().numpy(),
                _per_row(reach.numpy() if isinstance(reach, torch.Tensor) else reach,
                         len(pos_m)), self.max_z_m, nan if self.min_z_m is None else self.min_z_m,
                nan if self.behind_m is None else self.behind_m, self.fps, JOLT_MPS,
                JOLT_MIN_Z_M, BOUNCE_MIN_KEEP, out)
            return torch.from_numpy(out)
        i = torch.arange(len(pos_m), device=pos_m.device)
        ball0, ball1 = pos_m[:, BALL], next_pos_m[:, BALL]
        gap0 = torch.linalg.vector_norm(ball0[:, :2] - pos_m[i, role, :2], dim=-1)
        gap1 = torch.linalg.vector_norm(ball1[:, :2] - next_pos_m[i, role, :2], dim=-1)
        inside = (gap0 <= reach) & (ball0[:, 2] <= self.max_z_m)
        sent_back = (ball1[:, 0] - ball0[:, 0]) * self.fps * end < -SHOT_MIN_VX_MPS
        leaves = gap1 > reach
        if vel_mps is not None:
            leaves = leaves | ball_jolted(pos_m, next_pos_m, vel_mps, self.fps)
        if self.min_z_m is not None:
            # Falling, not rising from its first bounce (the tracker counts a bounce only once
            # the ball has risen from it).
            drops = (ball1[:, 2] < self.min_z_m) & (ball1[:, 2] < ball0[:, 2])
            if vel_mps is not None:
                drops = drops | ((vel_mps[:, BALL, 2] < 0) &
                                 (free_fall_z_m(ball0, vel_mps[:, BALL], self.fps) < self.min_z_m))
            leaves = leaves | drops
        if self.behind_m is not None:
            behind = (ball1[:, 0] - next_pos_m[i, role, 0]) * end > self.behind_m
            leaves = leaves | behind
        return inside & leaves & ~sent_back

    def give_up(self, rows: np.ndarray) -> None:
        self.given_up += len(rows)

    def strike_rows(self, rows: np.ndarray) -> np.ndarray:
        """(rows,) bool: of the rows this rule gave up on (`give_up`'s), those whose ball is to
        be struck anyway: all of them with `force`."""
        return np.full(len(rows), self.force, dtype=bool)


class KeepChasing:
    """Reject a sampled frame in which the player due to play the ball does not run toward it
    while he is late for it: after his reaction time (`react_frames` from the last contact) he
    reads the ball's flight (`model.forecast`: gravity, drag, the spin read from its last three
    frames), finds the point nearest him where he could strike it
    (`forecast.nearest_playable`: his side, flying toward his end, a playable height) and how
    long it takes to get there; he is late when, beyond `reach_m` of it, at his speed toward
    it he would not cover the distance in that time. Then a frame whose speed toward it is
    below the least allowed is drawn again from the model's distribution, so how he runs
    stays the model's: the least is his speed (he does not slow down) and, for a ball struck
    at contact `accel_from_shot` or later (2: the server's first rally ball on; the serve's
    chase is left at that), that speed raised by `accel_mps2` for a frame, never above what
    he needs or `max_speed_mps`. After `max_tries` draws of a row in a frame, with `hold` the
    frame's step of the late player is lengthened along his way to the ball to that least
    speed (the step across it stays the model's); without, the frame stands. `band_m` (low,
    high): for a flight whose bounce carries the ball above a racket (`STRIKE_MAX_Z_M`), his
    ball is the point after the bounce nearest him within that height band, where the flight
    has one (`HIGH_BALL_BAND_M` for the simulator's `chase_high_balls`).

    Why: fed the ball the record played (`eval.chase`), the bundled model's players ran the
    first 0.8-1 s of a long chase as the record's did and then slowed, as players on shorter
    runs do: beyond 1.5 m of 21-24 % of the balls that sent the record's player 3 m or more,
    and of 11.9 % of all rally balls, where the record's missed 1.0 %. Teacher-forced on the
    record's own runs it brakes barely more than the record (0.01-0.03 m/s a frame); the
    rollout compounds it. A player who sees he will not get there does not brake, whatever he
    did in frames before, and one who has not yet started runs; the rule leaves the when and
    where of his strike to the model. Redraws alone (at most 3 a frame, else a batch waits on
    the one player the model insists on braking) left 10.8 % of those balls beyond 1.5 m;
    holding the speed after them 7.3 %, also raising it by 6 m/s² from the server's first
    rally ball (the generator's players' acceleration) 4.9 %; raised for the serve too, the
    receivers ran after serves they could not return, which the leak check reads
    (docs/evaluation.md, twenty-eighth part). The nearest playable point of a ball rising from
    the clay above a racket is its rise beside him, so he was never late for it and let it pass
    over him: on clay 0.156 of the model's slow balls went unanswered against the truth's 0.016;
    run to its comfortable height after the bounce, 0.101 (thirty-ninth part)."""

    def __init__(self, tracker, reach_m: float = CHASE_REACH_M, react_frames: int = 5,
                 max_speed_mps: float = CHASE_MAX_SPEED_MPS, max_tries: int = 3,
                 fps: float = 25.0, hold: bool = True,
                 accel_mps2: float = CHASE_ACCEL_MPS2, accel_from_shot: int = 2,
                 band_m: tuple[float, float] | None = None):
        if band_m is not None and not PLAYABLE_Z_M[0] <= band_m[0] < band_m[1]:
            raise ValueError(f"band_m must be (low, high) with {PLAYABLE_Z_M[0]} <= low < high, "
                             f"got {band_m}")
        if not reach_m > 0 or not max_speed_mps > 0 or int(react_frames) < 0 or accel_mps2 < 0:
            raise ValueError(f"reach_m and max_speed_mps must be positive and react_frames "
                             f"and accel_mps2 >= 0, got {reach_m}, {max_speed_mps}, "
                             f"{react_frames}, {accel_mps2}")
        self.tracker = tracker
        self.reach_m = float(reach_m)
        self.react_frames = int(react_frames)
        self.max_speed_mps = float(max_speed_mps)
        self.max_tries = max_tries
        self.fps = float(fps)
        self.hold = bool(hold)
        self.accel_mps2 = float(accel_mps2)
        self.accel_from_shot = int(accel_from_shot)
        self.band_m = None if band_m is None else (float(band_m[0]), float(band_m[1]))
        self.offset = 0
        self.given_up = 0
        self.held = 0
        # (B, 2) per rollout row the server's and the receiver's top speed (`sim.top_speed`),
        # where the simulator reads them: a late player is not asked beyond his own.
        self.max_speed_rows_mps: np.ndarray | None = None
        # Per frame, by the rollout's row: where a row sits in the frame's first reading (-1:
        # not read) and how often it has been judged.
        n = len(tracker.ended)
        self._frame: int | None = None
        self._at = np.full(n, -1, dtype=np.int64)
        self._late: tuple = ()
        self._tries = np.zeros(n, dtype=np.int64)

    def late(self, rows: np.ndarray, pos_m: torch.Tensor, vel_mps: torch.Tensor,
             frame: int | None = None):
        """-> (B,) bool late rows, (B,) role of the player due, (B, 2) unit direction to his
        nearest playable ball, (B,) his speed along it (m/s), (B,) the least speed along it a
        late player's next frame may have (m/s): his speed, raised by `accel_mps2` for a frame
        short of what he needs, never above his cap, and (B,) that cap: `max_speed_mps`, or his
        own top speed where lower (`max_speed_rows_mps`). With `frame`, read once a frame:
        the redraws of a frame ask again for some of its rows, in the same state."""
        rows = np.asarray(rows)
        fast = kernel_inputs(pos_m, vel_mps)
        if frame is not None and self._frame == frame and (self._at[rows] >= 0).all():
            at = self._at[rows]
            if fast:
                return tuple(torch.from_numpy(x.numpy()[at]) for x in self._late)
            i = torch.as_tensor(at, device=pos_m.device)
            return tuple(x[i] for x in self._late)
        if fast:
            return self._remember(frame, rows, self._late_compiled(rows, pos_m, vel_mps))
        t = self.tracker
        dev, dtype = pos_m.device, pos_m.dtype
        due, role, cap = self._due(rows)
        role = torch.as_tensor(role, device=dev)
        cap = torch.as_tensor(cap, dtype=dtype, device=dev)
        late = torch.zeros(len(rows), dtype=torch.bool, device=dev)
        unit = torch.zeros(len(rows), 2, dtype=dtype, device=dev)
        along = torch.zeros(len(rows), dtype=dtype, device=dev)
        least = torch.zeros(len(rows), dtype=dtype, device=dev)
        if due.any():
            i = torch.as_tensor(np.flatnonzero(due), device=dev)
            recent = torch.as_tensor(t.recent_frames(rows[due]), dtype=dtype, device=dev)
            prev_vel = (recent[:, -2, BALL] - recent[:, -3, BALL]) * self.fps
            columns, track = ball_forecast(pos_m[i, BALL], vel_mps[i, BALL], prev_vel,
                                           self.fps, path=True)
            me = pos_m[i, role[i], :2]
            near = nearest_playable(track, me[:, None])[:, 0]          # (n, 3)
            if self.band_m is not None:
                bounced = torch.as_tensor(t.n_bounces[rows[due]] >= 1, device=dev)
                near = self._high_ball_target(track, columns[:, -1], me, near, bounced)
            dist = torch.linalg.vector_norm(near[:, :2], dim=-1)
            u = near[:, :2] / dist.clamp_min(1e-6)[:, None]
            v_along = (vel_mps[i, role[i], :2] * u).sum(-1)
            need = dist - self.reach_m
            late[i] = (near[:, 2] > 0) & (need > 0) & (v_along * near[:, 2] < need)
            unit[i], along[i] = u, v_along
            wanted = need / near[:, 2].clamp_min(1e-3)
            shot = torch.as_tensor(t.n_shots[rows[due]], device=dev)
            accel = torch.where(shot >= self.accel_from_shot, self.accel_mps2, 0.0)
            # A late player is slower than he needs (v_along < wanted), so this is never
            # below his speed but where he already runs flat out, which the rule leaves.
            least[i] = torch.minimum(torch.minimum(v_along + accel / self.fps, wanted), cap[i])
        return self._remember(frame, rows, (late, role, unit, along, least, cap))

    def _remember(self, frame: int | None, rows: np.ndarray, out: tuple) -> tuple:
        """`late`'s reading `out` of `rows`, kept for the frame's redraws (with `frame`)."""
        if frame is not None:
            self._frame, self._late = frame, out
            self._at[:] = -1
            self._at[rows] = np.arange(len(rows))
            self._tries[:] = 0
        return out

    def _due(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rows,) bool: the ball is his to chase and he has had his reaction time; (rows,) the
        role of the player due; (rows,) float64 his speed cap (`max_speed_mps`, or his own
        top speed where lower). Rounded once to a reading's dtype, as a float32 cap is."""
        t = self.tracker
        hitter = t.hitter[rows]
        due = ~t.ended[rows] & (hitter >= 0) & (t.n_bounces[rows] <= 1) & \
            (t.frames_since_contact(rows) >= self.react_frames)
        role = 1 - np.clip(hitter, 0, 1)
        cap = np.full(len(rows), self.max_speed_mps)
        if self.max_speed_rows_mps is not None:
            cap = np.minimum(cap, self.max_speed_rows_mps[rows, role])
        return due, role, cap

    def _late_compiled(self, rows: np.ndarray, pos_m: torch.Tensor,
                       vel_mps: torch.Tensor) -> tuple:
        """`late`'s reading in numpy, its flights by `forecast_rows` and the players' by
        `constraint_kernel.chase_rows` (the torch operations in `late` are its reference):
        the same values, as CPU tensors over numpy arrays (a frame's torch operations on
        one row were most of the rule's cost)."""
        t = self.tracker
        n = len(rows)
        due, role, cap = self._due(rows)
        cap = cap.astype(np.float32)
        late = np.zeros(n, dtype=bool)
        unit = np.zeros((n, 2), dtype=np.float32)
        along = np.zeros(n, dtype=np.float32)
        least = np.zeros(n, dtype=np.float32)
        if due.any():
            i = np.flatnonzero(due)
            recent = t.recent_frames(rows[i])
            prev_vel = ((recent[:, -2, BALL] - recent[:, -3, BALL]) * self.fps).astype(
                np.float32)
            pos, vel = pos_m.numpy(), vel_mps.numpy()
            columns, track = forecast_rows(np.ascontiguousarray(pos[i, BALL]),
                                           np.ascontiguousarray(vel[i, BALL]), prev_vel,
                                           self.fps, path=True)
            who = role[i]
            accel = np.where(t.n_shots[rows[i]] >= self.accel_from_shot, self.accel_mps2, 0.0)
            lo, hi = (np.nan, np.nan) if self.band_m is None else self.band_m
            out_late, out_unit = np.empty(len(i), dtype=np.bool_), np.empty((len(i), 2))
            out_along, out_least = np.empty(len(i)), np.empty(len(i))
            constraint_kernel.chase_rows(
                track, columns[:, -1].astype(np.float64), pos[i, who, :2].astype(np.float64),
                vel[i, who, :2].astype(np.float64), t.n_bounces[rows[i]] >= 1, lo, hi,
                PLAYABLE_Z_M[0], PLAYABLE_Z_M[1], STEP_S, HORIZON_S, STRIKE_MAX_Z_M,
                self.reach_m, self.fps, accel, cap[i].astype(np.float64), out_late, out_unit,
                out_along, out_least)
            late[i], unit[i], along[i], least[i] = out_late, out_unit, out_along, out_least
        return tuple(torch.from_numpy(x) for x in (late, role, unit, along, least, cap))

    def _high_ball_target(self, track: torch.Tensor, bounce_s: torch.Tensor, me: torch.Tensor,
                          near: torch.Tensor, bounced: torch.Tensor) -> torch.Tensor:
        """`near` (n, 3), but for flights (n, N, 3) whose bounce carries the ball above a
        racket (`STRIKE_MAX_Z_M`): the point after the bounce nearest the player `me` (n, 2)
        where it is within `band_m`, where there is one. `bounce_s` (n,): the forecast's time
        of the next bounce (`ball_forecast`'s last column; its horizon where none is found);
        `bounced` (n,) bool: the ball has bounced already (the whole flight is after it)."""
        row_s = (torch.arange(track.shape[-2], device=track.device, dtype=track.dtype) + 1) * STEP_S
        after = (row_s[None] > bounce_s[:, None]) & (bounce_s[:, None] < HORIZON_S)
        after = after | bounced[:, None]
        z = torch.where(after, track[..., 2], -1.0)     # before the bounce: not his ball
        high = (z > STRIKE_MAX_Z_M).any(-1)
        if not bool(high.any()):                          # most frames: no high bounce
            return near
        post = torch.cat([track[..., :2], z[..., None]], dim=-1)
        band = nearest_playable(post, me[:, None], self.band_m)[:, 0]
        return torch.where((high & (band[:, 2] > 0))[:, None], band, near)

    def accept(self, rows: np.ndarray, frame: int, pos_m: torch.Tensor,
               next_pos_m: torch.Tensor, vel_mps: torch.Tensor | None = None) -> torch.Tensor:
        rows = np.asarray(rows)
        ok = torch.ones(len(rows), dtype=torch.bool, device=pos_m.device)
        if vel_mps is None or not len(rows):
            if vel_mps is None:
                self._frame = None               # nothing read: nothing for `settle` to hold
            return ok
        late, role, unit, along, least, cap = self.late(rows, pos_m, vel_mps, frame)
        if not late.any():
            return ok
        # Each row is judged at most `max_tries` times a frame: the rollout keeps redrawing
        # while any row of the batch is rejected, up to twice the largest `max_tries` of its
        # constraints, and one player the model insists on braking held a whole batch of
        # rollouts there (four times slower).
        fresh = self._tries[rows] < self.max_tries
        self._tries[rows] += 1
        if kernel_inputs(pos_m, next_pos_m, vel_mps):
            # The torch lines below in numpy: the same float32 operations, a tenth the cost.
            i, who = np.arange(len(rows)), role.numpy()
            step = (next_pos_m.numpy()[i, who, :2] - pos_m.numpy()[i, who, :2]) * unit.numpy()
            speed = (step[:, 0] + step[:, 1]) * np.float32(self.fps)
            slows = (speed < least.numpy()) & (along.numpy() < cap.numpy())
            return torch.from_numpy(~(late.numpy() & slows & fresh))
        slows = (self._speed_along(pos_m, next_pos_m, role, unit) < least) & (along < cap)
        return ~(late & slows & torch.as_tensor(fresh, device=pos_m.device))

    def _speed_along(self, pos_m, next_pos_m, role, unit) -> torch.Tensor:
        """(B,) the player due's speed in the sampled frame along his way to the ball (m/s)."""
        i = torch.arange(len(role), device=pos_m.device)
        return ((next_pos_m[i, role, :2] - pos_m[i, role, :2]) * unit).sum(-1) * self.fps

    def give_up(self, rows: np.ndarray) -> None:
        self.given_up += len(rows)

    def settle(self, rows: np.ndarray, pos_m: torch.Tensor,
               next_pos_m: torch.Tensor) -> torch.Tensor:
        """With `hold`, the frame's final draw: a late player still below the least speed
        toward the ball (`late`) has his step along his way to it lengthened to that speed
        (never shortened), from this frame's reading; `held` counts them. Rows this frame did
        not read, or read as not late, are left alone."""
        if not self.hold or not len(rows) or self._frame is None or \
                not bool(self._late[0].any()):               # most frames: nobody late
            return next_pos_m
        rows = np.asarray(rows)
        at = self._at[rows]
        read = torch.as_tensor(at >= 0, device=pos_m.device)
        if not bool(read.any()):
            return next_pos_m
        i = torch.as_tensor(np.where(at >= 0, at, 0), device=pos_m.device)
        late, role, unit, along, least, cap = (x[i] for x in self._late)
        short_mps = least - self._speed_along(pos_m, next_pos_m, role, unit)
        fix = read & late & (short_mps > 0) & (along < cap)
        if not bool(fix.any()):
            return next_pos_m
        out = next_pos_m.clone()
        j = torch.nonzero(fix).squeeze(1)
        out[j, role[j], :2] += unit[j] * (short_mps[j] / self.fps)[:, None]
        self.held += int(fix.sum())
        return out


class AllOf:
    """Several constraints at once: a frame must satisfy all of them. When the rollout gives
    up on rows, each part is told only the rows it rejected on their last draw.

    Each part keeps its own number of tries: a rejection asks for a redraw (`asks`) only while
    the row has been judged at most `2 * max_tries` times in the frame, so it is drawn again at
    most `2 * max_tries` times as under that part alone; past it the part's rejection stands
    until the rollout gives up on the row (a forced strike, say). Without this a
    counterfactual's shot constraint (200 tries) gave every rule its 200: the rule for balls in
    reach rejected 44,359 draws of a 2 x 100 counterfactual where a win probability's rollouts
    see 2,051 (docs/evaluation.md, session s104)."""

    def __init__(self, *constraints):
        self.parts = [c for c in constraints if c is not None]
        self.max_tries = max(c.max_tries for c in self.parts)
        self._frame: int | None = None
        self._judged = np.zeros(0, dtype=np.int64)   # by row: judgements in `_frame`
        # (parts, rows): the part rejected the row's last draw in `_frame`.
        self._rejected = np.ones((len(self.parts), 0), dtype=bool)
        self.asks = np.zeros(0, dtype=bool)          # the last judged rows a part redraws
        self.judges_strikes = any(getattr(c, "judges_strikes", False) for c in self.parts)

    @property
    def offset(self) -> int:
        return self.parts[0].offset

    @offset.setter
    def offset(self, value: int) -> None:
        for c in self.parts:
            c.offset = value

    def accept(self, rows, frame, pos_m, next_pos_m, vel_mps=None) -> torch.Tensor:
        oks = [c.accept(rows, frame, pos_m, next_pos_m, vel_mps) for c in self.parts]
        rows = np.asarray(rows, dtype=np.int64)
        ok = oks[0]
        for o in oks[1:]:
            ok = ok & o
        # Each part's last verdict on each row of the frame, for `give_up`: a row whose
        # rejecting parts are spent is not drawn again, so it may not be in the last draw.
        if frame != self._frame:
            self._judged[:] = 0
            self._rejected[:] = True
            self._frame = frame
        if len(rows) and rows.max() >= len(self._judged):
            more = int(rows.max()) + 1 - len(self._judged)
            self._judged = np.concatenate([self._judged, np.zeros(more, dtype=np.int64)])
            self._rejected = np.concatenate(
                [self._rejected, np.ones((len(self.parts), more), dtype=bool)], axis=1)
        self._judged[rows] += 1
        self.asks = ~ok.cpu().numpy()
        if not self.asks.any():                  # most judgements: nothing rejected
            self._rejected[:, rows] = False
            return ok
        judged = self._judged[rows]
        self.asks[:] = False
        for i, (c, o) in enumerate(zip(self.parts, oks)):
            no = ~o.cpu().numpy()
            self._rejected[i, rows] = no
            self.asks |= no & (judged <= 2 * c.max_tries)
        return ok

    def judge_strikes(self, rows, frame, pos_m, land_xy, serve) -> np.ndarray:
        """(R,) bool: every part that judges the heads' strikes lets each stand."""
        ok = np.ones(len(rows), dtype=bool)
        for c in self.parts:
            if getattr(c, "judges_strikes", False):
                ok &= c.judge_strikes(rows, frame, pos_m, land_xy, serve)
        return ok

    def _rejected_by(self, rows: np.ndarray) -> list[np.ndarray]:
        """Per part, (rows,) bool: it rejected the row's last draw in this frame (every part,
        for a row this object has not judged in it)."""
        if len(rows) and rows.max() >= self._rejected.shape[1]:
            return [np.ones(len(rows), dtype=bool) for _ in self.parts]
        return [r[rows] for r in self._rejected]

    def give_up(self, rows) -> None:
        rows = np.asarray(rows, dtype=np.int64)
        for c, mine in zip(self.parts, self._rejected_by(rows)):
            if mine.any():
                c.give_up(rows[mine])

    def strike_rows(self, rows) -> np.ndarray:
        """(rows,) bool: rows given up on whose ball a part that rejected it wants struck."""
        rows = np.asarray(rows, dtype=np.int64)
        out = np.zeros(len(rows), dtype=bool)
        for c, mine in zip(self.parts, self._rejected_by(rows)):
            if hasattr(c, "strike_rows") and mine.any():
                out[mine] |= c.strike_rows(rows[mine])
        return out

    def project(self, pos_m, next_pos_m):
        for c in self.parts:
            if hasattr(c, "project"):
                next_pos_m = c.project(pos_m, next_pos_m)
        return next_pos_m

    def settle(self, rows, pos_m, next_pos_m):
        for c in self.parts:
            if hasattr(c, "settle"):
                next_pos_m = c.settle(rows, pos_m, next_pos_m)
        return next_pos_m
