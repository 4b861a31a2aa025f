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
physics, the movement, the outcome rules and the ball track. `play` starts at the toss;
`continue_rally` starts from a `RallyState` (a ball in flight after a contact, both players'
positions and velocities), e.g. a state of a model's own rollout.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from sportsngen.synth import physics
from sportsngen.synth.players import Mover, max_distance_m, min_time_s
from sportsngen.tennis import court
from sportsngen.tennis.court import BASELINE_X_M, FENCE_X_M, FENCE_Y_M

FLIGHT_T_MAX_S = 3.0
AFTER_END_S = 1.0                # tracks go on this long after the point ends
GROUND_Z_RANGE_M = (0.15, 2.3)   # contact heights of a groundstroke after the bounce
VOLLEY_Z_RANGE_M = (0.3, 3.0)    # before the bounce, for a player at the net
REACH_PLAN_FACTOR = 0.85         # plan contacts within this share of the reach (slack to steer)
REACH_TOLERANCE_M = 0.15
SEARCH_STEP_S = 0.02
PAST_BASELINE_M = 3.0            # an unreached ball this far past his baseline ends the point
TOSS_HAND_Z_M = 1.0
TOSS_RELEASE_Z_M = 1.9
TOSS_RELEASE_S = 0.35
TOSS_ABOVE_CONTACT_M = 0.25
FALLBACK_PACE = (1.3, 0.8, 1.7)  # pace multipliers tried when the planned speed cannot land
DRIVE_ELEVATION_DEG = 5.0        # no pace lands: driven at the target, the physics decides
AZIMUTH_NOISE_RATIO = 1.6        # lateral aim errors are larger in angle than depth errors
# How a player picks among the contacts he can reach: cost per metre from his comfortable
# height, per unit of duress (share of his movement capacity), per second of waiting, per
# metre deeper than he likes, and the bonus of a volley for a player at the net.
CONTACT_COST = {"height": 3.0, "duress": 1.5, "early": 0.2, "deep": 0.3, "volley": 1.0}


@dataclass(frozen=True)
class Body:
    """How one player moves, and where he likes to meet the ball: contacts away from
    `contact_z_m`, and further behind his baseline than `contact_depth_m` in a rally or
    `return_depth_m` on this rally's return, cost him."""

    max_speed_mps: float
    max_accel_mps2: float
    reach_m: float
    contact_z_m: float = 1.0
    contact_depth_m: float = 0.0
    return_depth_m: float = 0.0


@dataclass(frozen=True)
class ShotPlan:
    """What the hitter tries: aim point, speed, spin, labels and execution noise (degrees).
    `into_net`: the ball is meant to find the net (a fitted model's net error);
    `error_kind`: the label if the ball does not land in ("forced" or "unforced")."""

    target_x_m: float
    target_y_m: float
    speed_mps: float
    spin_mps: float
    stroke: str
    spin_label: str
    direction: str
    noise_deg: float
    net_clearance_m: float = 0.3
    lob: bool = False
    into_net: bool = False
    error_kind: str = "unforced"


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


@dataclass
class Intercept:
    """A contact on a flight (flight-local time). `reachable` False: the best the player can
    aim at, where he arrives late."""

    t_s: float
    ball_m: np.ndarray
    volley: bool
    duress: float
    reachable: bool = True


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


def toss(contact_m: np.ndarray) -> tuple[float, float]:
    """(time of contact, launch z-speed at release) of a toss peaking above the contact."""
    rise = contact_m[2] + TOSS_ABOVE_CONTACT_M - TOSS_RELEASE_Z_M
    vz = math.sqrt(2.0 * physics.GRAVITY_MPS2 * max(rise, 0.05))
    t_down = math.sqrt(2.0 * TOSS_ABOVE_CONTACT_M / physics.GRAVITY_MPS2)
    return TOSS_RELEASE_S + vz / physics.GRAVITY_MPS2 + t_down, vz


