"""Decisions of a player in the shot cycle: serve, return and rally shots, recovery position.

Pure functions of the profile, the geometry and a numpy Generator. They say *what* the player
tries (target, speed, spin, stroke) and how precisely (execution noise); `rally.py` then flies the
ball with the physics and lets the outcome emerge (a ball into the net or out is an error, a ball
the opponent cannot reach is a winner).

Geometry reminders (project frame): a player's `end` is the sign of x of his baseline; he faces
-end * x. Facing +x the right hand points to -y, so a right-hander's forehand side has y sign
`end` and the server's deuce side is y sign `end` too (his right of the centre mark).
"""

from __future__ import annotations

import math

import numpy as np

from sportsngen.synth.profiles import PlayerProfile
from sportsngen.synth.shot import ShotPlan
from sportsngen.tennis import court
from sportsngen.tennis.court import BASELINE_X_M, SERVICE_LINE_X_M, SINGLES_HALF_WIDTH_M

SERVE_DEPTH_MARGIN_M = 0.9  # first serves are aimed this far inside the service line
SECOND_SERVE_DEPTH_MARGIN_M = 1.4  # second serves, with their bigger margin for error
# Players stand and meet the ball deeper on slow courts (Hawk-Eye: the same players return and
# rally from further back on clay than on hard courts).
SURFACE_DEPTH_M = {"hard": 0.0, "clay": 0.3, "grass": -0.3}
# A neutral rally ball to a side is aimed this far inside the sideline (less when attacking):
# at real rally pace (31-35 m/s) a narrower margin makes every tenth ball a winner.
SIDE_MARGIN_M = 3.0
RETURN_SPIN_FACTOR = 0.4     # returns are flatter (blocked, sliced) than rally balls
RETURN_SIDE_SHARE = 0.5      # returns go cross or down the line this often against rally balls
# Least height over the cord a player allows his ball (at least a, plus b times how safe he
# plays, 1 - aggression): a floor, not the typical height (real p10 of rally balls: 0.2 m).
NET_CLEARANCE_M = (0.05, 0.25)
# A return is rushed (the serve's weight shows: the returner's `rushed_return_noise` times the
# aim noise, and the depth and width of a reply to a hard ball) with chance
# 1 - difficulty^-RUSHED_RETURN_EXPONENT, else clean; a heavier serve rushes more returns rather
# than scattering every one of them (real returns cross the net at 1.7-2.1 m, 90 % below
# 2.3-3.5 m).
RUSHED_RETURN_EXPONENT = 0.5
# How much of a serve's weight (the server's `serve_heaviness`) a surface passes on, as a power:
# clay's slow, high bounce gives the returner time. Hawk-Eye (AO 2020 against RG 2019-2020):
# service points ending at the serve or its return fall from 0.32 to 0.22 of the ATP's (0.34 to
# 0.23 for Djokovic, 0.30 to 0.22 for Nadal) and rallies grow by 0.6 shots; with the same weight
# on both surfaces the generated ones fell only 0.04 and grew 0.2. Grass stays at hard's: the
# 2011 serving figures the weights are calibrated to mix US Open and Wimbledon.
SURFACE_SERVE_WEIGHT = {"hard": 1.0, "clay": 0.7, "grass": 1.0}
SERVE_ZONES = ("wide", "body", "T")
KMH_PER_MPS = 3.6


def deuce_sign(server_end: int, serving_side: str) -> int:
    """Sign of y of the server's half of the court (the side he serves from)."""
    if serving_side not in ("deuce", "ad"):
        raise ValueError(f"serving_side must be 'deuce' or 'ad', got {serving_side!r}")
    return server_end if serving_side == "deuce" else -server_end


# -- serve ---------------------------------------------------------------------------------------

def serve_stance(server_end: int, serving_side: str) -> tuple[float, float]:
    """Where the server stands: just behind the baseline, near the centre mark."""
    return server_end * (BASELINE_X_M + 0.2), deuce_sign(server_end, serving_side) * 0.8


def return_stance(p: PlayerProfile, server_end: int, serving_side: str,
                  serve_number: int, surface: str) -> tuple[float, float]:
    """Where the returner waits: `return_depth_m` (second serves: `second_return_depth_m`)
    behind the baseline, deeper on slow courts, in line with the middle of the box the serve
    is aimed at."""
    s = -deuce_sign(server_end, serving_side)
    return -server_end * (BASELINE_X_M + return_depth_m(p, serve_number, surface)), s * 3.0


