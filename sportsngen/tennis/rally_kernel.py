"""`RallyTracker.update` compiled with numba: the same rules, one rally at a time.

Why compiled: the tracker's numpy code is some 150 array operations a frame, written for
batches; a match plays one rally at a time, where each operation's overhead is the whole
cost: the tracker was 9 % of a simulated match's frame (py-spy, docs/benchmarks.md, issue 19).
This kernel walks the same formulas per row, in the same float64 operations and order, so its
state after every frame equals the numpy code's to the bit (tests/test_rally_kernel.py keeps
the numpy path as the reference). The numpy path's cross-row effects are kept too: a frame
that updates any rally resets the rest counter of every rally it does not judge.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sportsngen.tennis.court import (
    BALL_RADIUS_M,
    BASELINE_X_M,
    NET_HEIGHT_CENTRE_M,
    NET_HEIGHT_POST_M,
    NET_POST_Y_M,
    SERVICE_LINE_X_M,
    SINGLES_HALF_WIDTH_M,
)
from sportsngen.tennis.rally import (
    _C,
    _D,
    _R,
    BALL,
    BALL_MAX_SPEED_MPS,
    BOUNCE_AFTER_CONTACT_FRAMES,
    BOUNCE_MAX_ACC_DOWN_G,
    BOUNCE_MAX_ACC_H_MPS2,
    BOUNCE_MAX_Z_M,
    BOUNCE_MIN_ACC_DOWN_G,
    BOUNCE_MIN_VZ_IN_MPS,
    BOUNCE_MIN_VZ_OUT_MPS,
    CONTACT_GAP_FRAMES,
    CONTACT_MAX_Z_M,
    CONTACT_REACH_M,
    EVENT_MIN_SHARE,
    GRAVITY_MPS2,
    GROUND_MIN_Z_M,
    LINE_ALLOWANCE_M,
    NET_CARRY_M,
    NET_STOP_VX_MPS,
    NET_THROUGH_TOL_M,
    NET_ZONE_ABOVE_M,
    NET_ZONE_M,
    NO_SERVE_S,
    PASS_BEYOND_BASELINE_M,
    PLAYER_MAX_SPEED_MPS,
    RECEIVER,
    REST_FRAMES,
    REST_SPEED_MPS,
    ROLL_MAX_Z_M,
    SERVE_CENTRE_TOL_M,
    SERVE_INSIDE_TOL_M,
    SERVE_MIN_HSPEED_MPS,
    SERVE_SLIVER_MIN_MPS,
    SERVE_WIDE_TOL_M,
    SERVER,
    SHOT_MIN_VX_MPS,
    TOSS_MAX_HSPEED_MPS,
)

# Python floats folded as the numpy code folds them (a sum of two constants, then compared).
_SERVE_MIN_X_M = BASELINE_X_M - SERVE_INSIDE_TOL_M
_SERVE_MAX_Y_M = SINGLES_HALF_WIDTH_M + SERVE_WIDE_TOL_M
_PAST_X_M = BASELINE_X_M + PASS_BEYOND_BASELINE_M
_LATE_SHARE = 1.0 - EVENT_MIN_SHARE
_SINGLES_X_M = BASELINE_X_M + LINE_ALLOWANCE_M
_SINGLES_Y_M = SINGLES_HALF_WIDTH_M + LINE_ALLOWANCE_M
_NET_RISE_M = NET_HEIGHT_POST_M - NET_HEIGHT_CENTRE_M
_ACC_DOWN_MAX = -BOUNCE_MAX_ACC_DOWN_G * GRAVITY_MPS2
_ACC_DOWN_MIN = -BOUNCE_MIN_ACC_DOWN_G * GRAVITY_MPS2
_FAULT, _ACE, _DOUBLE, _WINNER, _ERROR = _R["fault"], _R["ace"], _R["double_fault"], \
    _R["winner"], _R["error"]
_NET, _OUT, _UNREACHED = _D["net"], _D["out"], _D["unreached"]
_F_THROUGH_NET, _F_GROUND, _F_JUMP = _C["through_net"], _C["through_ground"], _C["position_jump"]
_F_REACH, _F_SERVE, _F_NO_SERVE = _C["contact_out_of_reach"], _C["serve_position"], _C["no_serve"]
_F_CAP = _C["duration_cap"]
# History slots of `RallyTracker._hist`: frame t is slot 5, t-1 slot 4, ... t-5 slot 0.
_T0, _T1, _T2, _T3, _T4, _T5 = 5, 4, 3, 2, 1, 0


@njit(cache=True, error_model="numpy")
def _nan_max(a, b):
    """np.maximum of two floats: NaN if either is."""
    if math.isnan(a) or math.isnan(b):
        return math.nan
    return a if a >= b else b


@njit(cache=True, error_model="numpy")
def _nan_min(a, b):
    if math.isnan(a) or math.isnan(b):
        return math.nan
    return a if a <= b else b


@njit(cache=True, error_model="numpy")
def _sign(x):
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    if x == 0.0:
        return 0.0
    return math.nan


@njit(cache=True, error_model="numpy")
def _share(before, during, after):
    if after != before:
        return (during - before) / (after - before)
    return math.nan


@njit(cache=True, error_model="numpy")
def net_height_m(y_m):
    """`court.net_height_m` of one lateral position, compiled (the same float64 result)."""
    y = min(abs(y_m), NET_POST_Y_M)
    q = y / NET_POST_Y_M
    return NET_HEIGHT_CENTRE_M + _NET_RISE_M * (q * q)


@njit(cache=True, error_model="numpy")
def _end_of(role, server_end):
    return server_end if role == SERVER else -server_end


@njit(cache=True, error_model="numpy")
def _in_service_box(x, y, server_end, deuce):
    x_far = -server_end * SERVICE_LINE_X_M
    y_far = (-server_end if deuce else server_end) * SINGLES_HALF_WIDTH_M
    x0, x1 = min(0.0, x_far), max(0.0, x_far)
    y0, y1 = min(0.0, y_far), max(0.0, y_far)
    r = LINE_ALLOWANCE_M
    if x0 < 0:
        x0 = x0 - r
    else:
        x1 = x1 + r
    return x >= x0 and x <= x1 and y >= y0 - r and y <= y1 + r


@njit(cache=True, error_model="numpy")
def _in_singles(x, y, side):
    along = side * x
    return along >= 0.0 and along <= _SINGLES_X_M and abs(y) <= _SINGLES_Y_M


@njit(cache=True, error_model="numpy")
def _bounce_point(pa, pb, pc, fps):
    """`rally._bounce_point` for one flight (3,) x 3 -> (x, y, s). A zero denominator gives
    inf or NaN as numpy's does (error_model="numpy"), which the clip then reads."""
    dt = 1.0 / fps
    v = np.empty(3)
    acc = np.empty(3)
    for k in range(3):
        v[k] = (pc[k] - pb[k]) * fps
        a = (pc[k] - 2.0 * pb[k] + pa[k]) * fps * fps
        if not math.isfinite(a):
            a = -GRAVITY_MPS2 if k == 2 else 0.0
        acc[k] = a
    h = math.hypot(acc[0], acc[1])
    scale = min(h, BOUNCE_MAX_ACC_H_MPS2) / max(h, 1e-9)
    acc[0] *= scale
    acc[1] *= scale
    acc[2] = min(max(acc[2], _ACC_DOWN_MAX), _ACC_DOWN_MIN)
    half_dt = 0.5 * dt
    v0x, v0y, v0z = v[0] + half_dt * acc[0], v[1] + half_dt * acc[1], v[2] + half_dt * acc[2]
    c = _nan_max(pc[2] - BALL_RADIUS_M, 0.0)
    a_half = 0.5 * acc[2]
    b = v0z
    s = 2.0 * c / (-b + math.sqrt(_nan_max(b * b - 4.0 * a_half * c, 0.0)))
    if math.isnan(s):
        s = 0.0
    elif s == math.inf:
        s = 3.0 * dt
    s = min(max(s, 0.0), 3.0 * dt)
    ss = s * s
    x = pc[0] + v0x * s + 0.5 * acc[0] * ss
    y = pc[1] + v0y * s + 0.5 * acc[1] * ss
    return x, y, s