def toss_track(t: np.ndarray, stance: tuple[float, float], contact: np.ndarray,
               vz: float) -> np.ndarray:
    """Ball positions during the toss: carried up by the hand, then thrown."""
    out = np.empty((len(t), 3))
    u = np.clip(t / TOSS_RELEASE_S, 0.0, 1.0)
    out[:, 0] = stance[0] + (contact[0] - stance[0]) * u
    out[:, 1] = stance[1] + (contact[1] - stance[1]) * u
    tf = np.maximum(t - TOSS_RELEASE_S, 0.0)
    hand = TOSS_HAND_Z_M + (TOSS_RELEASE_Z_M - TOSS_HAND_Z_M) * u * u
    flying = TOSS_RELEASE_Z_M + vz * tf - 0.5 * physics.GRAVITY_MPS2 * tf * tf
    out[:, 2] = np.where(t < TOSS_RELEASE_S, hand, flying)
    return out


def perturb_launch(vel_mps: np.ndarray, noise_deg: float,
                   rng: np.random.Generator) -> np.ndarray:
    """Execution noise: rotate the launch velocity by a random elevation (s.d. `noise_deg`) and
    azimuth (s.d. `AZIMUTH_NOISE_RATIO * noise_deg`); speed unchanged. Zero noise: unchanged."""
    if noise_deg <= 0.0:
        return vel_mps
    vx, vy, vz = (float(v) for v in vel_mps)
    speed = math.sqrt(vx * vx + vy * vy + vz * vz)
    h = math.hypot(vx, vy)
    elev = math.atan2(vz, h) + math.radians(noise_deg) * rng.standard_normal()
    azim = math.atan2(vy, vx) + math.radians(noise_deg * AZIMUTH_NOISE_RATIO) * \
        rng.standard_normal()
    return np.array([speed * math.cos(elev) * math.cos(azim),
                     speed * math.cos(elev) * math.sin(azim), speed * math.sin(elev)])


def launch(contact: np.ndarray, plan: ShotPlan, surface: str) -> tuple[np.ndarray, float]:
    """Launch velocity and speed for the plan. When the planned speed cannot land on the target
    (too fast to drop in over the net, or too slow to get there) the player adjusts the pace;
    when nothing works the ball is driven at the target and the physics decides (usually the
    net). A plan `into_net` is then lowered, a degree at a time, until its flight meets the net."""
    target = (plan.target_x_m, plan.target_y_m)
    vel = physics.solve_launch(contact, target, plan.speed_mps, plan.spin_mps,
                               net_clearance_m=plan.net_clearance_m, lob=plan.lob)
    speed = plan.speed_mps
    if vel is None and plan.lob:
        return launch(contact, replace(plan, lob=False), surface)
    for scale in FALLBACK_PACE if vel is None else ():
        vel = physics.solve_launch(contact, target, speed * scale, plan.spin_mps,
                                   net_clearance_m=plan.net_clearance_m)
        if vel is not None:
            speed = speed * scale
            break
    dx, dy = target[0] - contact[0], target[1] - contact[1]
    h = math.hypot(dx, dy)
    if vel is None:
        elev = math.radians(DRIVE_ELEVATION_DEG)
        vel = np.array([speed * math.cos(elev) * dx / h, speed * math.cos(elev) * dy / h,
                        speed * math.sin(elev)])
    if not plan.into_net:
        return vel, speed
    elev = math.atan2(vel[2], math.hypot(vel[0], vel[1]))
    for _ in range(40):
        elev -= math.radians(1.0)
        v = np.array([speed * math.cos(elev) * dx / h, speed * math.cos(elev) * dy / h,
                      speed * math.sin(elev)])
        f = physics.fly(contact, v, plan.spin_mps, surface, FLIGHT_T_MAX_S, max_bounces=1)
        if f.events and f.events[0].kind == "net":
            return v, speed
    return vel, speed


def flight_events(flight: physics.Flight) -> tuple[object | None, object | None]:
    """First event of a flight and its second bounce (if the first event was a bounce)."""
    first = flight.events[0] if flight.events else None
    bounces = [e for e in flight.events if e.kind == "bounce"]
    second = bounces[1] if len(bounces) > 1 and first is not None and first.kind == "bounce" \
        else None
    return first, second


def read_flight(flight: physics.Flight, pos_m: np.ndarray, vel_mps: np.ndarray,
                spin_mps: float, surface: str, max_bounces: int = 2) -> physics.Flight:
    """The flight a player reads from the launch: the flight itself, or for a ball that will
    meet the net, its flight through the net (before it meets the cord nobody can tell)."""
    first = flight.events[0] if flight.events else None
    if first is None or first.kind != "net":
        return flight
    return physics.fly(pos_m, vel_mps, spin_mps, surface, FLIGHT_T_MAX_S,
                       max_bounces=max_bounces, net=False)