def return_depth_m(p: PlayerProfile, serve_number: int, surface: str) -> float:
    """How far behind his baseline the returner waits for, and likes to meet, the serve."""
    depth = p.return_depth_m if serve_number == 1 else p.second_return_depth_m
    return depth + SURFACE_DEPTH_M[surface]


def rally_depth_m(p: PlayerProfile, surface: str) -> float:
    """How far behind his baseline the player recovers to and likes to meet rally balls."""
    return p.recovery_depth_m + SURFACE_DEPTH_M[surface]


def plan_serve(p: PlayerProfile, server_end: int, serving_side: str, serve_number: int,
               rng: np.random.Generator) -> ShotPlan:
    """Placement, speed and spin of a serve. First serves: the player's wide/body/T mix, aimed
    `serve_margin_m` inside the lines; second serves: kick, bigger margins, mostly to the body
    and the backhand corner."""
    s = -deuce_sign(server_end, serving_side)  # y sign of the target box
    if serve_number == 1:
        zone = SERVE_ZONES[rng.choice(3, p=p.serve_mix)]
        margin = p.serve_margin_m
        kmh = p.first_serve_kmh + p.first_serve_kmh_sd * rng.standard_normal()
        spin, label, noise = p.first_serve_spin_mps, "flat", p.first_serve_noise_deg
    else:
        zone = SERVE_ZONES[rng.choice(3, p=(0.35, 0.35, 0.3))]
        margin = p.serve_margin_m + 0.35
        kmh = p.second_serve_kmh + p.second_serve_kmh_sd * rng.standard_normal()
        spin, label, noise = p.second_serve_spin_mps, "kick", p.second_serve_noise_deg
        if spin < 0:
            label = "slice"
    lateral = {"wide": SINGLES_HALF_WIDTH_M - margin, "body": 2.0, "T": margin}[zone]
    depth = SERVICE_LINE_X_M - (SERVE_DEPTH_MARGIN_M if serve_number == 1 else
                                SECOND_SERVE_DEPTH_MARGIN_M)
    return ShotPlan(target_x_m=-server_end * depth, target_y_m=s * lateral,
                    speed_mps=max(kmh, 60.0) / KMH_PER_MPS, spin_mps=spin, stroke="serve",
                    spin_label=label, direction=zone, noise_deg=noise, net_clearance_m=0.05)


# -- rally shots ---------------------------------------------------------------------------------

def choose_stroke(p: PlayerProfile, end: int, player_y: float, ball_y: float,
                  ball_z: float, volley: bool) -> str:
    """Forehand or backhand by the side the ball is on (with some running around the backhand
    according to `forehand_preference`), volley before the bounce, overhead when high."""
    if volley and ball_z > 2.3:
        return "overhead"
    f = int(court.forehand_side_sign(end, p.handedness))
    forehand = (ball_y - player_y) * f > -0.6 * p.forehand_preference
    if volley:
        return "forehand_volley" if forehand else "backhand_volley"
    return "forehand" if forehand else "backhand"


