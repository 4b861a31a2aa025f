"""Court geometry in the project frame.

Frame: origin on the ground at the centre of the net; x along the length of the court
(baselines at x = +-11.885 m), y across it (singles sidelines at y = +-4.115 m), z up.
All lengths in metres.

Constants, `net_height_m`, and vectorised numpy geometry: which half a point is in, in/out for
the singles court and the service boxes, serve zones (wide/body/T) and the direction class of a
rally shot (cross court, down the line, middle, inside-out, inside-in).
"""

from __future__ import annotations

import numpy as np

BASELINE_X_M = 11.885
SERVICE_LINE_X_M = 6.40
SINGLES_HALF_WIDTH_M = 4.115
DOUBLES_HALF_WIDTH_M = 5.485
NET_HEIGHT_CENTRE_M = 0.914
NET_HEIGHT_POST_M = 1.07
NET_POST_Y_M = 6.40  # doubles posts, as on a show court
FENCE_X_M = 18.0     # back stop of a show court, from the net
FENCE_Y_M = 9.5      # side stop, from the centre line


def net_height_m(y_m):
    """Height of the net cord at lateral position `y_m` (scalar or array), in metres.

    0.914 m at the centre strap, 1.07 m at the posts (y = +-6.40 m); the cord sags between
    them, modelled as a parabola. Beyond the posts the height stays at the post height.
    """
    import numpy as np

    y = np.minimum(np.abs(np.asarray(y_m, dtype=float)), NET_POST_Y_M)
    h = NET_HEIGHT_CENTRE_M + (NET_HEIGHT_POST_M - NET_HEIGHT_CENTRE_M) * (y / NET_POST_Y_M) ** 2
    return float(h) if np.ndim(h) == 0 else h


# --- Geometry functions -------------------------------------------------------------------
# Orientation facts every function below relies on (z up, right-handed frame):
# a player at the -x end faces +x, so his right hand points to -y; a player at the +x end faces
# -x, so his right hand points to +y. Hence a player's right-hand side has the sign of y equal
# to his end (the sign of x of his baseline).

BALL_RADIUS_M = 0.0335
SERVING_SIDES = ("deuce", "ad")
HANDEDNESS = ("right", "left")
SHOT_DIRECTIONS = ("cross_court", "down_the_line", "middle", "inside_out", "inside_in")
SERVE_ZONES = ("wide", "body", "T")
# Strokes `shot_direction` accepts; the overhead is hit on the racket-arm side, like a forehand.
_FOREHAND_STROKES = ("forehand", "forehand_volley", "overhead")
_BACKHAND_STROKES = ("backhand", "backhand_volley")
THIRD_WIDTH_M = 2.0 * SINGLES_HALF_WIDTH_M / 3.0  # a lateral third of the singles court


def _out(a):
    """Scalar in -> Python scalar out; array in -> array out."""
    a = np.asarray(a)
    return a.item() if a.ndim == 0 else a


def _check_end(end, name: str = "end") -> np.ndarray:
    if type(end) is int and (end == 1 or end == -1):
        return np.asarray(end)      # the usual call: np.isin took 42 us of it, this 0.5 us
    e = np.asarray(end)
    if not np.all(np.isin(e, (-1, 1))):
        raise ValueError(f"{name} must be +1 or -1 (sign of x of the baseline), got {end!r}")
    return e.astype(int)


def _check_choice(values, allowed: tuple[str, ...], name: str) -> np.ndarray:
    v = np.asarray(values, dtype=object)
    bad = [x for x in np.unique(v.astype(str)) if x not in allowed]
    if bad:
        raise ValueError(f"{name} must be one of {allowed}, got {bad}")
    return v.astype(str)


def court_half(x_m):
    """Sign of the court half that `x_m` lies in: +1 for x >= 0, -1 for x < 0.

    A point exactly on the net line (x = 0) counts as the +1 half, by convention, so the
    function never returns 0.
    """
    return _out(np.where(np.asarray(x_m, dtype=float) >= 0.0, 1, -1))


def forehand_side_sign(end, handedness):
    """Sign of y of the forehand side of a player whose baseline is at `end` (+1/-1).

    A right-hander's forehand is on his right: -y at the -x end, +y at the +x end, so the
    sign is `end`; a left-hander's is the opposite, -`end`. Vectorised over `end` and `handedness`.
    """
    if (isinstance(handedness, str) and isinstance(end, (int, float, np.number))
            and end in (1, -1) and handedness in HANDEDNESS):
        # one player's sign, asked once a shot by the generator: a tenth of its time in numpy
        return int(end) if handedness == "right" else -int(end)
    e = _check_end(end)
    h = _check_choice(handedness, HANDEDNESS, "handedness")
    return _out(np.where(h == "right", e, -e))


def is_in_singles(x_m, y_m, side, ball_radius_m: float = 0.0):
    """Whether a bounce at (`x_m`, `y_m`) is in the singles court half at end `side`.

    `side` = +1 is the x > 0 half, -1 the x < 0 half. The lines belong to the court (the court
    dimensions run to the outside of the lines); with `ball_radius_m` > 0 (e.g.
    `BALL_RADIUS_M`) a ball whose centre is up to one radius beyond the outer edge of the
    baseline or sideline still touches the line and is in. x = 0 (the net line) is in either
    half: a real bounce cannot happen there.
    """
    s = _check_end(side, "side")
    if ball_radius_m < 0:
        raise ValueError(f"ball_radius_m must be >= 0, got {ball_radius_m}")
    along = s * np.asarray(x_m, dtype=float)
    y = np.asarray(y_m, dtype=float)
    inside = ((along >= 0.0) & (along <= BASELINE_X_M + ball_radius_m)
              & (np.abs(y) <= SINGLES_HALF_WIDTH_M + ball_radius_m))
    return _out(inside)