@njit(cache=True, error_model="numpy")
def _end(r, win, why, detail, frame, ended, winner, reason, end_detail, end_frame):
    ended[r] = True
    winner[r] = win
    reason[r] = why
    end_detail[r] = detail
    end_frame[r] = frame


@njit(cache=True, error_model="numpy")
def _hitter_loses(r, detail, frame, n_shots, serve_number, hitter, ended, winner, reason,
                  end_detail, end_frame):
    if n_shots[r] == 1:
        second = serve_number[r] == 2
        _end(r, RECEIVER if second else -1, _DOUBLE if second else _FAULT, detail, frame,
             ended, winner, reason, end_detail, end_frame)
    else:
        _end(r, 1 - hitter[r], _ERROR, detail, frame, ended, winner, reason, end_detail,
             end_frame)


@njit(cache=True, error_model="numpy")
def _hitter_wins(r, frame, n_shots, hitter, ended, winner, reason, end_detail, end_frame):
    _end(r, hitter[r], _ACE if n_shots[r] == 1 else _WINNER, _UNREACHED, frame, ended, winner,
         reason, end_detail, end_frame)


@njit(cache=True, error_model="numpy")
def update_rows(pos, live, fps, hist, seen, ended, end_frame, winner, reason, end_detail,
                hitter, n_shots, n_bounces, last_contact, last_bounce, serve_next, rest, through,
                flags, contact_frame, contact_hitter, contact_m, contact_gap_m, bounce_frame,
                bounce_m, n_bounces_total, server_end, deuce, serve_number, max_frames):
    """One `RallyTracker.update` of the rows `live` (B,) bool with the frame `pos` (B, 3, 3),
    in place on the tracker's arrays (passed by name). The contact and bounce tables must have
    room for one more entry per row."""
    dt = 1.0 / fps
    for r in range(len(live)):
        if not live[r]:
            rest[r] = 0
            continue
        for j in range(5):
            hist[r, j] = hist[r, j + 1]
        hist[r, _T0] = pos[r]
        seen[r] += 1
        if seen[r] >= 4:
            _impulses(r, fps, dt, hist, seen, ended, end_frame, winner, reason, end_detail,
                      hitter, n_shots, n_bounces, last_contact, last_bounce, serve_next, flags,
                      contact_frame, contact_hitter, contact_m, contact_gap_m, bounce_frame,
                      bounce_m, n_bounces_total, server_end, deuce, serve_number)
        if ended[r]:
            rest[r] = 0
            continue
        _frame_rules(r, fps, hist, seen, ended, end_frame, winner, reason, end_detail, hitter,
                     n_shots, n_bounces, rest, through, flags, server_end, serve_number,
                     max_frames)


