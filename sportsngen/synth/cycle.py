"""The shot-cycle kernel: one rally as flights and runs, from a serve or from any mid-rally state,
with the decisions supplied by a policy.

The cycle (as in Vid2Player): the hitter's plan (aim point, speed, spin, execution noise) is
launched by the physics (`launch`: a pace that lands on the aim, with fallbacks) and flown
(`physics.fly`). The opponent reacts after his reaction delay, reads the flight from its launch
(through the net: before it meets the cord nobody can tell that it will), searches it for the
best contact he can reach in time (`find_intercept`) and runs to a spot beside it; the hitter
recovers. Outcomes emerge: a ball into the net or out is an error (a fault on a serve), a ball
the opponent cannot reach is a winner (an ace on a serve).

Causal (generator version 6): every run is planned from what the player has seen by then. Both
players keep to their plans whatever the shot's fate (the receiver goes for a serve that will be
a fault, the opponent for a ball he will not reach, the hitter recovers after a winner) until
the end of the point is visible (the net hit, the bounce out, the ball reaching the contact the
opponent could not make), and each brakes one reaction time later.

Who decides what is the policy's (`Policy`): the generator's profiles and behaviour
(`synth.rally`) or a fitted shot-cycle model (`baselines.shot_cycle_sim`). The kernel owns the
physics, the movement, the outcome rules and the ball track; the pieces of one shot (launch,
noise, the flight a player reads, the intercept search, the track) are in `synth.shot`. `play`
starts at the toss; `continue_rally` starts from a `RallyState` (a ball in flight after a
contact, both players' positions and velocities), e.g. a state of a model's own rollout.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from sportsngen.synth import physics
from sportsngen.synth.players import Mover
from sportsngen.synth.shot import (  # noqa: F401  (re-exported: the kernel's vocabulary)
    AZIMUTH_NOISE_RATIO,
    CONTACT_COST,
    FLIGHT_T_MAX_S,
    Body,
    Intercept,
    ShotPlan,
    ball_track,
    find_intercept,
    flight_events,
    launch,
    nearest_pass,
    perturb_launch,
    read_flight,
    stop_roll_at_net,
    toss,
)
from sportsngen.tennis import court
from sportsngen.tennis.court import BASELINE_X_M

AFTER_END_S = 1.0                # tracks go on this long after the point ends
REACH_TOLERANCE_M = 0.15         # a run that ends this far beyond the reach still makes it
PAST_BASELINE_M = 3.0            # an unreached ball this far past his baseline ends the point
# Off: each player's serves meet the ball at one fraction of a frame (the generated tracks of
# version 6.2). On, the toss starts anywhere within the first frame, as real trackers' frames
# fall: the statistics hold but not a seed's points, and seven tests of readers and exemplars
# still lean on the one phase (docs/synthetic-data.md), so it waits for version 6.3. Tests turn
# it on to keep the readers honest about real tracking.
SERVE_PHASE = False
SERVE_PHASE_STREAM = 1           # `serve_phase`'s stream, apart from the shapes' (`stream_key`)


@dataclass
class Shot:
    """One racket contact and what became of the ball."""

    hitter: int                  # 0 server, 1 receiver
    t_s: float
    stroke: str
    spin: str
    direction: str
    contact_m: np.ndarray
    speed_mps: float
    bounce_xy: tuple[float, float] | None = None
    target_xy: tuple[float, float] | None = None   # the aim point (before execution noise)
    outcome: str = "in_play"
    error_kind: str = "none"


@dataclass
class RallyResult:
    """Outcome and (when rendered) tracks of one rally. Roles: 0 server, 1 receiver. Times and
    frames count from the rally's start (the toss), or from the state `continue_rally` began at."""

    end_reason: str
    end_detail: str
    winner_role: int | None      # None for a first-serve fault
    rally_length: int
    serve_kmh: float
    shots: list[Shot]
    n_frames: int
    ball_m: np.ndarray | None = None          # (n_frames, 3)
    players_m: np.ndarray | None = None       # (2, n_frames, 2)
    frame_shot: np.ndarray | None = None      # index of the shot in progress at each frame
    contact_gap_m: list[float] = field(default_factory=list)  # COM-to-ball at each contact


