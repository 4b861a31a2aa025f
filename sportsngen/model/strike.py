"""A racket strike as where its ball goes: landing point, height over the net and spin.

A rally ball's fate (in, out, net) is decided by its velocity the frame after the strike, to a
few centimetres a frame: a 1 m/s error lands it about a metre off. Drawn as a next-frame offset,
the strike falls where the ball's bins are 10-17 cm (3-4 m/s) wide along the court, and the
model has to invert the flight itself to choose a bin that lands in the court. Here the strike
is described in the coordinates its outcome is decided in, the hitter's view of the other half:

- ``depth_m``: how far beyond the net the flight lands (the baseline at 11.885 m);
- ``lateral_m``: how far from the centre line it lands, toward the hitter's left
  (``-side * y``; the singles lines at +-4.115 m);
- ``net_height_m``: the ball's height as it crosses the net's plane (the net: 0.914-1.07 m);
- ``lift_per_s``: its spin, as the Magnus lift across the flight per m/s of speed (negative:
  topspin), the quantity the ball's physics centre carries (`centre.turned_lift_mps2`).

A strike's first three frames are stepped with its lift (`launch_frames`); after them the
flight is the physics centre's own step (`fly_on`: gravity, drag and the lift read from the
track, turned), so a strike placed in a rollout flies on as it was solved. `strike_labels`
reads the four numbers from a recorded strike's first three frames; `solve_launch` finds the
velocity at the contact that gives them (Newton's method on the flight). The flight is stepped
in numpy, not with the centre's torch functions: a solve is hundreds of steps on a few rows,
where a library call's fixed cost is most of the work; `tests/test_strike.py` holds the two
steps equal.
"""

from __future__ import annotations

import numpy as np

from sportsngen.model import strike_kernel
from sportsngen.model.centre import (
    DRAG_PER_M,
    GRAVITY_MPS2,
    MAGNUS_PER_M,
    MAX_LIFT_COEFFICIENT,
    MAX_LIFT_MPS2,
    MAX_LIFT_PER_M,
    magnus_ratio,
)
from sportsngen.tennis.contact_speed import speed_frame_after_contact_mps
from sportsngen.tennis.court import BALL_RADIUS_M, BASELINE_X_M, SINGLES_HALF_WIDTH_M

STRIKE_DIMS = ("depth_m", "lateral_m", "net_height_m", "lift_per_s")
# Bumped when `strike_labels` reads recorded strikes otherwise, so that states cached with an
# older reading are refused (`train.head_fit.cached_states`, for every caller): 2, a ball down
# before the net read.
STRIKE_LABELS_VERSION = 2
STRIKE_BINS = 96
# Each dimension's range, split into STRIKE_BINS equal bins. Depth and lateral edges fall on
# the baseline and the singles lines, so a bin is wholly in or wholly out.
_DEPTH_W = 0.25
_LAT_HALF = SINGLES_HALF_WIDTH_M * 48.0 / 28.0      # +-4.115 m are edges 20 and 76
STRIKE_RANGES = ((BASELINE_X_M - 48 * _DEPTH_W, BASELINE_X_M + 48 * _DEPTH_W),
                 (-_LAT_HALF, _LAT_HALF), (0.0, 7.2), (-1.6, 0.8))