@njit(cache=True, error_model="numpy")
def _impulses(r, fps, dt, hist, seen, ended, end_frame, winner, reason, end_detail, hitter,
              n_shots, n_bounces, last_contact, last_bounce, serve_next, flags, contact_frame,
              contact_hitter, contact_m, contact_gap_m, bounce_frame, bounce_m,
              n_bounces_total, server_end, deuce, serve_number):
    """`RallyTracker._impulses` (and `_bounce`) for row r."""
    ball = hist[r, :, BALL]
    va = (ball[_T2] - ball[_T3]) * fps
    vb = (ball[_T0] - ball[_T1]) * fps
    vm = (ball[_T1] - ball[_T2]) * fps
    seg = seen[r] - 3
    p0 = ball[_T2]
    end = server_end[r]

    dvx = va[0] - vb[0]
    if abs(dvx) > 1e-9:
        s1 = (ball[_T1, 0] - vb[0] * dt - p0[0]) / dvx
    else:
        s1 = 0.5 * dt
    if math.isnan(s1):
        s1 = 0.5 * dt
    s1 = min(max(s1, 0.0), dt)
    contact = p0 + va * s1
    frac = s1 * fps
    before, after = hist[r, _T2, :2, :2], hist[r, _T1, :2, :2]
    players = before + (after - before) * frac
    half = 1 if contact[0] >= 0.0 else -1
    who = SERVER if half == end else RECEIVER
    hs_a, hs_b = math.hypot(va[0], va[1]), math.hypot(vb[0], vb[1])
    spaced = seg - last_contact[r] >= CONTACT_GAP_FRAMES
    in_segment = _share(va[0], vm[0], vb[0]) > EVENT_MIN_SHARE
    free = spaced and in_segment
    served = n_shots[r] == 0 and hs_b > SERVE_MIN_HSPEED_MPS and vb[0] * end < 0
    late = served and free and serve_next[r] and abs(va[0]) > SERVE_SLIVER_MIN_MPS
    serve = served and free and (hs_a < TOSS_MAX_HSPEED_MPS or serve_next[r])
    serve_next[r] = served and spaced and not in_segment and hs_a < TOSS_MAX_HSPEED_MPS
    if late:
        back_s = abs(va[0]) / _nan_max(abs(vm[0]), 1e-9) * dt
        contact = p0 - vm * back_s
        frac = 0.0
        players = before.copy()
        half = 1 if contact[0] >= 0.0 else -1
        who = SERVER if half == end else RECEIVER
    role = SERVER if serve else who
    gap = math.hypot(contact[0] - players[role, 0], contact[1] - players[role, 1])
    reach = gap <= CONTACT_REACH_M and contact[2] <= CONTACT_MAX_Z_M
    at_net = abs(contact[0]) < NET_ZONE_M and not reach
    reverse = va[0] * half > SHOT_MIN_VX_MPS and vb[0] * half < -SHOT_MIN_VX_MPS
    shot = free and n_shots[r] > 0 and reverse and who != hitter[r] and not at_net
    hit = serve or shot
    if hit:
        if not reach:
            flags[r] |= _F_REACH
        sy = contact[1] * (end if deuce[r] else -end)
        placed = contact[0] * end >= _SERVE_MIN_X_M and sy >= -SERVE_CENTRE_TOL_M and \
            sy <= _SERVE_MAX_Y_M
        if serve and not placed:
            flags[r] |= _F_SERVE
        k = n_shots[r]
        contact_frame[r, k] = seg + (1 if frac >= 0.5 else 0)
        contact_hitter[r, k] = role
        contact_m[r, k] = contact
        contact_gap_m[r, k] = gap
        n_shots[r] += 1
        hitter[r] = role
        n_bounces[r] = 0
        last_contact[r] = seg

    dead = _nan_max(ball[_T1, 2], ball[_T0, 2]) < ROLL_MAX_Z_M and \
        abs(vb[2]) <= BOUNCE_MIN_VZ_OUT_MPS
    off_net = abs(p0[0]) < NET_ZONE_M and va[0] * vb[0] < 0.0
    share_z = _share(va[2], vm[2], vb[2])
    bounce = not hit and not off_net and hitter[r] >= 0 and va[2] < -BOUNCE_MIN_VZ_IN_MPS and \
        (vb[2] > BOUNCE_MIN_VZ_OUT_MPS or dead) and \
        _nan_min(p0[2], ball[_T1, 2]) < BOUNCE_MAX_Z_M and \
        seg - last_bounce[r] >= CONTACT_GAP_FRAMES and \
        seg - last_contact[r] >= BOUNCE_AFTER_CONTACT_FRAMES and share_z > EVENT_MIN_SHARE
    if bounce:
        lb = share_z > _LATE_SHARE
        if lb:
            bx, by, s = _bounce_point(ball[_T5], ball[_T4], ball[_T3], fps)
        else:
            bx, by, s = _bounce_point(ball[_T4], ball[_T3], ball[_T2], fps)
        frame = seg - (1 if lb else 0) + np.int64(np.rint(s * fps))
        j = n_bounces_total[r]
        bounce_frame[r, j] = frame
        bounce_m[r, j, 0] = bx
        bounce_m[r, j, 1] = by
        n_bounces_total[r] += 1
        last_bounce[r] = seg
        side = 1 if bx >= 0.0 else -1
        own = side == _end_of(hitter[r], end)
        first = not own and n_bounces[r] == 0
        second = not own and n_bounces[r] >= 1
        if n_shots[r] == 1:
            good = _in_service_box(bx, by, end, deuce[r])
        else:
            good = _in_singles(bx, by, side)
        if own or (first and not good):
            _hitter_loses(r, _OUT, frame, n_shots, serve_number, hitter, ended, winner, reason,
                          end_detail, end_frame)
        if first and good:
            n_bounces[r] = 1
        if second:
            _hitter_wins(r, frame, n_shots, hitter, ended, winner, reason, end_detail,
                         end_frame)
    e_h = _end_of(hitter[r], end)
    net = not hit and not ended[r] and hitter[r] >= 0 and abs(p0[0]) < NET_ZONE_M and \
        p0[2] < net_height_m(p0[1]) + NET_ZONE_ABOVE_M and va[0] * e_h < -SHOT_MIN_VX_MPS and \
        vb[0] * e_h > -NET_STOP_VX_MPS
    if net:
        _hitter_loses(r, _NET, seg, n_shots, serve_number, hitter, ended, winner, reason,
                      end_detail, end_frame)


