"""What a player could see of the ball a reaction time before he moves: where its flight, as
seen then, will land against the lines (`seen_flight`) and how far aside it will pass him
(`seen_reach`). The leak check (`sportsngen.eval.leaks`) compares only contacts that looked
alike in these terms, so that a player who reacts to a ball he saw is not read as one who
knows the outcome.

The seen flight (`seen_flight`): the ball's position, velocity and acceleration at frame
``at_frame - SEEN_LAG_S`` (for a serve's receiver ``at_frame - SEEN_RETURN_LAG_S``: returners
read a serve sooner) from three frames of its track after the contact, flown on to its
bounce (`predict_flight`); the code is the bin in `SEEN_MARGIN_BINS_M` of the bounce's
distance inside the target (the service box of a serve, the singles court beyond the net of a
rally shot), at most the "close" bin for a ball seen within `SEEN_NET_MARGIN_M` of the
cord, `SEEN_NET` for one seen going into the net (further below the cord) or landing short of
it, and `SEEN_NONE` where fewer than three tracked frames lie between the contact and the seen
frame.
The bins are wide on purpose: a player reads "clearly long" from the flight, not a ball that
lands 10 cm out, and noisy tracking (the acceleration is a second difference) blurs the
extrapolation. The price: a fault lies beyond the line by definition, so in the "close" bin
faults meet ins that came elsewhere, and movement that varies smoothly with where the ball
comes can pass for a leak (`docs/synthetic-data.md`, the receiver before faults).

The seen pace (`seen_pace`): the bin in `SEEN_PACE_BINS_MPS` of the ball's seen speed, the
hitter's own ball as he saw it leave (his cells only). A server may run back slower after a
harder serve, and a harder serve is more often an ace: he saw the pace, not the outcome.

The seen width (`seen_width`): the bin in `SEEN_WIDTH_BINS_M` of how far across the court the
hitter saw his ball go, the sideways distance from the contact to its seen bounce (his cells
only). A hitter recovers toward the middle of the replies his ball allows, so after a ball sent
far across he runs further, and such balls are more often winners: he saw where he hit it. The
leak check reads it after rally shots only: a serve's width is its direction label's.

The seen reach (`seen_reach`): the seen bounce carried on along the ball's seen horizontal
direction to the opponent's depth at the seen frame, and the bin in `SEEN_REACH_BINS_M` of
its sideways distance from him there (`SEEN_NONE` where the flight is not seen or is seen into
the net).
"""

from __future__ import annotations

import numpy as np

from sportsngen.tennis.court import (
    BALL_RADIUS_M,
    BASELINE_X_M,
    SERVICE_LINE_X_M,
    SINGLES_HALF_WIDTH_M,
    net_height_m,
)
from sportsngen.tennis.rally import GRAVITY_MPS2

SEEN_LAG_S = 0.2     # a player's reaction time: he acts at frame t on the flight seen by then
# A serve's receiver reads it sooner: returners anticipate from the toss and the racket, and
# the generator's (causal) returners move from its floor, `synth.rally.MIN_RETURN_REACTION_S`.
# With the 0.2 s lag the check held nothing of the serve 6 frames on, while both the
# generator's and the model's receivers already ran to the serve's side from the third frame:
# the bundled model's receiver read 0.606 at k = 6 on its own serves (1,200 points), 0.572
# with this; the generator's receiver before unseen faults, 12 frames on, 0.36 / 0.36 on two
# 10,000-point samples, 0.45 / 0.46 with this (docs/evaluation.md, sixty-eighth part).
SEEN_RETURN_LAG_S = 0.08
# Bounce inside the target by: clearly out, close, in, well in. Narrower bins at the lines
# (a +-0.2 m bin) were tried for the receiver before faults (module doc): on two 10,000-point
# samples his speed 12 frames on gave AUC 0.46 and 0.24 against 0.34 and 0.35 with these, on a
# third of the comparable pairs: noisier, not steadier.
SEEN_MARGIN_BINS_M = (-0.5, 0.5, 2.0)
SEEN_NET_MARGIN_M = 0.2  # seen crossing the cord within this: close; further below: net
SEEN_NONE, SEEN_NET = -1, len(SEEN_MARGIN_BINS_M) + 1
SEEN_ON_LINE = int(np.digitize(0.0, SEEN_MARGIN_BINS_M))  # the "close" bin: on a line
SEEN_MAX_SPACING_FRAMES = 3  # frames between the three track points of the seen flight
SEEN_MAX_AERO_MPS2 = 60.0    # drag plus Magnus beyond this is tracking noise
SEEN_MAX_SPEEDUP = 1.5       # aerodynamic forces scaled by at most this (a falling lob gains)
SEEN_STEP_S, SEEN_HORIZON_S = 0.01, 4.0  # integration of the seen flight to its bounce
# How far sideways the seen ball passes the opponent: within reach / a stride or two / a run /
# out of reach. Without it a receiver who sprints at a serve passing 3 m from him (more often an
# ace) read as knowing the outcome: the bundled model's rollouts, his speed 12 frames after the
# serve, 0.62 / 0.67 on two 1,200-point samples, 0.52 / 0.55 with it (the generator's, seed
# 0: 0.51 without it, 0.50 with it).
SEEN_REACH_BINS_M = (1.0, 2.0, 3.0)
# How fast the hitter saw his own ball leave: 5 m/s bands of its seen speed. Without it the
# bundled model's server, who runs back a little slower after harder serves (as the record's
# does not), read as knowing the ace: his speed 12 frames after his own serves 0.387 / 0.395
# on two 1,200-point samples, 0.439 / 0.420 with it (the generator's 0.482 / 0.513 -> 0.468 /
# 0.503; docs/evaluation.md, sixty-seventh part).
SEEN_PACE_BINS_MPS = tuple(float(v) for v in range(10, 65, 5))
# How far across the court the hitter saw his ball go (contact to seen bounce, sideways): along
# a line / across / far across / corner to corner. Without it Djokovic v Murray's hitter ran
# faster 12 frames before a rally winner (AUC 0.56 on 10,000 generated points, 0.60 on 800),
# because the generator's hitter recovers to 0.35 of his target's sideways position
# (`synth.behaviour.recovery_target`), as real players recover to the bisector of the replies,
# so the further across he sent it the further he runs (docs/evaluation.md, sixty-ninth part).
SEEN_WIDTH_BINS_M = (2.0, 4.0, 6.0)