MAX_FLIGHT_FRAMES = 150                              # 6 s at 25 Hz: the highest lob lands
MAX_LAUNCH_MPS = 75.0
MIN_INCOMING_MPS = 2.0   # a strike meets a ball coming to the hitter's side this fast along x
# A serve: struck from a toss (barely moving along x) this high, this far back, sent this fast.
SERVE_MIN_Z_M = 1.8
SERVE_MIN_BACK_M = 9.0
# Sent toward the net at least as fast as the toss may move along x: a serve struck late in
# a frame's interval moves its first frame only a little (0.1 m, 2.75 m/s), and with a gap
# between the two thresholds (2 and 3 m/s once) neither frame read as a serve: 62 % of the
# training rallies of 14 population men went without one. Equal, exactly one of the two does.
SERVE_MIN_OUT_MPS = MIN_INCOMING_MPS
# A serve is drawn by its speed instead of its height over the net: struck from 2.5-3 m, a
# flat serve's landing and net height fix a near-straight line, and the speed that fits them
# is ill-conditioned (landing 5.5 m beyond the net at 1.20 m over it: 188 km/h; 5.8 m at
# 1.15 m: 254 km/h), so a bin of either would span tens of km/h. The speed is the ball's over
# one to two frame times after the contact, what the serve-speed statistics read
# (`eval.physical`, `tennis.contact_speed`): a placed serve is struck on its frame, so it reads
# the launch's first two frames (`solve_serve`); a recorded serve is struck between frames, and
# its track is read at that time after its contact (`serve_labels`). Read instead over its third
# and second frames after the contact, a serve struck 0.84 of a frame before its first frame
# after (every one of the generator's Williams') was read 0.84 frames later in its flight than
# a placed one: her model's serves flew 4-5 km/h slower than hers.
SERVE_DIMS = ("depth_m", "lateral_m", "speed_mps", "lift_per_s")
SERVE_RANGES = (STRIKE_RANGES[0], STRIKE_RANGES[1], (10.0, 74.0), STRIKE_RANGES[3])


def strike_edges() -> np.ndarray:
    """(4, STRIKE_BINS + 1) the bins' edges of each strike dimension."""
    return _EDGES.copy()


_EDGES = np.stack([lo + np.linspace(0.0, 1.0, STRIKE_BINS + 1) * (hi - lo)
                   for lo, hi in STRIKE_RANGES])
_SERVE_EDGES = np.stack([lo + np.linspace(0.0, 1.0, STRIKE_BINS + 1) * (hi - lo)
                         for lo, hi in SERVE_RANGES])


def serve_edges() -> np.ndarray:
    """(4, STRIKE_BINS + 1) the bins' edges of each serve dimension (`SERVE_DIMS`)."""
    return _SERVE_EDGES.copy()


def strike_bin_index(values: np.ndarray, edges: np.ndarray | None = None) -> np.ndarray:
    """(..., 4) strike values -> (..., 4) int64 bin indices (clamped to the outer bins);
    `edges` (default the strike's) as `strike_edges` gives them (`serve_edges` for serves)."""
    edges = _EDGES if edges is None else edges
    out = [np.clip(np.searchsorted(edges[d, 1:-1], values[..., d], side="right"), 0,
                   STRIKE_BINS - 1) for d in range(4)]
    return np.stack(out, axis=-1).astype(np.int64)


def strike_bin_value(idx: np.ndarray, u: np.ndarray | None = None,
                     edges: np.ndarray | None = None) -> np.ndarray:
    """(..., 4) bin indices -> values at fraction u in [0, 1) of each bin (default the centre);
    `edges` as in `strike_bin_index`."""
    edges = _EDGES if edges is None else edges
    lo = np.stack([edges[d][idx[..., d]] for d in range(4)], axis=-1)
    hi = np.stack([edges[d][idx[..., d] + 1] for d in range(4)], axis=-1)
    return lo + (0.5 if u is None else u) * (hi - lo)


def _gravity_drag(v: np.ndarray) -> np.ndarray:
    acc = -DRAG_PER_M * np.linalg.norm(v, axis=-1, keepdims=True) * v
    acc[..., 2] -= GRAVITY_MPS2
    return acc


def _lift_direction(v: np.ndarray) -> np.ndarray:
    """Across the flight in its vertical plane, |v| long (as `centre.lift_direction`)."""
    vu = np.linalg.norm(v[..., :2], axis=-1, keepdims=True)
    u_hat = v[..., :2] / np.maximum(vu, 1e-6)
    return np.concatenate([-v[..., 2:3] * u_hat, vu], axis=-1)