@njit(cache=True, error_model="numpy")
def _frame_rules(r, fps, hist, seen, ended, end_frame, winner, reason, end_detail, hitter,
                 n_shots, n_bounces, rest, through, flags, server_end, serve_number, max_frames):
    """`RallyTracker._frame_rules` for row r (live, not ended)."""
    now, prev = hist[r, _T0], hist[r, _T1]
    t = seen[r] - 1
    moved = seen[r] >= 2
    d = now[BALL] - prev[BALL]
    ball_v = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) * fps
    jump = ball_v > BALL_MAX_SPEED_MPS
    for k in range(2):
        dx, dy = now[k, 0] - prev[k, 0], now[k, 1] - prev[k, 1]
        if math.sqrt(dx * dx + dy * dy) * fps > PLAYER_MAX_SPEED_MPS:
            jump = True
    if moved and jump:
        flags[r] |= _F_JUMP
    if now[BALL, 2] < GROUND_MIN_Z_M:
        flags[r] |= _F_GROUND

    x0, x1 = prev[BALL, 0], now[BALL, 0]
    cross = moved and _sign(x0) != _sign(x1) and x1 != 0.0
    if cross:
        w = abs(x0) / (abs(x0) + abs(x1))
        y_net = prev[BALL, 1] + w * (now[BALL, 1] - prev[BALL, 1])
        z_net = prev[BALL, 2] + w * (now[BALL, 2] - prev[BALL, 2])
        if z_net - BALL_RADIUS_M < net_height_m(y_net) - NET_THROUGH_TOL_M:
            through[r] = _sign(x1)
        elif _sign(x1) != through[r]:
            through[r] = 0.0
    if through[r] != 0 and x1 * through[r] > NET_CARRY_M:
        flags[r] |= _F_THROUGH_NET
        through[r] = 0.0

    end = server_end[r]
    played = hitter[r] >= 0
    opp = 1 - hitter[r]
    e = _end_of(opp, end)
    o = min(max(opp, 0), 1)
    ox, oy = now[o, 0], now[o, 1]
    gap = math.hypot(now[BALL, 0] - ox, now[BALL, 1] - oy)
    past = played and n_bounces[r] >= 1 and x1 * e > _PAST_X_M and x1 * e > ox * e and \
        gap > CONTACT_REACH_M
    if past:
        _hitter_wins(r, t, n_shots, hitter, ended, winner, reason, end_detail, end_frame)

    still = moved and ball_v < REST_SPEED_MPS
    rest[r] = rest[r] + 1 if still else 0
    if played and not past and rest[r] >= REST_FRAMES:
        own = (1 if x1 >= 0.0 else -1) == _end_of(hitter[r], end)
        at_net = abs(x1) < NET_ZONE_M and abs(now[BALL, 1]) < NET_POST_Y_M
        if own and at_net:
            _hitter_loses(r, _NET, t, n_shots, serve_number, hitter, ended, winner, reason,
                          end_detail, end_frame)
        elif (own and not at_net) or (not own and n_bounces[r] == 0):
            _hitter_loses(r, _OUT, t, n_shots, serve_number, hitter, ended, winner, reason,
                          end_detail, end_frame)
        elif not own and n_bounces[r] >= 1:
            _hitter_wins(r, t, n_shots, hitter, ended, winner, reason, end_detail, end_frame)

    if not ended[r]:
        no_serve = hitter[r] < 0 and seen[r] >= NO_SERVE_S * fps
        if no_serve:
            flags[r] |= _F_NO_SERVE
        elif seen[r] >= max_frames[r]:
            flags[r] |= _F_CAP
        else:
            return
        _end(r, -1, 0, 0, t, ended, winner, reason, end_detail, end_frame)