def service_box(server_end: int, serving_side: str) -> tuple[float, float, float, float]:
    """The box a serve must land in: (x_min, x_max, y_min, y_max) in metres.

    The server's baseline is at x = `server_end` * 11.885; he serves into the opposite half,
    diagonally. Deuce side = the server's right of the centre mark, i.e. y sign +server_end
    (see the orientation note above), so the deuce box lies at y sign -server_end across the
    net; the ad box at +server_end. Example: server at the -x end on the deuce side stands at
    y < 0 and serves into 0 <= x <= 6.40, 0 <= y <= 4.115 (the receiver's right-hand box).
    """
    if server_end not in (-1, 1):
        raise ValueError(f"server_end must be +1 or -1, got {server_end!r}")
    if serving_side not in SERVING_SIDES:
        raise ValueError(f"serving_side must be one of {SERVING_SIDES}, got {serving_side!r}")
    x_far = -server_end * SERVICE_LINE_X_M
    y_sign = -server_end if serving_side == "deuce" else server_end
    y_far = y_sign * SINGLES_HALF_WIDTH_M
    return (min(0.0, x_far), max(0.0, x_far), min(0.0, y_far), max(0.0, y_far))


def is_in_service_box(x_m, y_m, server_end: int, serving_side: str,
                      ball_radius_m: float = 0.0):
    """Whether a serve bouncing at (`x_m`, `y_m`) is in the correct service box.

    Lines are in; `ball_radius_m` widens the box by one ball radius on the three line sides
    (service line, sideline, centre service line), not at the net.
    """
    if ball_radius_m < 0:
        raise ValueError(f"ball_radius_m must be >= 0, got {ball_radius_m}")
    x0, x1, y0, y1 = service_box(server_end, serving_side)
    r = ball_radius_m
    # The net edge of the box (x = 0) gets no allowance; every other edge gets r.
    x0, x1 = (x0 - r, x1) if x0 < 0 else (x0, x1 + r)
    x = np.asarray(x_m, dtype=float)
    y = np.asarray(y_m, dtype=float)
    return _out((x >= x0) & (x <= x1) & (y >= y0 - r) & (y <= y1 + r))


def serve_zone(y_land_m, box_width_m: float = SINGLES_HALF_WIDTH_M):
    """Serve placement by thirds of the service box width, measured from the centre line.

    |y| < width/3 -> "T", width/3 <= |y| < 2 width/3 -> "body", otherwise "wide" (a fault past
    the sideline is "wide" too). The thirds do not depend on the end or the side because the
    centre service line is y = 0 for every box.
    """
    d = np.abs(np.asarray(y_land_m, dtype=float))
    third = box_width_m / 3.0
    return _out(np.where(d < third, "T", np.where(d < 2.0 * third, "body", "wide")))


def shot_direction(hitter_x, hitter_y, land_x, land_y, handedness, stroke):
    """Direction class of a rally shot: one of `SHOT_DIRECTIONS`.

    The singles court width is split into three lateral thirds of width 8.23/3 = 2.743 m
    (middle third: |y| <= 1.372 m). With s = the sign of y of the hitter's stroke side (the
    forehand side `forehand_side_sign(court_half(hitter_x), handedness)` for forehands,
    forehand volleys and overheads; the opposite for backhands and backhand volleys):

    1. Landing in the middle third (|land_y| <= 1.372 m) -> "middle".
    2. Otherwise the reference side r is the side of the hitter's own third, sign(hitter_y),
       when he stands in an outer third (|hitter_y| > 1.372 m); from the middle third, the
       ball is taken from the stroke side, r = s.
    3. The ball lands on the same side as r (sign(land_y) == r): down the line, else cross
       court. Both use absolute y, so the ball keeps to one sideline or crosses the court.
    4. A plain "forehand" hit from an outer third on the player's backhand side (r == -s,
       the player ran around his backhand): "inside_out" when hit cross court,
       "inside_in" when hit down the line.

    `land_x` is accepted for symmetry and validation only: the classes depend on y.
    Vectorised: every argument may be an array (strings as arrays of str).
    """
    hx = np.asarray(hitter_x, dtype=float)
    hy = np.asarray(hitter_y, dtype=float)
    ly = np.asarray(land_y, dtype=float)
    np.asarray(land_x, dtype=float)  # validates it is numeric
    st = _check_choice(stroke, _FOREHAND_STROKES + _BACKHAND_STROKES, "stroke")
    fh_sign = np.asarray(forehand_side_sign(court_half(hx), handedness))
    is_fh = np.isin(st, _FOREHAND_STROKES)
    stroke_sign = np.where(is_fh, fh_sign, -fh_sign)
    half = THIRD_WIDTH_M / 2.0
    outer = np.abs(hy) > half
    ref = np.where(outer, np.sign(hy), stroke_sign)
    along_line = np.sign(ly) == ref
    inside = (st == "forehand") & outer & (ref == -fh_sign)
    label = np.where(along_line, np.where(inside, "inside_in", "down_the_line"),
                     np.where(inside, "inside_out", "cross_court"))
    return _out(np.where(np.abs(ly) <= half, "middle", label))