def _launch(contact_m: np.ndarray, v_mps: np.ndarray, lift_per_s: np.ndarray, fps: float,
            n_frames: int = 3) -> np.ndarray:
    """(N, n_frames, 3) the first frames after a contact at `contact_m` with velocity `v_mps`
    and lift `lift_per_s` (constant across the flight, per m/s). The contact is taken on the
    struck frame itself: recorded strikes solved so lie a median 0.05 m from the record's next
    frames, against 0.42 m with the contact a quarter frame later and 0.63 m at half."""
    out = np.empty((len(contact_m), n_frames, 3))
    p, v = contact_m.astype(float).copy(), v_mps.astype(float).copy()
    lift = np.asarray(lift_per_s, dtype=float)[:, None]
    for k in range(n_frames):
        dt = 1.0 / fps
        a = _gravity_drag(v) + lift * _lift_direction(v)
        p = p + v * dt + a * dt * dt
        v = v + a * dt
        out[:, k] = p
    return out


def _turned_lift(lift: np.ndarray, prev_v: np.ndarray, v: np.ndarray) -> np.ndarray:
    """`centre.turned_lift_mps2` in numpy (a test holds the two equal)."""
    mid = 0.5 * (prev_v + v)
    mid2 = np.maximum((mid * mid).sum(-1, keepdims=True), 1e-6)
    lift = lift - (lift * mid).sum(-1, keepdims=True) / mid2 * mid
    v2_prev = np.maximum((prev_v * prev_v).sum(-1, keepdims=True), 1e-6)
    d_prev = _lift_direction(prev_v)
    across = (lift * d_prev).sum(-1, keepdims=True) / v2_prev
    u = np.sqrt(v2_prev)
    c = np.minimum(np.abs(across) / (MAGNUS_PER_M * u), MAX_LIFT_COEFFICIENT)
    scale = magnus_ratio(c, u, np.linalg.norm(v, axis=-1, keepdims=True))
    return lift - across * d_prev + across * scale * _lift_direction(v)


def _centre_acceleration(v: np.ndarray, prev_v: np.ndarray, fps: float) -> np.ndarray:
    """`centre.ball_acceleration_mps2` in numpy: the physics centre's step in a flight."""
    base = _gravity_drag(v)
    track = (v - prev_v) * fps
    limit = np.minimum(MAX_LIFT_PER_M * (v * v).sum(-1, keepdims=True), MAX_LIFT_MPS2)
    flight = np.linalg.norm(track - base, axis=-1, keepdims=True) <= limit
    lift = track - _gravity_drag(0.5 * (prev_v + v))
    at_t = _gravity_drag(1.5 * v - 0.5 * prev_v)
    return np.where(flight, at_t + _turned_lift(lift, prev_v, v), base)


def fly_on(frames_m: np.ndarray, fps: float, n_frames: int = MAX_FLIGHT_FRAMES) -> np.ndarray:
    """(N, >= 3, 3) a flight's frames so far -> (N, n_frames, 3) the frames after them as the
    physics centre steps them (a rollout whose ball stays in the centre bins), the ground
    ignored. Compiled (`strike_kernel.fly_on_rows`); `fly_on_numpy` is the reference."""
    out = np.empty((len(frames_m), n_frames, 3))
    strike_kernel.fly_on_rows(np.ascontiguousarray(frames_m, dtype=float), float(fps), out)
    return out


def fly_on_numpy(frames_m: np.ndarray, fps: float,
                 n_frames: int = MAX_FLIGHT_FRAMES) -> np.ndarray:
    """`fly_on` in numpy operations, the reference its kernel is tested against."""
    p = frames_m[:, -1].astype(float)
    v = (frames_m[:, -1] - frames_m[:, -2]) * fps
    prev = (frames_m[:, -2] - frames_m[:, -3]) * fps
    out = np.empty((len(p), n_frames, 3))
    for k in range(n_frames):
        nxt = p + v / fps + _centre_acceleration(v, prev, fps) / (fps * fps)
        prev, v, p = v, (nxt - p) * fps, nxt
        out[:, k] = p
    return out


