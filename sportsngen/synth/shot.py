"""The pieces of one shot in the shot-cycle kernel (`synth.cycle`): the toss, the launch with
its pace fallbacks and execution noise, the flight a player reads, the search for the contact he
goes for, and the ball track drawn from the flights. Decisions are not made here: a `ShotPlan`
comes from a policy, a `Body` says how a player moves and what contact he likes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from sportsngen.synth import physics
from sportsngen.synth.players import max_distance_m, min_time_s
from sportsngen.tennis.court import BASELINE_X_M, FENCE_X_M, FENCE_Y_M

FLIGHT_T_MAX_S = 3.0
GROUND_Z_RANGE_M = (0.15, 2.3)   # contact heights of a groundstroke after the bounce
VOLLEY_Z_RANGE_M = (0.3, 3.0)    # before the bounce, for a player at the net
REACH_PLAN_FACTOR = 0.85         # plan contacts within this share of the reach (slack to steer)
SEARCH_STEP_S = 0.02
TOSS_HAND_Z_M = 1.0
TOSS_RELEASE_Z_M = 1.9
TOSS_RELEASE_S = 0.35
TOSS_ABOVE_CONTACT_M = 0.25
# Pace multipliers tried in turn when the planned speed cannot land (slower before blind: with
# only 1.3, 0.8 and 1.7, 1.6 % of servers' third balls were driven at the net or long).
FALLBACK_PACE = (1.3, 0.8, 0.65, 0.5, 1.7)
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
class Intercept:
    """A contact on a flight (flight-local time). `reachable` False: the best the player can
    aim at, where he arrives late."""

    t_s: float
    ball_m: np.ndarray
    volley: bool
    duress: float
    reachable: bool = True


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
    # A flight that ends first (the net, the second bounce) has nothing later to meet: a state
    # handed to the kernel late in a flight (continue_rally) reached here with t_stop past it.
    t_stop = min(t_stop, float(flight.t_s[-1]))
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
               toss: tuple[tuple[float, float], np.ndarray, float, float] | None = None
               ) -> np.ndarray:
    """Ball at each frame time: the toss (`toss` = (stance, serve contact, toss z-speed, the
    toss's start time; the ball rests in the hand before it)), then each flight until the next
    contact, then the last flight and a roll-out; a ball reaching the fence stops there and
    drops."""
    out = np.empty((len(t), 3))
    starts = [s for s, _ in flights]
    before = t < starts[0]
    if toss is not None:
        out[before] = toss_track(t[before] - toss[3], toss[0], toss[1], toss[2])
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