def predict_flight(pos_m: np.ndarray, vel_mps: np.ndarray, acc_mps2: np.ndarray,
                   end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where balls seen at `pos_m` with `vel_mps` and `acc_mps2` (N, 3 each) will bounce (N, 2;
    NaN if not within `SEEN_HORIZON_S`) and by how much they clear the net cord (N; +inf if
    already past it or not crossing before the bounce), hit from the court end `end` (N, +-1).

    The acceleration beyond gravity (drag and Magnus) is split into its parts along and across
    the velocity, each scaled with the speed squared as the ball flies on: held constant, the
    drag of a fast ball would stop it metres short over a second's flight."""
    n = len(pos_m)
    grav = np.array([0.0, 0.0, -GRAVITY_MPS2])
    aero = acc_mps2 - grav
    size = np.linalg.norm(aero, axis=1, keepdims=True)
    aero *= np.minimum(size, SEEN_MAX_AERO_MPS2) / np.maximum(size, 1e-9)
    speed0 = np.maximum(np.linalg.norm(vel_mps, axis=1), 1e-6)
    # Drag per (m/s)^2 (never a push: that is noise, and it would grow without bound) ...
    along = np.minimum(np.einsum("ij,ij->i", aero, vel_mps) / speed0 ** 2, 0.0)
    across = aero - along[:, None] * vel_mps                        # ... Magnus at speed0
    p, v = pos_m.astype(np.float64), vel_mps.astype(np.float64)
    land = np.full((n, 2), np.nan)
    clear = np.full(n, np.inf)
    flying = np.ones(n, bool)
    dt = SEEN_STEP_S
    for _ in range(int(round(SEEN_HORIZON_S / dt))):
        ratio = np.minimum(np.linalg.norm(v, axis=1) / speed0, SEEN_MAX_SPEEDUP)
        a = grav + along[:, None] * ratio[:, None] * v + across * (ratio ** 2)[:, None]
        v_next = v + a * dt
        p_next = p + 0.5 * (v + v_next) * dt
        cross = flying & (p[:, 0] * end > 0) & (p_next[:, 0] * end <= 0)
        if cross.any():
            w = (p[cross, 0] / (p[cross, 0] - p_next[cross, 0]))[:, None]
            at = p[cross] + w * (p_next[cross] - p[cross])
            clear[cross] = at[:, 2] - BALL_RADIUS_M - net_height_m(at[:, 1])
        down = flying & (p_next[:, 2] <= BALL_RADIUS_M)
        if down.any():
            w = ((p[down, 2] - BALL_RADIUS_M) /
                 np.maximum(p[down, 2] - p_next[down, 2], 1e-9))[:, None]
            land[down] = (p[down] + w * (p_next[down] - p[down]))[:, :2]
            flying &= ~down
        if not flying.any():
            break
        p, v = p_next, v_next
    return land, clear


def seen_ball(ball_m: np.ndarray, contact: np.ndarray, seen: np.ndarray, row0: np.ndarray,
              track_end: np.ndarray, fps: float) -> dict[str, np.ndarray]:
    """The ball's flight as seen at frame `seen` of each contact (module doc): ``ok`` (three
    tracked frames between the contact and the seen frame), ``vel_mps`` (N, 3) at the seen
    frame, ``land_m`` (N, 2; NaN where not seen or not landing within the horizon), ``clear_m``
    (N; over the cord, +inf where not crossing), ``contact_m`` (N, 3), the ball at the
    contact, and ``end`` (N), the hitter's end of the court (+-1). `ball_m` (rows, 3) is the
    ball's track, frame t of a contact's rally at row ``row0 + t``; `track_end` one past the
    rally's last frame."""
    spacing = np.minimum((seen - contact) // 2, SEEN_MAX_SPACING_FRAMES)
    ok = (spacing >= 1) & (seen < track_end)
    h = np.maximum(spacing, 1)
    rows = np.where(ok, row0 + seen, 0)
    p0, p1, p2 = (ball_m[np.where(ok, rows - j * h, 0)].astype(np.float64) for j in range(3))
    at_contact = ball_m[np.where(ok, row0 + contact, 0)].astype(np.float64)
    dt = (h / fps)[:, None]
    vel = (3.0 * p0 - 4.0 * p1 + p2) / (2.0 * dt)   # second-order backward difference
    acc = (p0 - 2.0 * p1 + p2) / dt ** 2
    end = np.where(at_contact[:, 0] >= 0, 1.0, -1.0)  # the hitter's end of the court
    land, clear = np.full((len(ok), 2), np.nan), np.full(len(ok), np.inf)
    land[ok], clear[ok] = predict_flight(p0[ok], vel[ok], acc[ok], end[ok])
    return {"ok": ok, "vel_mps": vel, "land_m": land, "clear_m": clear, "contact_m": at_contact,
            "end": end}


def seen_flight(ball_m: np.ndarray, contact: np.ndarray, seen: np.ndarray, row0: np.ndarray,
                track_end: np.ndarray, serve: np.ndarray, fps: float,
                ball: dict[str, np.ndarray] | None = None) -> np.ndarray:
    """`seen_flight` code of each contact (module doc); arguments as `seen_ball` (whose result
    may be passed as `ball`), `serve` flags serves."""
    if ball is None:
        ball = seen_ball(ball_m, contact, seen, row0, track_end, fps)
    land, clear, at_contact, end = ball["land_m"], ball["clear_m"], ball["contact_m"], ball["end"]
    far_x = -end * land[:, 0]                        # > 0 beyond the net
    box_side = -np.sign(at_contact[:, 1])            # a serve goes to the diagonal box
    inside = np.where(
        serve,
        np.minimum.reduce([SERVICE_LINE_X_M - far_x, far_x,
                           np.minimum(SINGLES_HALF_WIDTH_M - np.abs(land[:, 1]),
                                      box_side * land[:, 1])]),
        np.minimum.reduce([BASELINE_X_M - far_x, far_x,
                           SINGLES_HALF_WIDTH_M - np.abs(land[:, 1])]))
    net = (clear < -SEEN_NET_MARGIN_M) | (far_x <= 0)
    # A ball seen skimming the cord is a close call whatever its bounce.
    code = np.digitize(inside, SEEN_MARGIN_BINS_M)
    code = np.where(clear < SEEN_NET_MARGIN_M, np.minimum(code, SEEN_ON_LINE), code)
    code = np.where(net, SEEN_NET, code)
    return np.where(~ball["ok"] | np.isnan(land[:, 0]), SEEN_NONE, code).astype(np.int64)


def seen_reach(ball: dict[str, np.ndarray], flight_code: np.ndarray,
               opponent_xy_m: np.ndarray) -> np.ndarray:
    """`seen_reach` code of each contact (module doc): the bin in `SEEN_REACH_BINS_M` of how
    far sideways the seen ball's line passes the opponent (at `opponent_xy_m`, (N, 2), his
    place at the seen frame) at his depth: the bounce of `seen_ball` carried on along the seen
    horizontal direction. `SEEN_NONE` where the flight code is `SEEN_NONE` or `SEEN_NET`."""
    land, vel = ball["land_m"], ball["vel_mps"]
    vx = np.where(np.abs(vel[:, 0]) > 1e-6, vel[:, 0], 1e-6)
    cross_y = land[:, 1] + vel[:, 1] / vx * (opponent_xy_m[:, 0] - land[:, 0])
    code = np.digitize(np.abs(cross_y - opponent_xy_m[:, 1]), SEEN_REACH_BINS_M)
    none = (flight_code == SEEN_NONE) | (flight_code == SEEN_NET) | ~np.isfinite(cross_y)
    return np.where(none, SEEN_NONE, code).astype(np.int64)


def seen_width(ball: dict[str, np.ndarray], bins_m=SEEN_WIDTH_BINS_M) -> np.ndarray:
    """`seen_width` code of each contact (module doc): the bin in `bins_m` of the sideways
    distance between the ball at the contact and its seen bounce (`seen_ball`), `SEEN_NONE`
    where the bounce is not seen."""
    width = np.abs(ball["land_m"][:, 1] - ball["contact_m"][:, 1])
    seen = ball["ok"] & np.isfinite(width)
    code = np.digitize(np.where(seen, width, 0.0), bins_m)
    return np.where(seen, code, SEEN_NONE).astype(np.int64)


def seen_pace(ball: dict[str, np.ndarray], bins_mps=SEEN_PACE_BINS_MPS) -> np.ndarray:
    """`seen_pace` code of each contact (module doc): the bin in `bins_mps` of the ball's
    seen speed (`seen_ball`'s velocity at the seen frame), `SEEN_NONE` where not seen."""
    speed = np.linalg.norm(ball["vel_mps"], axis=1)
    code = np.digitize(np.where(ball["ok"], speed, 0.0), bins_mps)
    return np.where(ball["ok"], code, SEEN_NONE).astype(np.int64)
