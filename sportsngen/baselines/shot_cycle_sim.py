"""Rally simulator driven by the shot-cycle model: decisions from the fitted distributions,
flight, movement and outcomes from the shot-cycle kernel (`synth.cycle`) the generator uses too.
Output: a `RallyData` like the generator's.

`ModelPolicy` answers the kernel's questions with the fitted model: the serve and each shot
(shot type, speed, placement, or a ball into the net) from `PlayerModel.choose_shot`, the
recovery from `PlayerModel.recover`, where to stand at a contact from the chosen stroke's side
and the player's usual contact offset. The kernel launches the decision so that it lands on the
drawn placement (`cycle.launch`), flies it, lets the opponent react and search the flight for a
contact he can reach (his fitted speed, acceleration and reach), and ends the point when the ball
is out, in the net or unreached. Outcomes therefore emerge from the drawn placements and the
physics, as in the generator, while every decision is the model's.

Assumptions the data cannot give: spin rates per spin label (`SPIN_MPS`), reaction times
(`Physique.reaction_s`, `RETURN_REACTION_S`), the toss, and the contact height window.
"""

from __future__ import annotations

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
from sportsngen.data.points import score_row
from sportsngen.data.tracking import (
    FPS_DEFAULT,
    FRAME_COLUMNS,
    RALLY_COLUMNS,
    SHOT_COLUMNS,
    RallyData,
)
from sportsngen.synth import cycle
from sportsngen.synth.cycle import Body, Intercept, RallyResult, Shot, ShotPlan
from sportsngen.tennis import court
from sportsngen.tennis.scoring import MatchFormat, MatchState

SPIN_MPS = {"none": 0.0, "flat": 0.0, "topspin": 6.0, "slice": -4.0, "kick": 7.0}
RETURN_REACTION_S = 0.1     # returners read the toss: shorter than the rally reaction
OVERHEAD_Z_M = 2.3
NO_CONTACT_DEPTH_PREFERENCE_M = 30.0   # the fitted model has no preferred contact depth
TOURNAMENT = "shot_cycle_sim"


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


class ModelPolicy:
    """The fitted model's decisions for one rally (roles 0 server, 1 receiver). Positions go
    to a player's own frame (his baseline at x < 0) by multiplying by `self.c[role]`."""

    def __init__(self, model: ShotCycleModel, server: str, receiver: str, server_end: int,
                 serving_side: str, serve_number: int, surface: str) -> None:
        self.server_end, self.serving_side = server_end, serving_side
        self.serve_number, self.surface = serve_number, surface
        self.c = (-float(server_end), float(server_end))
        self.ends = (server_end, -server_end)
        self.pms = (model.player_model(server, receiver), model.player_model(receiver, server))
        self.stances = (_stance(model, server, "server", serve_number, serving_side),
                        _stance(model, receiver, "receiver", serve_number, serving_side))
        self.bodies = tuple(Body(pm.physique.max_speed_mps, pm.physique.max_accel_mps2,
                                 pm.physique.reach_m, pm.physique.contact_z_m,
                                 NO_CONTACT_DEPTH_PREFERENCE_M) for pm in self.pms)
        self.decision: list[ShotDecision | None] = [None, None]
        self.at_contact = [np.zeros(2), np.zeros(2)]   # where each stood at his last contact

    def _shot_plan(self, role: int, d: ShotDecision) -> ShotPlan:
        c = self.c[role]
        return ShotPlan(target_x_m=c * d.place_xy[0], target_y_m=c * d.place_xy[1],
                        speed_mps=d.speed_mps, spin_mps=SPIN_MPS.get(d.spin, 0.0),
                        stroke=d.stroke, spin_label=d.spin, direction="none", noise_deg=0.0,
                        net_clearance_m=0.0, into_net=d.result == "net",
                        error_kind=d.error_kind)

    def serve(self, rng: np.random.Generator):
        c = self.c
        srv, rcv = self.stances
        stance_s = (c[0] * srv.xy[0], c[0] * srv.xy[1])
        stance_r = (c[1] * rcv.xy[0], c[1] * rcv.xy[1])
        cx, cy, cz = srv.contact_xyz
        self.at_contact[0] = np.array(stance_s)
        d = self.pms[0].choose_shot({"serve_number": self.serve_number,
                                     "side": self.serving_side}, rng, "serve")
        return stance_s, stance_r, np.array([c[0] * cx, c[0] * cy, cz]), self._shot_plan(0, d)

    def reaction_s(self, role: int, to_serve: bool) -> float:
        return RETURN_REACTION_S if to_serve else self.pms[role].physique.reaction_s

    def recovery(self, hitter: int, plan: ShotPlan | None, landed_in: bool,
                 rng: np.random.Generator,
                 shape_rng: np.random.Generator) -> tuple[float, float]:
        c = self.c[hitter]
        own = c * self.at_contact[hitter]
        place_y = c * plan.target_y_m if plan is not None else 0.0
        _, rec = self.pms[hitter].recover(plan is not None and plan.stroke == "serve",
                                          int(region(*own)), place_y, rng)
        return c * rec[0], c * rec[1]

    def can_volley(self, role: int, pos_m: np.ndarray) -> bool:
        pm = self.pms[role]
        return abs(float(pos_m[0])) < PLAYER_FRONT_X_M and \
            bool(pm.strokes & {"forehand_volley", "backhand_volley"})

    def prepare(self, role: int, hit: Intercept, pos_m: np.ndarray, opponent_m: np.ndarray,
                incoming: Shot, rng: np.random.Generator,
                shape_rng: np.random.Generator) -> tuple[float, float]:
        pm, c, ball = self.pms[role], self.c[role], hit.ball_m
        fh = float(court.forehand_side_sign(self.ends[role], pm.handedness))
        offset = pm.physique.contact_offset_m
        if not hit.reachable:  # he goes for it on his forehand side; no decision to draw
            return float(ball[0]), float(ball[1] - fh * offset)
        # The state as the shot table reads it, with the contact point standing in for the
        # player's own position (he will stand an arm's length beside it).
        ball_f = c * ball[:2]
        bounce = incoming.bounce_xy
        state = {
            "own_region": int(region(*ball_f)),
            "opp_region": int(region(*(-c * np.asarray(opponent_m)))),
            "in_start_region": int(region(*(-c * incoming.contact_m[:2]))),
            "in_bounce_region": (NO_REGION if hit.volley or bounce is None else
                                 int(bounce_region(*(c * np.asarray(bounce))))),
            "speed_bin": int(speed_bin(np.hypot(*(ball_f - c * np.asarray(pos_m)))
                                       / max(hit.t_s, 1e-3))),
        }
        allowed = _allowed(pm, hit.volley, float(ball[2]), fh * (ball[1] - pos_m[1]))
        d = pm.choose_shot(state, rng, "rally", allowed)
        self.decision[role] = d
        on_fh = d.stroke in ("forehand", "forehand_volley", "overhead")
        spot = (float(ball[0]), float(ball[1] - (fh if on_fh else -fh) * offset))
        self.at_contact[role] = np.array(spot)
        return spot

    def plan(self, role: int, hit: Intercept, opponent_m: np.ndarray, n_shots: int,
             rng: np.random.Generator) -> ShotPlan:
        return self._shot_plan(role, self.decision[role])