def find_intercept(flight: physics.Flight, t_react: float, pos: np.ndarray,
                   vel: tuple[float, float], body: Body, end: int, can_volley: bool,
                   t_bounce: float, t_stop: float, depth_m: float = 0.0) -> Intercept | None:
    """Best contact on the flight (local times) for a player who starts to move at `t_react`.

    Reachable: from (pos, vel) a disk drifting with the current velocity (while the player
    brakes it to zero) whose radius grows as he accelerates must reach within
    `REACH_PLAN_FACTOR` of his reach. Among reachable contacts he prefers (`CONTACT_COST`) a
    comfortable height, little running, an early ball and not deeper behind his baseline than
    `depth_m`. When none is reachable, the contact he is least late for (`reachable` False).
    None when the flight offers no contact at a playable height on his side at all."""
    t0 = max(t_react, 0.05)
    if t_stop <= t0:
        return None
    tau = np.arange(t0, t_stop, SEARCH_STEP_S)
    if len(tau) == 0:
        return None
    ball = flight.at(tau)
    z = ball[:, 2]
    post = tau > t_bounce
    on_my_side = ball[:, 0] * end > 0.5
    ok_post = post & (z >= GROUND_Z_RANGE_M[0]) & (z <= GROUND_Z_RANGE_M[1])
    ok_pre = (~post) & can_volley & on_my_side & (z >= VOLLEY_Z_RANGE_M[0]) & \
        (z <= VOLLEY_Z_RANGE_M[1])
    valid = (ok_post | ok_pre) & (np.abs(ball[:, 0]) < FENCE_X_M - 1.0)
    if not valid.any():
        return None
    avail = tau - t_react
    # While he cancels his velocity the player still drifts: by v d - a d^2 / 2 after d seconds
    # of braking, at most his braking distance v^2 / (2 a).
    t_brake = math.hypot(vel[0], vel[1]) / body.max_accel_mps2
    d = np.minimum(avail, t_brake)
    drift = d - 0.5 * d * d / t_brake if t_brake > 0 else np.zeros_like(d)
    gap = np.hypot(ball[:, 0] - pos[0] - vel[0] * drift, ball[:, 1] - pos[1] - vel[1] * drift)
    travel = np.maximum(gap - REACH_PLAN_FACTOR * body.reach_m, 0.0)
    need = min_time_s(travel, body.max_speed_mps, body.max_accel_mps2)
    ok = valid & (need <= avail)
    if not ok.any():
        k = int(np.argmin(np.where(valid, need - avail, np.inf)))
        return Intercept(float(tau[k]), ball[k].copy(), bool(ok_pre[k]), 1.0, reachable=False)
    reachable = max_distance_m(avail, body.max_speed_mps, body.max_accel_mps2)
    duress = np.clip(travel / np.maximum(reachable, 1e-6), 0.0, 1.0)
    deep = np.maximum(np.abs(ball[:, 0]) - BASELINE_X_M - depth_m, 0.0)
    w = CONTACT_COST
    cost = w["height"] * np.abs(z - body.contact_z_m) + w["duress"] * duress + \
        w["early"] * tau + w["deep"] * deep - w["volley"] * ok_pre
    k = int(np.argmin(np.where(ok, cost, np.inf)))
    return Intercept(float(tau[k]), ball[k].copy(), bool(ok_pre[k]), float(duress[k]))


def nearest_pass(flight: physics.Flight, t_react: float, pos: np.ndarray, end: int,
                 t_stop: float) -> tuple[float, np.ndarray] | None:
    """(local time, ball position) of the point of the flight on the player's side nearest to
    him: what he runs at when nothing is playable (a lob over him, a ball dying at the net)."""
    tau = np.arange(max(t_react, 0.05), t_stop, SEARCH_STEP_S)
    if len(tau) == 0:
        return None
    ball = flight.at(tau)
    gap = np.where(ball[:, 0] * end > 0.5,
                   np.hypot(ball[:, 0] - pos[0], ball[:, 1] - pos[1]), np.inf)
    k = int(np.argmin(gap))
    return (float(tau[k]), ball[k].copy()) if np.isfinite(gap[k]) else None