def flight_outcome(track_m: np.ndarray, side: np.ndarray,
                   short_of_net: bool = False) -> np.ndarray:
    """(N, T, 3) flights of balls struck from the `side` (N,) +-1 half -> (N, 3) depth beyond
    the net, lateral and height at the net (NaN where the flight does not cross the net or
    land within T frames). The landing is where the ball's centre comes down to its radius.
    `short_of_net`: a flight (the ground ignored) that comes down on the hitter's own half and
    then crosses the net's plane under the ground is read too: where it landed (a negative
    depth) and its height at the net (negative)."""
    n = len(track_m)
    out = np.full((n, 3), np.nan)
    s = np.asarray(side, dtype=float)[:, None]
    x_rel = track_m[..., 0] * s                    # > 0 on the hitter's half
    crossed = (x_rel[:, :-1] > 0) & (x_rel[:, 1:] <= 0)
    down = (track_m[:, :-1, 2] >= BALL_RADIUS_M) & (track_m[:, 1:, 2] < BALL_RADIUS_M)
    rows = np.arange(n)
    has_net, has_land = crossed.any(1), down.any(1)
    k_net, k_land = crossed.argmax(1), down.argmax(1)
    a, b = track_m[rows, k_net], track_m[rows, k_net + 1]
    f = a[:, 0] / np.where(a[:, 0] == b[:, 0], 1.0, a[:, 0] - b[:, 0])
    out[:, 2] = np.where(has_net, a[:, 2] + f * (b[:, 2] - a[:, 2]), np.nan)
    a, b = track_m[rows, k_land], track_m[rows, k_land + 1]
    f = (a[:, 2] - BALL_RADIUS_M) / np.where(a[:, 2] == b[:, 2], 1.0, a[:, 2] - b[:, 2])
    land = a[:, :2] + f[:, None] * (b[:, :2] - a[:, :2])
    ok = has_land & has_net & ((k_land >= k_net) | short_of_net)
    out[:, 0] = np.where(ok, -s[:, 0] * land[:, 0], np.nan)
    out[:, 1] = np.where(ok, -s[:, 0] * land[:, 1], np.nan)
    out[:, 2] = np.where(ok, out[:, 2], np.nan)
    return out


def strike_labels(after_m: np.ndarray, side: np.ndarray, fps: float,
                  short_of_net: bool = True) -> np.ndarray:
    """(N, 3, 3) a strike's first three frames after the contact, struck from `side` (N,)
    -> (N, 4) `STRIKE_DIMS`: the lift as `_launch` steps it, the rest where the physics
    centre flies the ball on from those frames (`fly_on`). NaN where that flight does not
    cross the net and land, or the first frame is already over the net.

    `short_of_net`: a ball that comes down on the hitter's own half before the net (a low
    ball into the net's foot) is read where it lands (a negative depth, in the first depth
    bin) and under the net (its height at the net's plane, under the ground: the first bin),
    an error into the net, instead of NaN. Without it such balls, every one an error, fell
    out of every record the heads and error tables read: 1.7 % of the returns of a
    12,000-point Federer v Nadal truth, every one an error (docs/evaluation.md, fifty-eighth
    part)."""
    q1, q2, q3 = after_m[:, 0], after_m[:, 1], after_m[:, 2]
    v2, v3 = (q2 - q1) * fps, (q3 - q2) * fps
    lift = (v3 - v2) * fps - _gravity_drag(v2)
    across = (lift * _lift_direction(v2)).sum(-1) / np.maximum((v2 * v2).sum(-1), 1e-6)
    track = np.concatenate([after_m, fly_on(after_m, fps)], axis=1)
    out = np.concatenate([flight_outcome(track, side, short_of_net), across[:, None]], axis=1)
    out[q1[:, 0] * np.asarray(side) <= 0] = np.nan
    return out