@dataclass(frozen=True)
class RallyState:
    """A rally in progress after a contact: enough to play it on. Positions in the court frame
    (m), velocities m/s, `ball_spin_mps` the flight's v_spin (> 0 topspin; 0 when unknown).
    `t_contact_s`: time of the last contact relative to this state (<= 0; None: long enough ago
    for the opponent to have reacted); `bounces`: bounces since it; `n_shots`: contacts so far,
    the serve included (1 = the serve is in the air)."""

    ball_m: tuple[float, float, float]
    ball_vel_mps: tuple[float, float, float]
    players_m: tuple[tuple[float, float], tuple[float, float]]
    last_hitter: int
    players_vel_mps: tuple[tuple[float, float], tuple[float, float]] = ((0.0, 0.0), (0.0, 0.0))
    ball_spin_mps: float = 0.0
    t_contact_s: float | None = None
    bounces: int = 0
    n_shots: int = 2


class Policy(Protocol):
    """The decisions of both players of one rally (roles 0 server, 1 receiver). Every method
    sees only what its player could have seen by then; `rng` is the play's stream, `shape_rng` a
    side stream for choices that shape the tracks but not the play."""

    server_end: int
    serving_side: str
    serve_number: int
    surface: str
    bodies: tuple[Body, Body]

    def serve(self, rng: np.random.Generator) -> tuple[tuple[float, float], tuple[float, float],
                                                       np.ndarray, ShotPlan]:
        """(server's stance, receiver's stance, serve contact point, serve plan)."""

    def reaction_s(self, role: int, to_serve: bool) -> float:
        """Delay between the opponent's contact (or a visible end) and this player's move."""

    def recovery(self, hitter: int, plan: ShotPlan | None, landed_in: bool,
                 rng: np.random.Generator,
                 shape_rng: np.random.Generator) -> tuple[float, float]:
        """Where the hitter heads after his shot (`plan` None: a shot the kernel did not plan,
        in `continue_rally`). `landed_in` is known to the kernel only: a policy may use it to
        keep the play's stream unchanged, never to decide differently."""

    def can_volley(self, role: int, pos_m: np.ndarray) -> bool:
        """May this player take the ball before the bounce (he is at the net)?"""

    def prepare(self, role: int, hit: Intercept, pos_m: np.ndarray, opponent_m: np.ndarray,
                incoming: Shot, rng: np.random.Generator,
                shape_rng: np.random.Generator) -> tuple[float, float]:
        """The spot this player runs to for `hit` on the `incoming` shot (beside the ball);
        also asked for a ball he will not reach (`hit.reachable` False): he goes for it."""

    def plan(self, role: int, hit: Intercept, opponent_m: np.ndarray, n_shots: int,
             rng: np.random.Generator) -> ShotPlan:
        """The shot this player makes at `hit` (`n_shots` contacts before it)."""


# -- pieces ----------------------------------------------------------------------------------

def stream_key(rng: np.random.Generator) -> int:
    """An integer fixed by `rng`'s current state, read without drawing from it."""
    return zlib.crc32(repr(rng.bit_generator.state).encode())


def serve_phase(rng: np.random.Generator) -> float:
    """The toss's start within the first frame, in [0, 1) frames: fixed by `rng`'s state,
    drawn without drawing from it."""
    return float(np.random.default_rng([stream_key(rng), SERVE_PHASE_STREAM]).random())


# -- the rally --------------------------------------------------------------------------------

