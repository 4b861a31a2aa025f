"""One rally (one serve and what follows) from the start of the toss to ~1 s after its end.

The shot cycle (as in Vid2Player): the hitter plans a shot (`behaviour`), the physics solves a
launch that lands on the aim point, execution noise rotates that launch, and the ball is flown
(`physics.fly`). If it hits the net or lands out, the hitter made an error (a fault on a serve).
Otherwise the opponent, who only starts moving after his reaction delay, searches the flight for
contact points he can reach in time within his height and lateral limits (`players`); none means
a winner (an ace on a serve), though he still runs at the ball (`_chase_spot`), as players do.
Meanwhile the hitter recovers toward his recovery position.

Players move frame by frame at the tracking rate, so the tracks obey the speed and acceleration
limits exactly; the ball is sampled from the flights at the same frame times.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field, replace

import numpy as np

from sportsngen.synth import behaviour as bh
from sportsngen.synth import physics
from sportsngen.synth.players import Mover, max_distance_m, min_time_s
from sportsngen.synth.profiles import PlayerProfile
from sportsngen.tennis import court
from sportsngen.tennis.court import BASELINE_X_M

FLIGHT_T_MAX_S = 3.0
AFTER_END_S = 1.0            # tracks go on this long after the point ends
FENCE_X_M = 18.0             # back stop of a show court, from the net
FENCE_Y_M = 9.5
GROUND_Z_RANGE_M = (0.15, 2.3)   # contact heights of a groundstroke after the bounce
VOLLEY_Z_RANGE_M = (0.3, 3.0)    # before the bounce, for a player at the net
IDEAL_CONTACT_Z_M = 1.0
# Centre of mass to ball at contact: uniform in this range per shot (a single value taught
# the decoder that a ball passing nearer the body is never struck, so rollouts whose receiver
# stood in the ball's path let it through).
CONTACT_LATERAL_RANGE_M = (0.3, 1.2)
REACH_PLAN_FACTOR = 0.85     # plan contacts within this share of the reach (slack for steering)
REACH_TOLERANCE_M = 0.15
SEARCH_STEP_S = 0.02
INITIATIVE_DECAY = 0.85         # per server shot, of the serve's initiative (log scale)
INITIATIVE_CARRY = 0.3          # share (in log) of the ball's difficulty passed on to the reply
TOSS_HAND_Z_M = 1.0
TOSS_RELEASE_Z_M = 1.9
TOSS_RELEASE_S = 0.35
TOSS_ABOVE_CONTACT_M = 0.25


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
    """Outcome and (when rendered) tracks of one rally. Roles: 0 server, 1 receiver."""

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


def _toss(stance: tuple[float, float], contact: np.ndarray) -> tuple[float, float]:
    """(time of contact, launch z-speed at release) of a toss peaking above the contact."""
    rise = contact[2] + TOSS_ABOVE_CONTACT_M - TOSS_RELEASE_Z_M
    vz = math.sqrt(2.0 * physics.GRAVITY_MPS2 * max(rise, 0.05))
    t_down = math.sqrt(2.0 * TOSS_ABOVE_CONTACT_M / physics.GRAVITY_MPS2)
    return TOSS_RELEASE_S + vz / physics.GRAVITY_MPS2 + t_down, vz


def _toss_track(t: np.ndarray, stance: tuple[float, float], contact: np.ndarray,
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


def _launch(contact: np.ndarray, plan: bh.ShotPlan) -> tuple[np.ndarray, float]:
    """Launch velocity for the plan. When the requested speed cannot land on the target (too
    fast to drop in over the net, or too slow to get there) the player adjusts the pace; when
    nothing works the ball is driven at the target and the physics decides (usually the net)."""
    target = (plan.target_x_m, plan.target_y_m)
    solve = physics.solve_launch
    speed = plan.speed_mps
    vel = solve(contact, target, speed, plan.spin_mps, net_clearance_m=plan.net_clearance_m,
                lob=plan.lob)
    if vel is not None:
        return vel, speed
    if plan.lob:
        return _launch(contact, replace(plan, lob=False))
    for s in (speed * 1.3, speed * 0.8, speed * 1.7):
        vel = solve(contact, target, s, plan.spin_mps, net_clearance_m=plan.net_clearance_m)
        if vel is not None:
            return vel, s
    dx, dy = target[0] - contact[0], target[1] - contact[1]
    h = math.hypot(dx, dy)
    elev = math.radians(5.0)
    return np.array([speed * math.cos(elev) * dx / h, speed * math.cos(elev) * dy / h,
                     speed * math.sin(elev)]), speed


def _events(flight) -> tuple[object | None, object | None]:
    """First event of a flight and the second bounce (if any)."""
    first = flight.events[0] if flight.events else None
    bounces = [e for e in flight.events if e.kind == "bounce"]
    second = bounces[1] if len(bounces) > 1 and first is not None and first.kind == "bounce" \
        else None
    return first, second


@dataclass
class _Intercept:
    t_s: float                   # flight-local time of contact
    ball_m: np.ndarray
    volley: bool
    duress: float


def _chase_spot(flight, t_react_local: float, pos: np.ndarray, end: int, t_stop: float,
                stand_off_m: float) -> tuple[float, float, float] | None:
    """Where a player who cannot reach the ball runs anyway (local time, x, y): toward the point
    of the flight on his side nearest to him, stopping `stand_off_m` short of it, so that his
    track never shows a ball within reach that he did not play. None when he is already that
    close or the ball never comes to his side."""
    tau = np.arange(max(t_react_local, 0.05), t_stop, SEARCH_STEP_S)
    if len(tau) == 0:
        return None
    ball = flight.at(tau)
    gap = np.where(ball[:, 0] * end > 0.5,
                   np.hypot(ball[:, 0] - pos[0], ball[:, 1] - pos[1]), np.inf)
    k = int(np.argmin(gap))
    if not np.isfinite(gap[k]) or gap[k] <= stand_off_m:
        return None
    keep = stand_off_m / gap[k]
    bx, by = float(ball[k, 0]), float(ball[k, 1])
    return float(tau[k]), bx + (pos[0] - bx) * keep, by + (pos[1] - by) * keep


def _find_intercept(flight, t_react_local: float, pos: np.ndarray, vel: tuple[float, float],
                    p: PlayerProfile,
                    end: int, at_net: bool, t_bounce: float, t_stop: float) -> _Intercept | None:
    """Best reachable contact on the flight (local times), or None when none is reachable."""
    t0 = max(t_react_local, 0.05)
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
    ok_pre = (~post) & at_net & on_my_side & (z >= VOLLEY_Z_RANGE_M[0]) & \
        (z <= VOLLEY_Z_RANGE_M[1])
    valid = (ok_post | ok_pre) & (np.abs(ball[:, 0]) < FENCE_X_M - 1.0)
    if not valid.any():
        return None
    avail = tau - t_react_local
    # Reachable set from (pos, vel): a disk drifting with the current velocity (while the player
    # cancels it) whose radius grows as the player accelerates.
    speed = math.hypot(vel[0], vel[1])
    drift = np.minimum(avail, speed / p.max_accel_mps2)
    gap = np.hypot(ball[:, 0] - pos[0] - vel[0] * drift, ball[:, 1] - pos[1] - vel[1] * drift)
    travel = np.maximum(gap - REACH_PLAN_FACTOR * p.reach_m, 0.0)
    ok = valid & (min_time_s(travel, p.max_speed_mps, p.max_accel_mps2) <= avail)
    if not ok.any():
        return None
    reachable = max_distance_m(avail, p.max_speed_mps, p.max_accel_mps2)
    duress = np.clip(travel / np.maximum(reachable, 1e-6), 0.0, 1.0)
    # Comfortable height, little running, early, and not deep behind the baseline (players
    # step in to short balls rather than wait for them to drop).
    deep = np.maximum(np.abs(ball[:, 0]) - BASELINE_X_M, 0.0)
    cost = np.abs(z - IDEAL_CONTACT_Z_M) + 1.5 * duress + 0.2 * tau + 0.3 * deep - 1.0 * ok_pre
    cost = np.where(ok, cost, np.inf)
    k = int(np.argmin(cost))
    return _Intercept(float(tau[k]), ball[k].copy(), bool(ok_pre[k]), float(duress[k]))


def _difficulty(n_shots: int, previous: float, server: PlayerProfile, serve_number: int,
                hitter_pressure: float) -> float:
    """How hard the ball just hit is to play (multiplies the receiver's aim noise).

    The return faces the serve's heaviness (its square root on a second serve). Later balls
    face the hitter's rally pressure times the inverse of the difficulty of the ball the hitter
    himself got, to the power `INITIATIVE_CARRY` (a weak reply hands over the initiative; half
    that for the server's first ball after the return, whose weakness is mostly in the
    return's errors). The server's rally balls also carry the serve's initiative, decaying by
    `INITIATIVE_DECAY` per shot in log scale."""
    if n_shots == 1:
        d = server.serve_heaviness if serve_number == 1 else math.sqrt(server.serve_heaviness)
    else:
        carry = 0.5 * INITIATIVE_CARRY if n_shots == 2 else INITIATIVE_CARRY
        d = hitter_pressure * previous ** -carry
        if n_shots % 2 == 1:
            boost = server.serve_initiative if serve_number == 1 else \
                server.second_serve_initiative
            d *= boost ** (INITIATIVE_DECAY ** ((n_shots - 3) // 2))
    return min(max(d, 0.2), 10.0)


def _stream_key(rng: np.random.Generator) -> int:
    """An integer fixed by `rng`'s current state, read without drawing from it."""
    return zlib.crc32(repr(rng.bit_generator.state).encode())


def play_rally(server: PlayerProfile, receiver: PlayerProfile, server_end: int,
               serving_side: str, serve_number: int, surface: str,
               rng: np.random.Generator, fps: float = 25.0, render: bool = True,
               noise: bool = True, max_shots: int = 80) -> RallyResult:
    """Play one rally. `render=False` skips the ball frames (outcome only, for calibration);
    `noise=False` removes execution noise (shots land on their aim points)."""
    if server_end not in (-1, 1):
        raise ValueError(f"server_end must be +1 or -1, got {server_end!r}")
    if serve_number not in (1, 2):
        raise ValueError(f"serve_number must be 1 or 2, got {serve_number!r}")
    dt = 1.0 / fps
    profiles = (server, receiver)
    ends = (server_end, -server_end)
    stance = bh.serve_stance(server_end, serving_side)
    movers = [Mover(stance[0], stance[1], server.max_speed_mps, server.max_accel_mps2, dt),
              Mover(*bh.return_stance(receiver, server_end, serving_side, serve_number),
                    receiver.max_speed_mps, receiver.max_accel_mps2, dt)]
    targets = [(movers[0].x, movers[0].y), (movers[1].x, movers[1].y)]
    at_net = [False, False]
    # Draws that shape the tracks but not the play come from a side stream keyed on the
    # rally's position in `rng`, so they leave every outcome draw where it was.
    shape_rng = np.random.default_rng(_stream_key(rng))

    # -- the toss and the serve
    contact = np.array([server_end * (BASELINE_X_M - 0.25), stance[1] * 0.9,
                        server.contact_height_m])
    t_contact, toss_vz = _toss(stance, contact)
    plan = bh.plan_serve(server, server_end, serving_side, serve_number, rng)
    hitter, duress, is_return, incoming = 0, 0.0, False, 1.0
    shots: list[Shot] = []
    flights: list[tuple[float, object]] = []     # (global start time, flight)
    gaps: list[float] = []
    end_reason = end_detail = ""
    winner: int | None = None
    t_end = 0.0
    serve_kmh = float("nan")

    for _ in range(max_shots):
        vel, speed = _launch(contact, plan)
        if noise:
            vel = bh.perturb_launch(vel, plan.noise_deg, rng)
        flight = physics.fly(contact, vel, plan.spin_mps, surface, FLIGHT_T_MAX_S,
                             max_bounces=2)
        shot = Shot(hitter, t_contact, plan.stroke, plan.spin_label, plan.direction,
                    contact.copy(), float(speed), target_xy=(plan.target_x_m, plan.target_y_m))
        shots.append(shot)
        flights.append((t_contact, flight))
        if plan.stroke == "serve":
            serve_kmh = speed * bh.KMH_PER_MPS
        first, second = _events(flight)
        opp = 1 - hitter
        if first is not None and first.kind == "bounce":
            shot.bounce_xy = (float(first.pos_m[0]), float(first.pos_m[1]))
        landed_in = first is not None and first.kind == "bounce" and (
            court.is_in_service_box(first.pos_m[0], first.pos_m[1], server_end, serving_side)
            if plan.stroke == "serve" else court.is_in_singles(first.pos_m[0], first.pos_m[1],
                                                               ends[opp]))
        if not landed_in:
            end_detail = "net" if first is not None and first.kind == "net" else "out"
            t_end = t_contact + (first.t_s if first is not None else flight.t_s[-1])
            shot.outcome = "error"
            if plan.stroke == "serve":
                shot.error_kind = "fault"
                end_reason = "fault" if serve_number == 1 else "double_fault"
                winner = None if serve_number == 1 else 1
            else:
                shot.error_kind = bh.error_kind(duress, is_return)
                end_reason = f"{shot.error_kind}_error"
                winner = opp
            break

        # The hitter recovers; the opponent reacts, then runs to the best reachable contact.
        if plan.stroke == "serve":
            # Both players stand still through the toss: nobody moves before the serve.
            for m in movers:
                m.run_to(int(math.floor(t_contact * fps)), m.x, m.y)
            delay = receiver.reaction_s + server.serve_disguise_s - \
                receiver.return_anticipation_s
            delay = max(delay, 0.08)
            if serve_number == 1 and rng.random() < 0.5 * server.net_approach:
                at_net[0] = True
            targets[0] = bh.recovery_target(server, server_end, plan.target_y_m, at_net[0])
            if at_net[0]:  # serve and volley: first volley around the service line
                targets[0] = (server_end * 6.0, targets[0][1])
        else:
            delay = profiles[opp].reaction_s
            targets[hitter] = bh.recovery_target(profiles[hitter], ends[hitter],
                                                 plan.target_y_m, at_net[hitter])
        t_react = t_contact + delay
        k_react = int(math.floor(t_react * fps))
        movers[opp].run_to(max(k_react, movers[opp].n_frames - 1), *targets[opp])
        movers[hitter].run_to(max(k_react, movers[hitter].n_frames - 1), *targets[hitter])
        t_stop = second.t_s if second is not None else flight.t_s[-1]
        hit = _find_intercept(flight, k_react * dt - t_contact, movers[opp].pos,
                              (movers[opp].vx, movers[opp].vy), profiles[opp],
                              ends[opp], at_net[opp], first.t_s, t_stop)
        if hit is None:
            # He cannot reach it but still goes for it (no random draw: outcomes unchanged).
            spot = _chase_spot(flight, k_react * dt - t_contact, movers[opp].pos, ends[opp],
                               t_stop, profiles[opp].reach_m + REACH_TOLERANCE_M)
            if spot is not None:
                movers[opp].run_to(max(int(round((t_contact + spot[0]) * fps)), k_react),
                                   spot[1], spot[2], hurry=True)
        else:
            t_next = t_contact + hit.t_s
            k_next = int(round(t_next * fps))
            stroke = bh.choose_stroke(profiles[opp], ends[opp], movers[opp].y, hit.ball_m[1],
                                      hit.ball_m[2], hit.volley)
            # Run to the point at a comfortable distance from the ball on the way to it.
            bx, by = hit.ball_m[0], hit.ball_m[1]
            away = math.hypot(movers[opp].x - bx, movers[opp].y - by)
            lateral = shape_rng.uniform(*CONTACT_LATERAL_RANGE_M)
            if away > lateral:
                spot = (bx + (movers[opp].x - bx) * lateral / away,
                        by + (movers[opp].y - by) * lateral / away)
            else:
                spot = (movers[opp].x, movers[opp].y)
            movers[opp].run_to(max(k_next, k_react), *spot, hurry=True)
            movers[hitter].run_to(max(k_next, k_react), *targets[hitter])
            gap = math.hypot(movers[opp].x - hit.ball_m[0], movers[opp].y - hit.ball_m[1])
            if gap > profiles[opp].reach_m + REACH_TOLERANCE_M:
                hit = None  # steering fell short: the ball passes the player
            else:
                gaps.append(gap)
        if hit is None:
            shot.outcome = "winner"
            end_reason = "ace" if plan.stroke == "serve" else "winner"
            end_detail, winner = "unreached", hitter
            past = np.nonzero(np.abs(flight.pos_m[:, 0]) > BASELINE_X_M + 3.0)[0]
            t_pass = flight.t_s[past[0]] if len(past) else flight.t_s[-1]
            t_end = t_contact + min(t_stop, t_pass)
            break

        # The opponent becomes the hitter.
        if not hit.volley and at_net[opp] and abs(hit.ball_m[0]) > 7.0:
            at_net[opp] = False  # lobbed or passed deep: back to the baseline game
        contact = hit.ball_m
        opponent = movers[hitter].pos
        is_return = len(shots) == 1
        incoming = _difficulty(len(shots), incoming, server, serve_number,
                               profiles[hitter].rally_pressure)
        plan = bh.plan_rally_shot(profiles[opp], ends[opp], stroke, contact, hit.duress,
                                  opponent, at_net[hitter], is_return=is_return,
                                  incoming_difficulty=incoming, rng=rng)
        if not at_net[opp] and abs(contact[0]) < BASELINE_X_M - 2.5 and \
                rng.random() < profiles[opp].net_approach:
            at_net[opp] = True
        hitter, duress, t_contact = opp, hit.duress, t_next
    else:  # a rally of max_shots: stop it as an unforced error of the last hitter
        end_reason, end_detail, winner = "unforced_error", "out", 1 - hitter
        shots[-1].outcome, shots[-1].error_kind = "error", "unforced"
        t_end = t_contact + 1.0

    rally_length = sum(s.outcome in ("in_play", "winner") for s in shots)
    n_frames = int(math.ceil((t_end + AFTER_END_S) * fps)) + 1
    result = RallyResult(end_reason, end_detail, winner, rally_length, serve_kmh, shots,
                         n_frames, contact_gap_m=gaps)
    for m in movers:  # after the point: both players brake to a stop
        m.run_to(max(n_frames - 1, m.n_frames - 1), *m.stop_point())
    if not render:
        return result
    result.players_m = np.stack([m.as_array()[:n_frames] for m in movers])
    # Player tracks are not clipped at the fence: a clip stops a running player dead, breaking
    # the acceleration limit; a player braking after a wide ball stays well inside |y| < 20 m.
    t = np.arange(n_frames) * dt
    result.ball_m = _ball_track(t, stance, shots[0].contact_m, toss_vz, flights)
    contact_frames = np.array([s.t_s for s in shots]) * fps
    result.frame_shot = np.maximum(np.searchsorted(np.round(contact_frames), np.arange(n_frames),
                                                   side="right") - 1, 0)
    return result


def _stop_roll_at_net(roll: np.ndarray, side: float) -> None:
    """A ball rolling on the ground into the net stops against it (in place), on its side."""
    if side == 0:
        return
    crossed = np.flatnonzero(np.sign(roll[:, 0]) != side)
    if len(crossed):
        k = crossed[0]
        roll[k:, 0] = side * physics.BALL_RADIUS_M
        roll[k:, 1] = roll[k - 1, 1] if k > 0 else roll[k, 1]


def _ball_track(t: np.ndarray, stance: tuple[float, float], serve_contact: np.ndarray,
                toss_vz: float, flights: list[tuple[float, object]]) -> np.ndarray:
    """Ball at each frame time: toss, then each flight until the next contact, then the last
    flight and a roll-out; a ball reaching the fence stops there and drops."""
    out = np.empty((len(t), 3))
    starts = [s for s, _ in flights]
    toss = t < starts[0]
    out[toss] = _toss_track(t[toss], stance, serve_contact, toss_vz)
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
            _stop_roll_at_net(roll, side=np.sign(p_end[0]))
            seg[~inside] = roll
        out[sel] = seg
    beyond = np.nonzero((np.abs(out[:, 0]) > FENCE_X_M) | (np.abs(out[:, 1]) > FENCE_Y_M))[0]
    if len(beyond):
        k = beyond[0]
        x, y = np.clip(out[k, 0], -FENCE_X_M, FENCE_X_M), np.clip(out[k, 1], -FENCE_Y_M,
                                                                     FENCE_Y_M)
        z0 = out[k, 2]
        fall = np.arange(len(t) - k) / (1.0 / (t[1] - t[0])) if len(t) > 1 else np.zeros(1)
        out[k:, 0], out[k:, 1] = x, y
        out[k:, 2] = np.maximum(z0 - 0.5 * physics.GRAVITY_MPS2 * fall ** 2,
                                physics.BALL_RADIUS_M)
    return out
