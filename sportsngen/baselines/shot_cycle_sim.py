"""Rally simulator driven by the shot-cycle model: decisions from the fitted distributions,
flight and reachability from the synthetic physics. Output: a `RallyData` like the generator's.

One shot cycle: the hitter's decision (shot type, speed, placement or a ball into the net) is
launched with `physics.solve_launch` so that it lands on the drawn placement, and flown with
`physics.fly`. A ball into the net or landing out is an error (a fault on a serve). Otherwise
the opponent reacts after his reaction time, searches the flight for a contact he can reach
(`players.max_distance_m`: his fitted speed and acceleration limits, his reach) and runs there
with a `players.Mover`; none reachable, or the run falling short, is a winner (an ace on a
serve). Meanwhile the hitter recovers to the model's recovery position. Outcomes therefore
emerge from the drawn placements and the physics, as in the generator, while every decision is
the model's.

Assumptions the data cannot give: spin rates per spin label (`SPIN_MPS`), reaction times
(`Physique.reaction_s`, `RETURN_REACTION_S`), the toss, and the contact height window.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from sportsngen.baselines.shot_cycle import PlayerModel, ShotCycleModel, ShotDecision, Stance
from sportsngen.baselines.shot_cycle_table import (
    NO_REGION,
    PLAYER_FRONT_X_M,
    bounce_region,
    region,
    speed_bin,
)
from sportsngen.data.tracking import (
    FPS_DEFAULT,
    FRAME_COLUMNS,
    RALLY_COLUMNS,
    SHOT_COLUMNS,
    RallyData,
)
from sportsngen.synth import physics
from sportsngen.synth.generate import score_row
from sportsngen.synth.players import Mover, max_distance_m
from sportsngen.tennis import court
from sportsngen.tennis.scoring import MatchFormat, MatchState

SPIN_MPS = {"none": 0.0, "flat": 0.0, "topspin": 6.0, "slice": -4.0, "kick": 7.0}
RETURN_REACTION_S = 0.1     # returners read the toss: shorter than the rally reaction
TOSS_S = 1.0                # rally time of the serve contact
AFTER_END_S = 1.0
FLIGHT_T_MAX_S = 3.0
SEARCH_STEP_S = 0.02
GROUND_Z_M = (0.2, 2.4)     # contact heights after the bounce
VOLLEY_Z_M = (0.3, 3.0)     # before the bounce, for a player in the front regions
OVERHEAD_Z_M = 2.3
REACH_TOLERANCE_M = 0.15
FENCE_X_M, FENCE_Y_M = 18.0, 9.5
MAX_SHOTS = 80
KMH_PER_MPS = 3.6
TOURNAMENT = "shot_cycle_sim"


@dataclass
class SimShot:
    """One contact (world frame)."""

    hitter: int                  # 0 server, 1 receiver
    t_s: float
    decision: ShotDecision
    contact_m: np.ndarray
    target_xy: tuple[float, float]
    speed_mps: float
    bounce_xy: tuple[float, float] | None = None
    outcome: str = "in_play"
    error_kind: str = "none"
    direction: str = "none"


@dataclass
class SimRally:
    end_reason: str
    end_detail: str
    winner_role: int | None
    shots: list[SimShot]
    ball_m: np.ndarray            # (n_frames, 3)
    players_m: np.ndarray         # (2, n_frames, 2)
    frame_shot: np.ndarray        # index of the shot in progress at each frame
    rally_length: int = 0
    serve_kmh: float = float("nan")
    flights: list = field(default_factory=list, repr=False)


def _launch(contact: np.ndarray, target: tuple[float, float], d: ShotDecision,
            surface: str) -> tuple[np.ndarray, float]:
    """Launch velocity and speed that land on `target` (the decision's speed, else the nearest
    of a few paces that can); for a ball into the net, lowered until `fly` meets the net."""
    spin = SPIN_MPS.get(d.spin, 0.0)
    vel, speed = None, d.speed_mps
    for scale in (1.0, 1.25, 0.8, 1.6, 0.6):
        vel = physics.solve_launch(contact, target, d.speed_mps * scale, spin)
        if vel is not None:
            speed = d.speed_mps * scale
            break
    if vel is None:  # no pace lands there: driven flat at the target, the physics decides
        dx, dy = target[0] - contact[0], target[1] - contact[1]
        h = math.hypot(dx, dy)
        vel = np.array([speed * dx / h, speed * dy / h, 0.0])
    if d.result != "net":
        return vel, speed
    h = math.hypot(vel[0], vel[1])
    elev = math.atan2(vel[2], h)
    for _ in range(40):
        elev -= math.radians(1.0)
        v = np.array([speed * math.cos(elev) * vel[0] / h, speed * math.cos(elev) * vel[1] / h,
                      speed * math.sin(elev)])
        f = physics.fly(contact, v, spin, surface, FLIGHT_T_MAX_S, max_bounces=1)
        if f.events and f.events[0].kind == "net":
            return v, speed
    return vel, speed


def _intercept(flight, t_react: float, t_stop: float, t_bounce: float, mover: Mover,
               end: int, pm: PlayerModel):
    """(flight time, ball position, volley?) of the contact the player goes for, or None.

    Reachable: from where he would stop if he braked now, and in the time left after his
    reaction and that braking, he can get within his reach of the ball. Among
    the reachable contacts he prefers his usual contact height and a low average running
    speed; a player in the front regions takes the ball before the bounce when he can."""
    ph = pm.physique
    tau = np.arange(max(t_react, 0.05), t_stop, SEARCH_STEP_S)
    if tau.size == 0:
        return None
    ball = flight.at(tau)
    z = ball[:, 2]
    front = abs(mover.x) < PLAYER_FRONT_X_M
    can_volley = bool(pm.strokes & {"forehand_volley", "backhand_volley"})
    after = tau > t_bounce
    ok = after & (z >= GROUND_Z_M[0]) & (z <= GROUND_Z_M[1])
    volley = (~after) & (ball[:, 0] * end > 0.5) & (z >= VOLLEY_Z_M[0]) & \
        (z <= VOLLEY_Z_M[1]) & front & can_volley
    ok = (ok | volley) & (np.abs(ball[:, 0]) < FENCE_X_M - 1.0)
    sx, sy = mover.stop_point()
    brake_s = math.hypot(mover.vx, mover.vy) / mover.max_accel_mps2
    avail = np.maximum(tau - t_react - brake_s, 0.0)
    travel = np.maximum(np.hypot(ball[:, 0] - sx, ball[:, 1] - sy) - ph.reach_m, 0.0)
    ok &= travel <= max_distance_m(avail, ph.max_speed_mps, ph.max_accel_mps2)
    if not ok.any():
        return None
    pace = travel / np.maximum(avail, 1e-3) / ph.max_speed_mps
    cost = np.abs(z - ph.contact_z_m) + pace + 0.2 * tau - 1.0 * volley
    k = int(np.argmin(np.where(ok, cost, np.inf)))
    return float(tau[k]), ball[k].copy(), bool(volley[k])


def _allowed(pm: PlayerModel, volley: bool, z: float, lateral_m: float) -> tuple[str, ...]:
    """Strokes the contact allows. `lateral_m`: how far the ball passes on the player's
    forehand side (negative: backhand side) of where he stands when he reacts; a ball clearly
    to one side (beyond his contact offset) is played on that side. The model picks among the
    rest, so its forehand share decides only the balls hit at the player."""
    if volley and z > OVERHEAD_Z_M and "overhead" in pm.strokes:
        return ("overhead",)
    fh, bh = ("forehand_volley", "backhand_volley") if volley else ("forehand", "backhand")
    if lateral_m > pm.physique.contact_offset_m:
        side = (fh,)
    elif lateral_m < -pm.physique.contact_offset_m:
        side = (bh,)
    else:
        side = (fh, bh)
    for choice in (side, (fh, bh), ("forehand", "backhand")):  # what the player's data has
        have = tuple(s for s in choice if s in pm.strokes)
        if have:
            return have
    raise ValueError(f"{pm.player} has no groundstrokes in the data")


def _stance(model: ShotCycleModel, player: str, role: str, n: int, side: str) -> Stance:
    """Fitted stance, else a default: server behind the centre mark, receiver behind the
    baseline in line with the box (his frame: deuce is y < 0)."""
    s = model.stances.get(player, {}).get((role, n, side))
    if s is not None:
        return s
    sign = -1.0 if side == "deuce" else 1.0
    if role == "server":
        return Stance((-12.1, 0.8 * sign), (-11.6, 0.7 * sign, 2.7))
    return Stance((-13.0, 3.0 * sign))


def play_rally(model: ShotCycleModel, server: str, receiver: str, server_end: int, side: str,
               serve_number: int, surface: str, rng: np.random.Generator,
               fps: float = FPS_DEFAULT) -> SimRally:
    """One rally (one serve and what follows). Roles: 0 server, 1 receiver."""
    dt = 1.0 / fps
    ends = (server_end, -server_end)
    c = (-float(server_end), float(server_end))       # world <-> player frame: multiply by c
    pms = (model.player_model(server, receiver), model.player_model(receiver, server))
    st = (_stance(model, server, "server", serve_number, side),
          _stance(model, receiver, "receiver", serve_number, side))
    movers = [Mover(c[k] * st[k].xy[0], c[k] * st[k].xy[1], pms[k].physique.max_speed_mps,
                    pms[k].physique.max_accel_mps2, dt) for k in (0, 1)]
    targets = [(m.x, m.y) for m in movers]
    cxyz = st[0].contact_xyz
    contact = np.array([c[0] * cxyz[0], c[0] * cxyz[1], cxyz[2]])
    t_contact = TOSS_S
    decision = pms[0].choose_shot({"serve_number": serve_number, "side": side}, rng, "serve")
    hitter = 0
    shots: list[SimShot] = []
    flights: list[tuple[float, object]] = []
    end_reason = end_detail = ""
    winner: int | None = None
    t_end = t_contact
    for k in (0, 1):  # both wait in their stances for the serve
        movers[k].run_to(int(round(t_contact * fps)), *targets[k])

    for _ in range(MAX_SHOTS):
        is_serve = not shots
        target = (c[hitter] * decision.place_xy[0], c[hitter] * decision.place_xy[1])
        vel, speed = _launch(contact, target, decision, surface)
        flight = physics.fly(contact, vel, SPIN_MPS.get(decision.spin, 0.0), surface,
                             FLIGHT_T_MAX_S, max_bounces=2)
        shot = SimShot(hitter, t_contact, decision, contact.copy(), target, speed)
        shots.append(shot)
        flights.append((t_contact, flight))
        opp = 1 - hitter
        bounces = [e for e in flight.events if e.kind == "bounce"]
        first = flight.events[0] if flight.events else None
        if first is not None and first.kind == "bounce":
            shot.bounce_xy = (float(first.pos_m[0]), float(first.pos_m[1]))
        if is_serve:
            landed_in = shot.bounce_xy is not None and bool(court.is_in_service_box(
                *shot.bounce_xy, server_end, side))
        else:
            landed_in = shot.bounce_xy is not None and bool(court.is_in_singles(
                *shot.bounce_xy, ends[opp]))
        if not landed_in:
            shot.outcome = "error"
            end_detail = "out" if shot.bounce_xy is not None else "net"
            t_end = t_contact + (first.t_s if first is not None else flight.t_s[-1])
            if is_serve:
                shot.error_kind = "fault"
                end_reason = "fault" if serve_number == 1 else "double_fault"
                winner = None if serve_number == 1 else 1
            else:
                shot.error_kind = decision.error_kind
                end_reason, winner = f"{decision.error_kind}_error", opp
            break

        # The hitter recovers; the opponent reacts, then looks for a reachable contact.
        own_frame = c[hitter] * np.array([movers[hitter].x, movers[hitter].y])
        _, rec = pms[hitter].recover(is_serve, int(region(*own_frame)), decision.place_xy[1],
                                     rng)
        targets[hitter] = (c[hitter] * rec[0], c[hitter] * rec[1])
        react = RETURN_REACTION_S if is_serve else pms[opp].physique.reaction_s
        k_react = int(math.floor((t_contact + react) * fps))
        for k in (0, 1):
            movers[k].run_to(max(k_react, movers[k].n_frames - 1), *targets[k])
        t_stop = bounces[1].t_s if len(bounces) > 1 else float(flight.t_s[-1])
        hit = _intercept(flight, k_react * dt - t_contact, t_stop, bounces[0].t_s, movers[opp],
                         ends[opp], pms[opp])
        next_decision = None
        if hit is not None:
            tau, ball, volley = hit
            t_next = t_contact + tau
            k_next = max(int(round(t_next * fps)), k_react)
            lead = k_next - movers[hitter].n_frames + 1
            hitter_then = movers[hitter].position_after(lead, *targets[hitter])
            opp_at_hit = c[opp] * np.asarray(movers[opp].track[int(round(t_contact * fps))])
            ball_f = c[opp] * ball[:2]
            # The state as the shot table reads it, with the contact point standing in for the
            # player's own position (he will stand an arm's length beside it).
            state = {
                "own_region": int(region(*ball_f)),
                "opp_region": int(region(*(c[hitter] * hitter_then))),
                "in_start_region": int(region(*(c[hitter] * contact[:2]))),
                "in_bounce_region": (NO_REGION if volley else
                                     int(bounce_region(*(c[opp] * np.array(shot.bounce_xy))))),
                "speed_bin": int(speed_bin(np.hypot(*(ball_f - opp_at_hit)) / max(tau, dt))),
            }
            fh = float(court.forehand_side_sign(ends[opp], pms[opp].handedness))
            allowed = _allowed(pms[opp], volley, float(ball[2]),
                               fh * (ball[1] - movers[opp].y))
            next_decision = pms[opp].choose_shot(state, rng, "rally", allowed)
            # Stand beside the ball on the side of the chosen stroke.
            on_fh = next_decision.stroke in ("forehand", "forehand_volley", "overhead")
            spot = (ball[0], ball[1] - (fh if on_fh else -fh) * pms[opp].physique.contact_offset_m)
            movers[opp].run_to(k_next, *spot, hurry=True)
            movers[hitter].run_to(k_next, *targets[hitter])
            gap = math.hypot(movers[opp].x - ball[0], movers[opp].y - ball[1])
            if gap > pms[opp].physique.reach_m + REACH_TOLERANCE_M:
                hit = None  # the run fell short: the ball passes
        if hit is None:
            shot.outcome = "winner"
            end_reason = "ace" if is_serve else "winner"
            end_detail, winner = "unreached", hitter
            t_end = t_contact + min(t_stop, float(flight.t_s[-1]))
            break
        contact, hitter, decision, t_contact = ball, opp, next_decision, t_next
    else:  # an endless rally: stopped as an unforced error of the last hitter
        end_reason, end_detail, winner = "unforced_error", "out", 1 - shots[-1].hitter
        shots[-1].outcome, shots[-1].error_kind = "error", "unforced"
        t_end = t_contact + 1.0

    n_frames = int(math.ceil((t_end + AFTER_END_S) * fps)) + 1
    for m in movers:
        m.run_to(max(n_frames - 1, m.n_frames - 1), *m.stop_point())
    players = np.stack([m.as_array()[:n_frames] for m in movers])
    t = np.arange(n_frames) * dt
    ball = _ball_track(t, shots[0].contact_m, flights)
    contact_frames = np.round(np.array([s.t_s for s in shots]) * fps)
    frame_shot = np.maximum(np.searchsorted(contact_frames, np.arange(n_frames), "right") - 1, 0)
    for s in shots:
        s.direction = _direction(s, pms[s.hitter].handedness)
    serve_kmh = shots[0].speed_mps * KMH_PER_MPS
    length = sum(s.outcome in ("in_play", "winner") for s in shots)
    return SimRally(end_reason, end_detail, winner, shots, ball, players, frame_shot, length,
                    serve_kmh)


def _direction(s: SimShot, handedness: str) -> str:
    land = s.bounce_xy if s.bounce_xy is not None else s.target_xy
    if s.decision.stroke == "serve":
        return str(court.serve_zone(land[1]))
    return str(court.shot_direction(s.contact_m[0], s.contact_m[1], land[0], land[1],
                                    handedness, s.decision.stroke))


def _ball_track(t: np.ndarray, serve_contact: np.ndarray,
                flights: list[tuple[float, object]]) -> np.ndarray:
    """The toss (a ball falling from 0.5 m above the serve contact), then each flight until the
    next contact; after the last flight the ball rests where it ended, inside the fence."""
    out = np.empty((len(t), 3))
    t0 = flights[0][0]
    toss = t < t0
    apex = math.sqrt(2 * 0.5 / physics.GRAVITY_MPS2)     # the ball peaks 0.5 m above contact
    out[toss, 0], out[toss, 1] = serve_contact[0], serve_contact[1]
    out[toss, 2] = np.maximum(serve_contact[2] + 0.5 - 0.5 * physics.GRAVITY_MPS2 *
                              (t[toss] - (t0 - apex)) ** 2, 1.0)
    starts = [s for s, _ in flights] + [np.inf]
    for i, (ts, flight) in enumerate(flights):
        sel = (t >= ts) & (t < starts[i + 1])
        tau = np.minimum(t[sel] - ts, float(flight.t_s[-1]))
        out[sel] = flight.at(tau)
    out[:, 0] = np.clip(out[:, 0], -FENCE_X_M, FENCE_X_M)
    out[:, 1] = np.clip(out[:, 1], -FENCE_Y_M, FENCE_Y_M)
    out[:, 2] = np.maximum(out[:, 2], physics.BALL_RADIUS_M)
    return out


def simulate_points(model: ShotCycleModel, server: str, receiver: str, surface: str,
                    n_points: int, seed: int, fmt: MatchFormat | None = None,
                    fps: float = FPS_DEFAULT) -> RallyData:
    """`n_points` points between `server` (serves first) and `receiver`, scored by
    `MatchState` (matches follow one another until the points are played), as a validated
    `RallyData`. Deterministic for a seed."""
    if n_points <= 0:
        raise ValueError(f"n_points must be positive, got {n_points}")
    rng = np.random.default_rng(seed)
    fmt = fmt or MatchFormat()
    names = (server, receiver)
    rallies, shots, frames = [], [], []
    played, match = 0, 0
    state = MatchState.new(fmt, first_server=0)
    while played < n_points:
        if state.is_over:
            match, state = match + 1, MatchState.new(fmt, first_server=0)
        played += 1
        srv = state.server
        base = {"match_id": f"shotcycle-{match:06d}", "point": state.points_played + 1,
                "server": names[srv], "receiver": names[1 - srv], "side": state.serving_side,
                "server_end": state.ends[srv], "surface": surface, "tournament": TOURNAMENT,
                **score_row(state, srv)}
        for n in (1, 2):
            res = play_rally(model, names[srv], names[1 - srv], state.ends[srv],
                             state.serving_side, n, surface, rng, fps)
            rid = len(rallies)
            role_name = (names[srv], names[1 - srv])
            rallies.append({"rally_id": rid, **base, "serve_number": n,
                            "winner": "" if res.winner_role is None else role_name[
                                res.winner_role],
                            "end_reason": res.end_reason, "end_detail": res.end_detail,
                            "serve_kmh": res.serve_kmh, "rally_length": res.rally_length})
            shots.extend(_shot_rows(rid, res, role_name, fps))
            frames.append(_frame_block(rid, res, role_name, fps))
            if res.end_reason != "fault":
                break
        state = state.point_won(srv if res.winner_role == 0 else 1 - srv)
    meta = {"generator": "sportsngen.baselines.shot_cycle_sim", "seed": int(seed),
            "n_points": int(n_points)}
    return RallyData.from_tables(pd.concat(frames, ignore_index=True),
                                 pd.DataFrame(rallies, columns=list(RALLY_COLUMNS)),
                                 pd.DataFrame(shots, columns=list(SHOT_COLUMNS)), fps=fps,
                                 meta=meta)


def _shot_rows(rid: int, res: SimRally, names: tuple[str, str], fps: float) -> list[dict]:
    rows = []
    for k, s in enumerate(res.shots):
        bx, by = s.bounce_xy if s.bounce_xy is not None else (np.nan, np.nan)
        rows.append({"rally_id": rid, "shot_index": k, "frame": int(round(s.t_s * fps)),
                     "hitter": names[s.hitter], "stroke": s.decision.stroke,
                     "spin": s.decision.spin, "direction": s.direction, "outcome": s.outcome,
                     "error_kind": s.error_kind, "contact_x": s.contact_m[0],
                     "contact_y": s.contact_m[1], "contact_z": s.contact_m[2],
                     "speed_mps": s.speed_mps, "bounce_x": bx, "bounce_y": by})
    return rows


def _frame_block(rid: int, res: SimRally, names: tuple[str, str], fps: float) -> pd.DataFrame:
    n = len(res.ball_m)
    idx = res.frame_shot
    lab = {k: np.array([getattr(s, a) if a else s.decision.stroke for s in res.shots],
                       dtype=object)[idx]
           for k, a in (("stroke", None), ("direction", "direction"), ("outcome", "outcome"),
                        ("error_kind", "error_kind"))}
    xyz = np.concatenate([res.ball_m, np.column_stack([res.players_m[0], np.zeros(n)]),
                          np.column_stack([res.players_m[1], np.zeros(n)])])
    frame = np.arange(n)
    return pd.DataFrame({
        "rally_id": np.full(3 * n, rid, dtype=np.int64), "frame": np.tile(frame, 3),
        "t": np.tile(frame / fps, 3),
        "object": np.repeat(np.array(["ball", names[0], names[1]], dtype=object), n),
        "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2],
        **{k: np.tile(v, 3) for k, v in lab.items()}}).loc[:, list(FRAME_COLUMNS)]