def play(policy: Policy, rng: np.random.Generator, fps: float = 25.0, render: bool = True,
         noise: bool = True, max_shots: int = 80) -> RallyResult:
    """One rally from the start of the toss to `AFTER_END_S` after its end. `render=False`
    skips the ball track (outcome only, for calibration); `noise=False` removes execution noise
    (shots land on their aim points)."""
    shape_rng = np.random.default_rng(stream_key(rng))
    stance_s, stance_r, contact, plan = policy.serve(rng)
    b = policy.bodies
    dt = 1.0 / fps
    movers = [Mover(stance_s[0], stance_s[1], b[0].max_speed_mps, b[0].max_accel_mps2, dt),
              Mover(stance_r[0], stance_r[1], b[1].max_speed_mps, b[1].max_accel_mps2, dt)]
    t_toss_s, toss_vz = toss(contact)
    # A tracker's frames fall anywhere in the serve's motion; with `SERVE_PHASE` the toss
    # starts that fraction of a frame after frame 0, from a stream of its own.
    start_s = serve_phase(rng) * dt if SERVE_PHASE else 0.0
    t_contact = start_s + t_toss_s
    for m in movers:  # both stand still through the toss: nobody moves before the serve
        m.run_to(int(math.floor(t_contact * fps)), m.x, m.y)
    vel, speed = launch(contact, plan, policy.surface)
    if noise:
        vel = perturb_launch(vel, plan.noise_deg, rng)
    return _run(policy, rng, shape_rng, movers, hitter=0, t_contact=t_contact, t_react0=None,
                contact=contact, vel=vel, spin=plan.spin_mps, plan=plan, speed=speed,
                bounces=0, n_shots=1, fps=fps, render=render, noise=noise,
                max_shots=max_shots, toss_info=(stance_s, contact, toss_vz, start_s))


def continue_rally(policy: Policy, state: RallyState, rng: np.random.Generator,
                   fps: float = 25.0, render: bool = True, noise: bool = True,
                   max_shots: int = 80) -> RallyResult:
    """Play a rally on from `state` (times and frames count from the state). The ball in the
    air at the state is the result's first shot, with stroke "none" (the kernel did not plan
    it); the rally's decisions come from `policy`, e.g. the generator's players (an expert
    that answers any state of a model's rollout)."""
    ball = np.asarray(state.ball_m, dtype=float).reshape(3)
    ball_vel = np.asarray(state.ball_vel_mps, dtype=float).reshape(3)
    pos = np.asarray(state.players_m, dtype=float).reshape(2, 2)
    pvel = np.asarray(state.players_vel_mps, dtype=float).reshape(2, 2)
    if state.last_hitter not in (0, 1):
        raise ValueError(f"last_hitter must be 0 (server) or 1 (receiver), "
                         f"got {state.last_hitter!r}")
    if state.bounces not in (0, 1):
        raise ValueError(f"bounces must be 0 or 1 (two end the point), got {state.bounces!r}")
    if state.n_shots < 1:
        raise ValueError(f"n_shots must be >= 1 (the ball was struck), got {state.n_shots!r}")
    if not (np.isfinite(ball).all() and np.isfinite(ball_vel).all() and np.isfinite(pos).all()
            and np.isfinite(pvel).all() and math.isfinite(state.ball_spin_mps)):
        raise ValueError("RallyState holds a NaN or infinite position, velocity or spin")
    if ball[2] < physics.BALL_RADIUS_M - 1e-9:
        raise ValueError(f"ball below the ground: z = {ball[2]:.3f} m")
    if state.t_contact_s is not None and state.t_contact_s > 0:
        raise ValueError(f"t_contact_s is the last contact's time relative to the state, so "
                         f"<= 0; got {state.t_contact_s}")
    b = policy.bodies
    dt = 1.0 / fps
    movers = [Mover(float(pos[k, 0]), float(pos[k, 1]), b[k].max_speed_mps,
                    b[k].max_accel_mps2, dt, float(pvel[k, 0]), float(pvel[k, 1]))
              for k in (0, 1)]
    shape_rng = np.random.default_rng(stream_key(rng))
    t_react0 = -math.inf if state.t_contact_s is None else float(state.t_contact_s)
    return _run(policy, rng, shape_rng, movers, hitter=state.last_hitter, t_contact=0.0,
                t_react0=t_react0, contact=ball, vel=ball_vel,
                spin=float(state.ball_spin_mps), plan=None, speed=float(np.linalg.norm(ball_vel)),
                bounces=state.bounces, n_shots=state.n_shots, fps=fps, render=render,
                noise=noise, max_shots=max_shots, toss_info=None)


def _landed_in(first, is_serve: bool, policy: Policy, receiver_end: int) -> bool:
    if first is None or first.kind != "bounce":
        return False
    x, y = float(first.pos_m[0]), float(first.pos_m[1])
    if is_serve:
        return bool(court.is_in_service_box(x, y, policy.server_end, policy.serving_side))
    return bool(court.is_in_singles(x, y, receiver_end))