def plan_rally_shot(p: PlayerProfile, end: int, stroke: str, contact_xyz: np.ndarray,
                    duress: float, opponent_xy: np.ndarray, opponent_at_net: bool,
                    is_return: bool, incoming_difficulty: float,
                    rng: np.random.Generator) -> ShotPlan:
    """Target, speed, spin and noise of a return or rally shot.

    `duress` in [0, 1] is the share of the player's movement capacity the ball demanded: under
    duress the player aims safer (middle, deeper margin), hits slower and misses more. A short
    ball (contact well inside the baseline) invites aggression. `incoming_difficulty` (the
    server's `serve_heaviness` on a return, the opponent's `rally_pressure` in a rally) above 1
    raises the execution noise a little and makes the reply shorter, slower and more central:
    an attackable ball. On a return it does so only when the return is rushed (see
    `RUSHED_RETURN_EXPONENT`).
    """
    cx, cy, cz = (float(v) for v in contact_xyz)
    difficulty = max(incoming_difficulty, 0.05)
    rushed = is_return and rng.random() < 1.0 - difficulty ** -RUSHED_RETURN_EXPONENT
    if is_return and not rushed:
        difficulty = 1.0  # a clean return: the serve's weight does not show
    short_ball = abs(cx) < BASELINE_X_M - 2.5 and duress < 0.5
    style = p.aggression * (1.0 - 0.7 * duress) * (0.5 if is_return else 1.0)
    # A short ball taken comfortably is attacked: nearer the lines and faster (the noise
    # follows the player's style, not the attack).
    aggr = min(max(style + (0.3 if short_ball else 0.0), 0.0), 1.0)
    f = int(court.forehand_side_sign(end, p.handedness))

    # Direction, relative to the hitter's lateral position (the stroke side near the middle).
    ref = np.sign(cy) if abs(cy) > 1.0 else (f if stroke.startswith("forehand") else -f)
    u = rng.random() / (RETURN_SIDE_SHARE if is_return else 1.0)
    if u < p.cross_court * (1.0 - 0.3 * duress):
        side = -ref                                   # cross court
    elif u < p.cross_court + p.down_the_line * (1.0 - 0.5 * duress):
        side = ref                                    # down the line
    else:
        side = 0.0                                    # middle
    if opponent_at_net and side == 0.0:
        side = -ref  # pass, don't hit at the volleyer

    side_margin = max(SIDE_MARGIN_M - 1.1 * aggr + 0.4 * duress, 0.8)
    # A heavy incoming ball (difficulty > 1) also makes the reply land shorter and slower.
    depth_margin = p.rally_depth_margin_m - 0.9 * aggr + 0.6 * duress + \
        0.6 * max(math.log(difficulty), 0.0)
    depth_margin = min(max(depth_margin, 1.5), 6.0)
    if side == 0.0:
        y = 0.6 * rng.standard_normal()
    else:
        y = side * (SINGLES_HALF_WIDTH_M - side_margin) * min(difficulty ** -0.3, 1.0)
    x = -end * (BASELINE_X_M - depth_margin)

    lob = False
    speed = p.rally_speed_mps * (0.88 + 0.35 * aggr) * (1.0 - 0.3 * duress)
    if is_return:
        speed *= p.return_pace
    spin, spin_label = p.topspin_mps * (RETURN_SPIN_FACTOR if is_return else 1.0), "topspin"
    volley = stroke.endswith("volley")
    if stroke == "overhead":
        speed, spin, spin_label = p.rally_speed_mps * 1.15, 0.0, "flat"
    elif volley:
        speed, spin, spin_label = p.rally_speed_mps * 0.75, 0.5 * p.slice_spin_mps, "slice"
        x = -end * (BASELINE_X_M - depth_margin - 1.0 + 2.0 * rng.random())
    elif stroke == "backhand" and (rng.random() < p.slice_share or duress > 0.85):
        speed, spin, spin_label = speed * 0.85, p.slice_spin_mps, "slice"
    if opponent_at_net and not volley and stroke != "overhead" and rng.random() < 0.2:
        lob, speed, spin, spin_label = True, 0.6 * speed, p.topspin_mps, "topspin"
        x, y = -end * (BASELINE_X_M - 1.5), 0.5 * y
    # A heavy ball slows the reply, except a return: the returner borrows the serve's pace.
    speed *= (1.0 + 0.04 * rng.standard_normal()) * (1.0 if is_return else difficulty ** -0.2)

    base = p.return_noise_deg if is_return else p.rally_noise_deg
    weight = p.rushed_return_noise if rushed else difficulty ** 0.8
    noise = base * weight * (1.0 + 1.3 * duress) * (0.75 + 0.5 * style)
    clearance = NET_CLEARANCE_M[0] + NET_CLEARANCE_M[1] * (1.0 - aggr)
    # The label follows the project's definition (court.shot_direction) of the intended shot.
    direction = str(court.shot_direction(cx, cy, x, y, p.handedness, stroke))
    return ShotPlan(target_x_m=x, target_y_m=float(y), speed_mps=float(speed),
                    spin_mps=float(spin), stroke=stroke, spin_label=spin_label,
                    direction=direction, noise_deg=float(noise), net_clearance_m=clearance,
                    lob=lob)


def error_kind(duress: float, is_return: bool) -> str:
    """An error under duress is forced; from a comfortable position it is unforced."""
    return "forced" if duress >= (0.35 if is_return else 0.5) else "unforced"


def recovery_target(p: PlayerProfile, end: int, shot_target_y_m: float,
                    at_net: bool, surface: str) -> tuple[float, float]:
    """Where the hitter recovers after his shot: behind his baseline (`rally_depth_m`, or at
    the net after an approach), shaded toward his own target (the bisector of the reply
    angles) and offset toward the backhand side by the player's habit."""
    backhand = -int(court.forehand_side_sign(end, p.handedness))
    if at_net:
        return end * 2.6, 0.45 * shot_target_y_m
    y = 0.35 * shot_target_y_m + backhand * p.recovery_backhand_offset_m
    return end * (BASELINE_X_M + rally_depth_m(p, surface)), y