def play_rally(model: ShotCycleModel, server: str, receiver: str, server_end: int, side: str,
               serve_number: int, surface: str, rng: np.random.Generator,
               fps: float = FPS_DEFAULT) -> RallyResult:
    """One rally (one serve and what follows). Roles: 0 server, 1 receiver."""
    policy = ModelPolicy(model, server, receiver, server_end, side, serve_number, surface)
    res = cycle.play(policy, rng, fps=fps, noise=False)
    for s in res.shots:
        s.direction = _direction(s, policy.pms[s.hitter].handedness)
    return res


def _direction(s: Shot, handedness: str) -> str:
    land = s.bounce_xy if s.bounce_xy is not None else s.target_xy
    if s.stroke == "serve":
        return str(court.serve_zone(land[1]))
    return str(court.shot_direction(s.contact_m[0], s.contact_m[1], land[0], land[1],
                                    handedness, s.stroke))


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


def _shot_rows(rid: int, res: RallyResult, names: tuple[str, str], fps: float) -> list[dict]:
    rows = []
    for k, s in enumerate(res.shots):
        bx, by = s.bounce_xy if s.bounce_xy is not None else (np.nan, np.nan)
        rows.append({"rally_id": rid, "shot_index": k, "frame": int(round(s.t_s * fps)),
                     "hitter": names[s.hitter], "stroke": s.stroke,
                     "spin": s.spin, "direction": s.direction, "outcome": s.outcome,
                     "error_kind": s.error_kind, "contact_x": s.contact_m[0],
                     "contact_y": s.contact_m[1], "contact_z": s.contact_m[2],
                     "speed_mps": s.speed_mps, "bounce_x": bx, "bounce_y": by})
    return rows


def _frame_block(rid: int, res: RallyResult, names: tuple[str, str],
                 fps: float) -> pd.DataFrame:
    n = len(res.ball_m)
    idx = res.frame_shot
    lab = {k: np.array([getattr(s, k) for s in res.shots], dtype=object)[idx]
           for k in ("stroke", "direction", "outcome", "error_kind")}
    xyz = np.concatenate([res.ball_m, np.column_stack([res.players_m[0], np.zeros(n)]),
                          np.column_stack([res.players_m[1], np.zeros(n)])])
    frame = np.arange(n)
    return pd.DataFrame({
        "rally_id": np.full(3 * n, rid, dtype=np.int64), "frame": np.tile(frame, 3),
        "t": np.tile(frame / fps, 3),
        "object": np.repeat(np.array(["ball", names[0], names[1]], dtype=object), n),
        "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2],
        **{k: np.tile(v, 3) for k, v in lab.items()}}).loc[:, list(FRAME_COLUMNS)]