def _initial_launch(contact_m: np.ndarray, target_xy: np.ndarray, net_height_m: np.ndarray,
                    lift_per_s: np.ndarray) -> np.ndarray:
    """Newton's starting point: a parabola from the contact over the net's point at
    `net_height_m` to the target, in the flight's time rather than its distance. Drag slows
    the ball along its path (ds/dt = u0 e^(-k s), k the drag per metre), so a point s along
    it is reached at t = (e^(k s) - 1) / (k u0); the spin's lift adds to gravity. Three rounds of
    the speed it gives; a vacuum parabola landed rally balls 7-8 m short."""
    d_xy = target_xy - contact_m[:, :2]
    dist = np.maximum(np.linalg.norm(d_xy, axis=-1), 1.0)
    u = d_xy / dist[:, None]
    f = np.clip(np.abs(contact_m[:, 0]) / np.maximum(np.abs(d_xy[:, 0]), 1e-3), 0.05, 0.95)
    r1, r2 = net_height_m - contact_m[:, 2], BALL_RADIUS_M - contact_m[:, 2]
    speed = np.full(len(dist), 25.0)
    k = DRAG_PER_M
    for _ in range(3):
        e1, e2 = np.expm1(k * f * dist) / k, np.expm1(k * dist) / k
        g = GRAVITY_MPS2 - np.minimum(lift_per_s, 0.0) * speed
        # r = a E - b E^2 through both points; b = g / (2 u0^2), a = vz / u0.
        b = -(r1 / e1 - r2 / e2) / (e1 - e2)
        a = r1 / e1 + b * e1
        speed_h = np.clip(np.sqrt(g / (2.0 * np.maximum(b, 1e-4))), 5.0, 50.0)
        speed = np.hypot(speed_h, a * speed_h)
    return np.concatenate([u * speed_h[:, None], (a * speed_h)[:, None]], axis=-1)


def _outcome_of_launch(contact_m, v, lift, side, fps) -> np.ndarray:
    """Where the flight of each launch lands (N, 3), flown a second at a time until every
    ball has come down (a rollout's single strike would otherwise pay for the highest lob)."""
    track = np.concatenate([contact_m[:, None], _launch(contact_m, v, lift, fps)], axis=1)
    chunk = int(round(fps))
    while track.shape[1] < MAX_FLIGHT_FRAMES:
        track = np.concatenate([track, fly_on(track[:, -3:], fps, chunk)], axis=1)
        if (track[:, -1, 2] < BALL_RADIUS_M).all():
            break
    return flight_outcome(track, side)


