"""One rally of the synthetic generator: the players' profiles and behaviour as a policy of the
shot-cycle kernel (`synth.cycle`).

The kernel flies the ball and moves the players; this module decides for them: the serve
(`behaviour.plan_serve`), where each player recovers, how he reacts (his reaction time; on a
serve, less the returner's anticipation, plus the server's disguise), the spot beside the ball he
runs to (a lateral distance drawn per shot from `CONTACT_LATERAL_RANGE_M`), and the shot he makes
there (`behaviour.plan_rally_shot`), whose execution noise grows with how hard the incoming ball
was to play (`_difficulty`: the serve's heaviness, rally pressure and initiative).

Draws that shape the tracks but not the play (the contact's lateral distance, choices for balls
the kernel already knows are out) come from a side stream keyed on the play's stream, so every
outcome draw stays where it was.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from sportsngen.synth import behaviour as bh
from sportsngen.synth import cycle
from sportsngen.synth.cycle import (  # noqa: F401  (re-exported: what a rally is made of)
    AFTER_END_S,
    Body,
    Intercept,
    RallyResult,
    RallyState,
    Shot,
    ShotPlan,
)
from sportsngen.synth.profiles import PlayerProfile
from sportsngen.tennis.court import BASELINE_X_M

# Centre of mass to ball at contact: uniform in this range per shot (a single value taught
# the decoder that a ball passing nearer the body is never struck, so rollouts whose receiver
# stood in the ball's path let it through).
CONTACT_LATERAL_RANGE_M = (0.3, 1.2)
IDEAL_CONTACT_Z_M = 1.0         # the most comfortable contact height
INITIATIVE_CARRY = 0.3          # share (in log) of the ball's difficulty passed on to the reply
SERVE_INSIDE_BASELINE_M = 0.5   # the serve is struck this far inside the baseline (Hawk-Eye:
#                                 0.43-0.64 m for the named players)
MIN_RETURN_REACTION_S = 0.08
# After the serve, before the return: back behind the baseline but no deeper than this (a
# server retreating to his rally depth met short returns going backward).
SERVE_RECOVERY_DEPTH_M = 0.3
# From the serve to the return contact (generated, first / second serves: 0.76 / 0.88 s on
# average), less a split step: the server's recovery run stops by then.
SERVE_SETTLE_S = (0.65, 0.75)
# Players read the opponent's swing: the first step after a rally contact comes this much
# sooner than the plain reaction time (the serve has its own `return_anticipation_s`).
RALLY_ANTICIPATION_S = 0.05


def _difficulty(n_shots: int, previous: float, server: PlayerProfile, serve_number: int,
                hitter_pressure: float, surface: str) -> float:
    """How hard the ball just hit is to play (multiplies the receiver's aim noise).

    The return faces the serve's heaviness (its square root on a second serve), to the power of
    the surface's `behaviour.SURFACE_SERVE_WEIGHT` (clay gives the returner time). Later balls
    face the hitter's rally pressure times the inverse of the difficulty of the ball the hitter
    himself got, to the power `INITIATIVE_CARRY` (a weak reply hands over the initiative; half
    that for the server's first ball after the return, whose weakness is mostly in the
    return's errors). The server's rally balls also carry the serve's initiative, undiminished:
    in the 2011 slams the chance that the server wins the point at his shot (or the receiver's
    next) stays 0.23-0.24 from the third shot to the ninth (Nadal, Djokovic serving), and
    decaying it by 0.85 a shot piled the receivers' errors on the first rally balls."""
    if n_shots == 1:
        d = server.serve_heaviness if serve_number == 1 else math.sqrt(server.serve_heaviness)
        d = d ** bh.SURFACE_SERVE_WEIGHT[surface]
    else:
        carry = 0.5 * INITIATIVE_CARRY if n_shots == 2 else INITIATIVE_CARRY
        d = hitter_pressure * previous ** -carry
        if n_shots % 2 == 1:
            boost = server.serve_initiative if serve_number == 1 else \
                server.second_serve_initiative
            d *= boost
    return min(max(d, 0.2), 10.0)


class ProfilePolicy:
    """The generator's decisions for one rally between two profiles (roles 0 server,
    1 receiver), with the rally's memory: who is at the net, how hard the last ball was, the
    stroke each player prepared for his next contact."""

    def __init__(self, server: PlayerProfile, receiver: PlayerProfile, server_end: int,
                 serving_side: str, serve_number: int, surface: str) -> None:
        if server_end not in (-1, 1):
            raise ValueError(f"server_end must be +1 or -1, got {server_end!r}")
        if serve_number not in (1, 2):
            raise ValueError(f"serve_number must be 1 or 2, got {serve_number!r}")
        bh.deuce_sign(server_end, serving_side)  # validates the side
        if surface not in bh.SURFACE_DEPTH_M:
            raise ValueError(f"unknown surface {surface!r}; known surfaces: "
                             f"{sorted(bh.SURFACE_DEPTH_M)}")
        self.server_end, self.serving_side = server_end, serving_side
        self.serve_number, self.surface = serve_number, surface
        self.profiles = (server.on_surface(surface), receiver.on_surface(surface))
        self.ends = (server_end, -server_end)
        self.bodies = tuple(Body(p.max_speed_mps, p.max_accel_mps2, p.reach_m,
                                 IDEAL_CONTACT_Z_M, bh.rally_depth_m(p, surface),
                                 bh.return_depth_m(p, serve_number, surface))
                            for p in self.profiles)
        self.at_net = [False, False]
        self.incoming = 1.0
        self.stroke = ["forehand", "forehand"]

    def carry_to(self, n_shots: int) -> None:
        """Set the rally's memory of how hard the last ball was (`incoming`) as a rally with
        `n_shots` contacts made has it. It depends only on the shot count, the players, the
        serve and the surface, so a rally played on from a state (`continue_rally`) carries the
        serve's heaviness and initiative as the played rally did (docs/evaluation.md,
        seventy-fourth part)."""
        self.incoming = 1.0
        for k in range(1, n_shots):     # the plan of contact k + 1, facing contact k's hitter
            self.incoming = _difficulty(k, self.incoming, self.profiles[0], self.serve_number,
                                        self.profiles[(k - 1) % 2].rally_pressure,
                                        self.surface)

    def serve(self, rng: np.random.Generator):
        server, receiver = self.profiles
        stance = bh.serve_stance(self.server_end, self.serving_side)
        wait = bh.return_stance(receiver, self.server_end, self.serving_side, self.serve_number,
                                self.surface)
        contact = np.array([self.server_end * (BASELINE_X_M - SERVE_INSIDE_BASELINE_M),
                            stance[1] * 0.9, server.contact_height_m])
        plan = bh.plan_serve(server, self.server_end, self.serving_side, self.serve_number, rng)
        return stance, wait, contact, plan

    def reaction_s(self, role: int, to_serve: bool) -> float:
        p = self.profiles[role]
        if not to_serve:
            return p.reaction_s - RALLY_ANTICIPATION_S
        return max(p.reaction_s + self.profiles[0].serve_disguise_s - p.return_anticipation_s,
                   MIN_RETURN_REACTION_S)

    def recovery(self, hitter: int, plan: ShotPlan | None, landed_in: bool,
                 rng: np.random.Generator,
                 shape_rng: np.random.Generator) -> tuple[float, float]:
        p, end = self.profiles[hitter], self.ends[hitter]
        target_y = plan.target_y_m if plan is not None else 0.0
        serve = plan is not None and plan.stroke == "serve"
        if serve and self.serve_number == 1:
            # Serve and volley is the server's choice before the serve, at the same chance
            # on every first serve; version 5 drew it from the play's stream on serves in,
            # so it still does there (outcomes keep their seeds) and from the side stream
            # on faults.
            u = rng.random() if landed_in else shape_rng.random()
            self.at_net[0] = u < 0.5 * p.net_approach
            target = bh.recovery_target(p, end, target_y, self.at_net[0], self.surface)
            # serve and volley: the first volley around the service line; else back behind
            # the baseline, but no deeper than SERVE_RECOVERY_DEPTH_M before the return
            if self.at_net[0]:
                return end * 6.0, target[1]
            depth = min(abs(target[0]) - BASELINE_X_M, SERVE_RECOVERY_DEPTH_M)
            return self._settled((end * (BASELINE_X_M + depth), target[1]))
        target = bh.recovery_target(p, end, target_y, self.at_net[hitter], self.surface)
        return self._settled(target) if serve else target

    def _settled(self, target: tuple[float, float]) -> tuple[float, float]:
        """The server's recovery after a serve, cut to what he can cover from his stance and
        stop at by the return (`SERVE_SETTLE_S`): he split-steps as the returner swings, so
        he can start for a return to either side (running through the return, he lost 19 %
        of the points in which he still ran at 2.5-4 m/s to return winners)."""
        x0, y0 = bh.serve_stance(self.server_end, self.serving_side)
        dx, dy = target[0] - x0, target[1] - y0
        dist = math.hypot(dx, dy)
        reach = 0.25 * self.profiles[0].max_accel_mps2 * \
            SERVE_SETTLE_S[self.serve_number - 1] ** 2
        if dist <= reach:
            return target
        return x0 + dx * reach / dist, y0 + dy * reach / dist

    def can_volley(self, role: int, pos_m: np.ndarray) -> bool:
        return self.at_net[role]

    def prepare(self, role: int, hit: Intercept, pos_m: np.ndarray, opponent_m: np.ndarray,
                incoming: Shot, rng: np.random.Generator,
                shape_rng: np.random.Generator) -> tuple[float, float]:
        x, y = float(pos_m[0]), float(pos_m[1])
        bx, by = float(hit.ball_m[0]), float(hit.ball_m[1])
        self.stroke[role] = bh.choose_stroke(self.profiles[role], self.ends[role], y, by,
                                             float(hit.ball_m[2]), hit.volley)
        # Run to the point at a comfortable distance from the ball on the way to it.
        away = math.hypot(x - bx, y - by)
        lateral = shape_rng.uniform(*CONTACT_LATERAL_RANGE_M)
        if away > lateral:
            return bx + (x - bx) * lateral / away, by + (y - by) * lateral / away
        return x, y

    def plan(self, role: int, hit: Intercept, opponent_m: np.ndarray, n_shots: int,
             rng: np.random.Generator) -> ShotPlan:
        p, other = self.profiles[role], 1 - role
        if not hit.volley and self.at_net[role] and abs(hit.ball_m[0]) > 7.0:
            self.at_net[role] = False  # lobbed or passed deep: back to the baseline game
        is_return = n_shots == 1
        self.incoming = _difficulty(n_shots, self.incoming, self.profiles[0], self.serve_number,
                                    self.profiles[other].rally_pressure, self.surface)
        plan = bh.plan_rally_shot(p, self.ends[role], self.stroke[role], hit.ball_m,
                                  hit.duress, opponent_m, self.at_net[other],
                                  is_return=is_return, incoming_difficulty=self.incoming,
                                  rng=rng)
        if not self.at_net[role] and abs(hit.ball_m[0]) < BASELINE_X_M - 2.5 and \
                rng.random() < p.net_approach:
            self.at_net[role] = True
        return replace(plan, error_kind=bh.error_kind(hit.duress, is_return))


def play_rally(server: PlayerProfile, receiver: PlayerProfile, server_end: int,
               serving_side: str, serve_number: int, surface: str,
               rng: np.random.Generator, fps: float = 25.0, render: bool = True,
               noise: bool = True, max_shots: int = 80) -> RallyResult:
    """Play one rally. `render=False` skips the ball frames (outcome only, for calibration);
    `noise=False` removes execution noise (shots land on their aim points)."""
    policy = ProfilePolicy(server, receiver, server_end, serving_side, serve_number, surface)
    return cycle.play(policy, rng, fps=fps, render=render, noise=noise, max_shots=max_shots)


def continue_rally(server: PlayerProfile, receiver: PlayerProfile, state: RallyState,
                   server_end: int, serving_side: str, serve_number: int, surface: str,
                   rng: np.random.Generator, fps: float = 25.0, render: bool = True,
                   noise: bool = True) -> RallyResult:
    """Play a rally on from any mid-rally `state` with the generator's players: what these
    players would do from there (times and frames count from the state)."""
    policy = ProfilePolicy(server, receiver, server_end, serving_side, serve_number, surface)
    policy.carry_to(state.n_shots)
    return cycle.continue_rally(policy, state, rng, fps=fps, render=render, noise=noise)