def stop_roll_at_net(roll: np.ndarray, side: float) -> None:
    """A ball rolling on the ground into the net stops against it (in place), on its side."""
    if side == 0:
        return
    crossed = np.flatnonzero(np.sign(roll[:, 0]) != side)
    if len(crossed):
        k = crossed[0]
        roll[k:, 0] = side * physics.BALL_RADIUS_M
        roll[k:, 1] = roll[k - 1, 1] if k > 0 else roll[k, 1]


def ball_track(t: np.ndarray, flights: list[tuple[float, physics.Flight]],
               toss: tuple[tuple[float, float], np.ndarray, float] | None = None) -> np.ndarray:
    """Ball at each frame time: the toss (`toss` = (stance, serve contact, toss z-speed)), then
    each flight until the next contact, then the last flight and a roll-out; a ball reaching
    the fence stops there and drops."""
    out = np.empty((len(t), 3))
    starts = [s for s, _ in flights]
    before = t < starts[0]
    if toss is not None:
        out[before] = toss_track(t[before], toss[0], toss[1], toss[2])
    else:  # a continued rally: the ball was where the first flight starts
        out[before] = flights[0][1].pos_m[0]
    for i, (t0, flight) in enumerate(flights):
        t1 = starts[i + 1] if i + 1 < len(flights) else np.inf
        sel = (t >= t0) & (t < t1)
        if not sel.any():
            continue
        tau = t[sel] - t0
        t_last = float(flight.t_s[-1])
        inside = tau <= t_last
        seg = np.empty((len(tau), 3))
        if inside.any():
            seg[inside] = flight.at(tau[inside])
        if (~inside).any():  # after the flight: roll on with decaying speed
            p_end, v_end = flight.pos_m[-1], flight.vel_mps[-1]
            extra = tau[~inside] - t_last
            decay = 0.5 * (1.0 - np.exp(-extra / 0.5))
            roll = np.empty((len(extra), 3))
            roll[:, 0] = p_end[0] + v_end[0] * decay
            roll[:, 1] = p_end[1] + v_end[1] * decay
            roll[:, 2] = max(physics.BALL_RADIUS_M, min(p_end[2], physics.BALL_RADIUS_M))
            stop_roll_at_net(roll, side=np.sign(p_end[0]))
            seg[~inside] = roll
        out[sel] = seg
    beyond = np.nonzero((np.abs(out[:, 0]) > FENCE_X_M) | (np.abs(out[:, 1]) > FENCE_Y_M))[0]
    if len(beyond):
        k = beyond[0]
        x, y = np.clip(out[k, 0], -FENCE_X_M, FENCE_X_M), np.clip(out[k, 1], -FENCE_Y_M,
                                                                     FENCE_Y_M)
        z0 = out[k, 2]
        fall = np.arange(len(t) - k) * (t[1] - t[0]) if len(t) > 1 else np.zeros(1)
        out[k:, 0], out[k:, 1] = x, y
        out[k:, 2] = np.maximum(z0 - 0.5 * physics.GRAVITY_MPS2 * fall ** 2,
                                physics.BALL_RADIUS_M)
    return out


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
    t_contact, toss_vz = toss(contact)
    for m in movers:  # both stand still through the toss: nobody moves before the serve
        m.run_to(int(math.floor(t_contact * fps)), m.x, m.y)
    vel, speed = launch(contact, plan, policy.surface)
    if noise:
        vel = perturb_launch(vel, plan.noise_deg, rng)
    return _run(policy, rng, shape_rng, movers, hitter=0, t_contact=t_contact, t_react0=None,
                contact=contact, vel=vel, spin=plan.spin_mps, plan=plan, speed=speed,
                bounces=0, n_shots=1, fps=fps, render=render, noise=noise,
                max_shots=max_shots, toss_info=(stance_s, contact, toss_vz))


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
        depth = bodies[opp].return_depth_m if is_serve else bodies[opp].contact_depth_m
        hit = find_intercept(read, t_react_local, mover.pos, (mover.vx, mover.vy), bodies[opp],
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