def solve_launch(contact_m: np.ndarray, side: np.ndarray, strike: np.ndarray, fps: float,
                 iterations: int = 8, tol_m: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """The velocity at the contact (N, 3) that flies a ball struck at `contact_m` (N, 3) from
    `side` (N,) to `strike` (N, 4 `STRIKE_DIMS`) (`launch_frames`, then `fly_on`), and whether
    it was found within `tol_m` on all three targets (N,)."""
    s = np.asarray(side, dtype=float)
    target = strike[:, :3]
    lift = strike[:, 3]
    xy = np.stack([-s * target[:, 0], -s * target[:, 1]], axis=-1)
    v = _initial_launch(contact_m, xy, target[:, 2], lift)
    n, eps = len(v), 0.05
    ok = np.zeros(n, dtype=bool)
    for _ in range(iterations):
        probe = np.concatenate([v] + [v + eps * np.eye(3)[k] for k in range(3)])
        out = _outcome_of_launch(np.tile(contact_m, (4, 1)), probe, np.tile(lift, 4),
                                 np.tile(s, 4), fps).reshape(4, n, 3)
        res = out[0] - target
        ok = np.isfinite(res).all(-1) & (np.abs(res) < tol_m).all(-1)
        if ok.all():
            break
        jac = (out[1:] - out[0][None]).transpose(1, 2, 0) / eps        # (n, 3 out, 3 in)
        good = np.isfinite(jac).all((1, 2)) & np.isfinite(res).all(-1)
        step = np.zeros_like(v)
        if good.any():
            det_ok = np.abs(np.linalg.det(jac[good])) > 1e-9
            idx = np.flatnonzero(good)[det_ok]
            step[idx] = np.linalg.solve(jac[idx], -res[idx][..., None])[..., 0]
        # A launch that does not cross or land yet (no finite outcome) is pushed higher.
        step[~good] = np.array([0.0, 0.0, 1.0])
        step = np.where(ok[:, None], 0.0, step)
        norm = np.linalg.norm(step, axis=-1, keepdims=True)
        v = v + step * np.minimum(1.0, 10.0 / np.maximum(norm, 1e-9))
        speed = np.linalg.norm(v, axis=-1, keepdims=True)
        v = v * np.minimum(1.0, MAX_LAUNCH_MPS / np.maximum(speed, 1e-9))
    return v, ok


def launch_frames(contact_m: np.ndarray, v_mps: np.ndarray, lift_per_s: np.ndarray,
                  fps: float) -> np.ndarray:
    """The three frames (N, 3, 3) after the contact of the flight `solve_launch` found: what a
    rollout puts there, so that the physics centre flies the ball on as solved."""
    return _launch(contact_m, v_mps, lift_per_s, fps)


def is_strike(pos_m: np.ndarray, vel_mps: np.ndarray, next_pos_m: np.ndarray,
              fps: float) -> np.ndarray:
    """(..., 3) the ball's position and backward velocity at a frame and its next position ->
    (...) bool: a racket strike of a rally ball between them (the ball was coming to the
    hitter's half and leaves toward the other; the serve, struck from a toss, is not one)."""
    side = np.sign(pos_m[..., 0])
    v_out = (next_pos_m[..., 0] - pos_m[..., 0]) * fps
    return (side * vel_mps[..., 0] > MIN_INCOMING_MPS) & (side * v_out < -MIN_INCOMING_MPS)


def is_strike_begun(pos_m: np.ndarray, vel_mps: np.ndarray, next_pos_m: np.ndarray,
                    fps: float) -> np.ndarray:
    """(..., 3) as `is_strike` -> (...) bool: the step stops a ball coming to the hitter's
    half along x (it moves no faster than `MIN_INCOMING_MPS` either way): the first step of a
    strike struck inside it (`is_strike_across`), which the frame after sends back."""
    side = np.sign(pos_m[..., 0])
    v_mid = side * (next_pos_m[..., 0] - pos_m[..., 0]) * fps
    return (side * vel_mps[..., 0] > MIN_INCOMING_MPS) & (np.abs(v_mid) <= MIN_INCOMING_MPS)


def is_strike_across(pos_m: np.ndarray, vel_mps: np.ndarray, next_pos_m: np.ndarray,
                     after_next_pos_m: np.ndarray, fps: float) -> np.ndarray:
    """(..., 3) the ball's position and backward velocity at a frame, its next position and
    the one after -> (...) bool: a rally strike between the frame and the next (`is_strike`),
    or one struck in that step where its ways in and out nearly cancel (along x the step moves
    no faster than `MIN_INCOMING_MPS` either way) and the step after sends the ball back. A
    recorded contact falls anywhere in a frame's interval: of 17,305 returns in the named
    players' round robins the single step missed 13.7 % (all found this way), the slower ones
    (median 23.7 against 28.2 m/s), and a head trained on the strikes found never saw them."""
    side = np.sign(pos_m[..., 0])
    v_after = side * (after_next_pos_m[..., 0] - next_pos_m[..., 0]) * fps
    across = is_strike_begun(pos_m, vel_mps, next_pos_m, fps) & (v_after < -MIN_INCOMING_MPS)
    return is_strike(pos_m, vel_mps, next_pos_m, fps) | across


def is_serve(pos_m: np.ndarray, vel_mps: np.ndarray, next_pos_m: np.ndarray,
             fps: float) -> np.ndarray:
    """(..., 3) as `is_strike` -> (...) bool: a serve between them: a tossed ball (moving along
    x slower than `MIN_INCOMING_MPS` either way), high above the hitter's baseline area,
    sent toward the other half at least `SERVE_MIN_OUT_MPS` (the same speed: of a toss frame
    and the frame after it, exactly one is a serve's)."""
    side = np.sign(pos_m[..., 0])
    v_out = (next_pos_m[..., 0] - pos_m[..., 0]) * fps
    return ((np.abs(vel_mps[..., 0]) < MIN_INCOMING_MPS) & (pos_m[..., 2] >= SERVE_MIN_Z_M)
            & (np.abs(pos_m[..., 0]) >= SERVE_MIN_BACK_M) & (side * v_out <= -SERVE_MIN_OUT_MPS))


def serve_labels(after_m: np.ndarray, side: np.ndarray, fps: float,
                 contact_m: np.ndarray) -> np.ndarray:
    """(N, 3, 3) a recorded serve's first three frames after the contact at `contact_m` (N, 3;
    or the toss's last frame before it), struck from `side` (N,) -> (N, 4) `SERVE_DIMS`:
    `strike_labels` with the speed in place of the height over the net, over one to two frame
    times after the contact (`tennis.contact_speed`), where a placed serve's speed is read."""
    # A serve into the ground before the net stays unread (NaN): the serve head's record and
    # tables were fitted without such serves, and were not measured with them.
    out = strike_labels(after_m, side, fps, short_of_net=False)
    out[:, 2] = np.where(np.isfinite(out[:, 2]),
                         speed_frame_after_contact_mps(contact_m, after_m, fps), np.nan)
    return out


def _serve_outcome(contact_m: np.ndarray, v: np.ndarray, lift: np.ndarray, side: np.ndarray,
                   fps: float) -> np.ndarray:
    """(N, 3): depth and lateral where each launch lands, and its speed over its first two
    frames (`SERVE_DIMS` but the spin; the speed as the statistics read a placed serve's)."""
    out = _outcome_of_launch(contact_m, v, lift, side, fps)
    frames = _launch(contact_m, v, lift, fps)
    out[:, 2] = np.linalg.norm(frames[:, 1] - frames[:, 0], axis=-1) * fps
    return out


def solve_serve(contact_m: np.ndarray, side: np.ndarray, serve: np.ndarray, fps: float,
                iterations: int = 10, tol_m: float = 0.01,
                tol_mps: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """The velocity at the contact (N, 3) of a serve struck at `contact_m` from `side` that
    lands at `serve` (N, 4 `SERVE_DIMS`)'s depth and lateral at its speed, and whether it was
    found within `tol_m` and `tol_mps` (N,). Newton's method from the straight line to the
    landing point lifted for the fall over its time (the fast, flat solution, not the lob)."""
    s = np.asarray(side, dtype=float)
    lift = serve[:, 3]
    target = np.stack([serve[:, 0], serve[:, 1], serve[:, 2]], axis=-1)
    land = np.stack([-s * serve[:, 0], -s * serve[:, 1], np.zeros(len(s))], axis=-1)
    d = land - contact_m
    dist = np.linalg.norm(d, axis=-1, keepdims=True)
    speed = np.clip(serve[:, 2:3], 5.0, MAX_LAUNCH_MPS)
    v = d / dist * speed
    v[:, 2] += 0.5 * GRAVITY_MPS2 * dist[:, 0] / speed[:, 0]
    n, eps = len(v), 0.05
    ok = np.zeros(n, dtype=bool)
    scale = np.array([1.0, 1.0, tol_m / tol_mps])   # speeds weighed as landing metres
    for _ in range(iterations):
        probe = np.concatenate([v] + [v + eps * np.eye(3)[k] for k in range(3)])
        out = _serve_outcome(np.tile(contact_m, (4, 1)), probe, np.tile(lift, 4),
                             np.tile(s, 4), fps).reshape(4, n, 3)
        res = out[0] - target
        ok = np.isfinite(res).all(-1) & (np.abs(res * scale) < tol_m).all(-1)
        if ok.all():
            break
        jac = (out[1:] - out[0][None]).transpose(1, 2, 0) / eps
        good = np.isfinite(jac).all((1, 2)) & np.isfinite(res).all(-1) & ~ok
        step = np.zeros_like(v)
        if good.any():
            det_ok = np.abs(np.linalg.det(jac[good])) > 1e-9
            idx = np.flatnonzero(good)[det_ok]
            step[idx] = np.linalg.solve(jac[idx], -res[idx][..., None])[..., 0]
        step[~good & ~ok] = np.array([0.0, 0.0, 1.0])   # no landing yet: aim higher
        norm = np.linalg.norm(step, axis=-1, keepdims=True)
        v = v + step * np.minimum(1.0, 10.0 / np.maximum(norm, 1e-9))
        v = v * np.minimum(1.0, MAX_LAUNCH_MPS / np.maximum(np.linalg.norm(v, axis=-1,
                                                                           keepdims=True), 1e-9))
    return v, ok