def _run(policy: Policy, rng: np.random.Generator, shape_rng: np.random.Generator,
         movers: list[Mover], hitter: int, t_contact: float, t_react0: float | None,
         contact: np.ndarray, vel: np.ndarray, spin: float, plan: ShotPlan | None,
         speed: float, bounces: int, n_shots: int, fps: float, render: bool, noise: bool,
         max_shots: int, toss_info) -> RallyResult:
    """The shot cycle from a ball just launched (or in the air) until the point ends."""
    dt = 1.0 / fps
    ends = (policy.server_end, -policy.server_end)
    bodies = policy.bodies
    targets = [(m.x, m.y) for m in movers]
    shots: list[Shot] = []
    flights: list[tuple[float, physics.Flight]] = []
    gaps: list[float] = []
    end_reason = end_detail = ""
    winner: int | None = None
    serve_kmh = float("nan")
    for _ in range(max_shots):
        is_serve = n_shots == 1
        opp = 1 - hitter
        flight = physics.fly(contact, vel, spin, policy.surface, FLIGHT_T_MAX_S,
                             max_bounces=2 - bounces)
        p = plan
        shot = Shot(hitter, t_contact, p.stroke if p else "none", p.spin_label if p else "none",
                    p.direction if p else "none", contact.copy(), float(speed),
                    target_xy=(p.target_x_m, p.target_y_m) if p else None)
        shots.append(shot)
        flights.append((t_contact, flight))
        if p is not None and p.stroke == "serve":
            serve_kmh = speed * 3.6
        first, _ = flight_events(flight)
        bounce_times = [e.t_s for e in flight.events if e.kind == "bounce"]
        if bounces:  # continued after the bounce: it was in, the next bounce ends the point
            landed_in, t_bounce = True, -1.0
            t_stop = bounce_times[0] if bounce_times else float(flight.t_s[-1])
        else:
            landed_in = _landed_in(first, is_serve, policy, ends[opp])
            if first is not None and first.kind == "bounce":
                shot.bounce_xy = (float(first.pos_m[0]), float(first.pos_m[1]))

        # Whatever the shot's fate: the hitter recovers, the opponent reacts and goes for it.
        targets[hitter] = policy.recovery(hitter, plan, landed_in, rng, shape_rng)
        delay = policy.reaction_s(opp, is_serve)
        t_react = t_contact + delay if t_react0 is None else max(t_react0 + delay, 0.0)
        # A state handed over after the opponent reacted (continue_rally): he chose his contact
        # when he reacted, standing, and has been running to it since. Planned from his
        # mid-run state instead, the intercept search (which brakes a player's velocity before
        # he accelerates) lost that run, and 12-17 % of the serves he had reached became aces.
        since = -(t_react0 + delay) if t_react0 is not None and math.isfinite(t_react0) else 0.0
        t_react0 = None
        k_react = int(math.floor(t_react * fps)) if t_react > 0 else 0
        for m in (opp, hitter):
            movers[m].run_to(max(k_react, movers[m].n_frames - 1), *targets[m])
        read = read_flight(flight, contact, vel, spin, policy.surface, max_bounces=2 - bounces)
        read_bounces = [e.t_s for e in read.events if e.kind == "bounce"]
        if not bounces:
            t_bounce = read_bounces[0] if read_bounces else math.inf
            t_stop = read_bounces[1] if len(read_bounces) > 1 else float(read.t_s[-1])
        t_react_local = k_react * dt - t_contact
        mover = movers[opp]
        plan_pos, plan_vel = mover.pos, (mover.vx, mover.vy)
        if since > 0.0:   # where he stood when he reacted, if he accelerated from rest since
            plan_pos = mover.pos - 0.5 * since * np.array(plan_vel)
            plan_vel, t_react_local = (0.0, 0.0), -since
        depth = bodies[opp].return_depth_m if is_serve else bodies[opp].contact_depth_m
        hit = find_intercept(read, t_react_local, plan_pos, plan_vel, bodies[opp],
                             ends[opp], policy.can_volley(opp, mover.pos), t_bounce, t_stop,
                             depth)
        if hit is None:
            near = nearest_pass(read, t_react_local, mover.pos, ends[opp], t_stop)
            if near is not None:
                hit = Intercept(near[0], near[1], False, 1.0, reachable=False)
        reached = False
        spot = k_next = None
        if hit is not None:
            t_next = t_contact + hit.t_s
            k_next = max(int(round(t_next * fps)), k_react)
            spot = policy.prepare(opp, hit, mover.pos, movers[hitter].pos, shot, rng,
                                  shape_rng)
            if landed_in and hit.reachable:
                mover.run_to(k_next, *spot, hurry=True)
                movers[hitter].run_to(k_next, *targets[hitter])
                gap = math.hypot(mover.x - hit.ball_m[0], mover.y - hit.ball_m[1])
                reached = gap <= bodies[opp].reach_m + REACH_TOLERANCE_M
                if reached:
                    gaps.append(gap)

        if not landed_in:
            t_seen = first.t_s if first is not None else float(flight.t_s[-1])
            end_detail = "net" if first is not None and first.kind == "net" else "out"
            shot.outcome = "error"
            if is_serve:
                shot.error_kind = "fault"
                end_reason = "fault" if policy.serve_number == 1 else "double_fault"
                winner = None if policy.serve_number == 1 else 1
            else:
                shot.error_kind = plan.error_kind if plan is not None else "unforced"
                end_reason = f"{shot.error_kind}_error"
                winner = opp
            t_end = t_contact + t_seen
        elif not reached:
            shot.outcome = "winner"
            end_reason = "ace" if is_serve else "winner"
            end_detail, winner = "unreached", hitter
            past = np.nonzero(flight.pos_m[:, 0] * ends[opp] > BASELINE_X_M + PAST_BASELINE_M)[0]
            t_pass = flight.t_s[past[0]] if len(past) else flight.t_s[-1]
            t_end = t_contact + min(t_stop, t_pass)
            t_seen = hit.t_s if hit is not None else min(t_stop, t_pass)
        else:
            n_shots += 1
            plan = policy.plan(opp, hit, movers[hitter].pos, n_shots - 1, rng)
            contact = hit.ball_m
            hitter, t_contact, bounces = opp, t_next, 0
            vel, speed = launch(contact, plan, policy.surface)
            if noise:
                vel = perturb_launch(vel, plan.noise_deg, rng)
            spin = plan.spin_mps
            continue
        # The end is visible at t_contact + t_seen: each player brakes a reaction time later.
        for role in (0, 1):
            k_brake = int(math.floor((t_contact + t_seen + policy.reaction_s(role, False))
                                     * fps))
            m = movers[role]
            if role == opp and spot is not None:
                m.run_to(max(k_brake, m.n_frames - 1), *spot, hurry=True, arrive_by=k_next)
            else:
                m.run_to(max(k_brake, m.n_frames - 1), *targets[role])
        break
    else:  # a rally of max_shots: stop it as an unforced error of the last hitter
        end_reason, end_detail, winner = "unforced_error", "out", 1 - hitter
        shots[-1].outcome, shots[-1].error_kind = "error", "unforced"
        t_end = t_contact + 1.0

    rally_length = sum(s.outcome in ("in_play", "winner") for s in shots)
    n_frames = int(math.ceil((t_end + AFTER_END_S) * fps)) + 1
    result = RallyResult(end_reason, end_detail, winner, rally_length, serve_kmh, shots,
                         n_frames, contact_gap_m=gaps)
    if not render:
        return result
    for m in movers:  # after the point: both players brake to a stop
        m.run_to(max(n_frames - 1, m.n_frames - 1), *m.stop_point())
    result.players_m = np.stack([m.as_array()[:n_frames] for m in movers])
    t = np.arange(n_frames) * dt
    result.ball_m = ball_track(t, flights, toss_info)
    contact_frames = np.array([s.t_s for s in shots]) * fps
    result.frame_shot = np.maximum(np.searchsorted(np.round(contact_frames), np.arange(n_frames),
                                                   side="right") - 1, 0)
    return result
