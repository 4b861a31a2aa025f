"""The per-row arithmetic of the sampling constraints (`sim.constraints`) compiled with numba:
`PhysicalLimits.accept` (the ground, the net, a ball struck or jolted out of reach) and
`StrikeInReach.passes` (a good ball leaving its player's reach).

Why compiled: a rollout judges every drawn frame, redraws included (about 1.6 judgements a
frame at one rally), and in torch each judgement was some 60 tensor operations on 1-3 rows,
their dispatch the whole cost: the constraints were 15 % of a simulated frame (py-spy of a
match, docs/benchmarks.md, issue 19). The formulas are the torch functions' (kept in
`sim.constraints` as the reference and for other devices), written per row in float64 from
the float32 frames; a verdict can differ from torch's float32 one only where a quantity lies
within float32 rounding of its threshold (tests/test_constraints_kernel.py).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sportsngen.model.centre import GRAVITY_MPS2
from sportsngen.tennis.court import FENCE_X_M, FENCE_Y_M
from sportsngen.tennis.rally import CONTACT_MAX_Z_M, NET_ZONE_M, SHOT_MIN_VX_MPS
from sportsngen.tennis.rally_kernel import net_height_m

BALL = 2


@njit(cache=True)
def _free_fall_z_m(z_m, vz_mps, fps):
    dt = 1.0 / fps
    return z_m + vz_mps * dt - 0.5 * GRAVITY_MPS2 * dt * dt


@njit(cache=True)
def _jolted(b0, b1, v, fps, jolt_mps, jolt_min_z_m, bounce_min_keep):
    """`constraints.ball_jolted` of one row: ball now `b0`, drawn `b1`, velocity `v` (3,)."""
    cx = (b1[0] - b0[0]) * fps - v[0]
    cy = (b1[1] - b0[1]) * fps - v[1]
    cz = (b1[2] - b0[2]) * fps - v[2]
    change = math.sqrt(cx * cx + cy * cy + cz * cz)
    low = _free_fall_z_m(b0[2], v[2], fps)
    inside = abs(b0[0]) < FENCE_X_M - 1.0 and abs(b0[1]) < FENCE_Y_M - 1.0
    along_in = math.sqrt(v[0] * v[0] + v[1] * v[1])
    along_out = math.sqrt((b1[0] - b0[0]) ** 2 + (b1[1] - b0[1]) ** 2) * fps
    braked = along_in > jolt_mps and along_out < bounce_min_keep * along_in
    in_air = change > jolt_mps and low > jolt_min_z_m and b0[2] > jolt_min_z_m
    return (in_air or braked) and inside


@njit(cache=True)
def physical_rows(pos, nxt, vel, reach_m, check_reach, ground_tol_m, net_tol_m, fps,
                  jolt_mps, jolt_min_z_m, bounce_min_keep, out):
    """`PhysicalLimits.accept` -> `out` (B,) bool. `pos`, `nxt`, `vel` (B, 3, 3); `reach_m`
    (B,) each row's reach; `check_reach`: judge struck and jolted balls (a reach and the
    velocities given)."""
    for r in range(pos.shape[0]):
        a, b = pos[r, BALL], nxt[r, BALL]
        ok = b[2] >= -ground_tol_m
        if ok and check_reach:
            vx_in = vel[r, BALL, 0]
            vx_out = (b[0] - a[0]) * fps
            reverse = vx_in * vx_out < 0 and abs(vx_in) > SHOT_MIN_VX_MPS and \
                abs(vx_out) > SHOT_MIN_VX_MPS
            if not reverse:
                reverse = _jolted(a, b, vel[r, BALL], fps, jolt_mps, jolt_min_z_m,
                                  bounce_min_keep)
            if reverse and abs(a[0]) >= NET_ZONE_M:
                gap = math.inf
                for p in range(BALL):
                    gap = min(gap, math.sqrt((pos[r, p, 0] - a[0]) ** 2 +
                                             (pos[r, p, 1] - a[1]) ** 2))
                near = gap <= reach_m[r] and a[2] <= CONTACT_MAX_Z_M
                ok = near
        if ok and a[0] * b[0] < 0:
            frac = a[0] / (a[0] - b[0] + 1e-12)
            y = a[1] + frac * (b[1] - a[1])
            z = a[2] + frac * (b[2] - a[2])
            ok = z >= net_height_m(y) - net_tol_m
        out[r] = ok


@njit(cache=True)
def passes_rows(pos, nxt, vel, has_vel, role, end, reach_m, max_z_m, min_z_m, behind_m, fps,
                jolt_mps, jolt_min_z_m, bounce_min_keep, out):
    """`StrikeInReach.passes` -> `out` (B,) bool. `role`, `end`, `reach_m` (B,); `min_z_m`,
    `behind_m`: NaN where the rule has none."""
    for r in range(pos.shape[0]):
        p = role[r]
        b0, b1 = pos[r, BALL], nxt[r, BALL]
        gap0 = math.sqrt((b0[0] - pos[r, p, 0]) ** 2 + (b0[1] - pos[r, p, 1]) ** 2)
        inside = gap0 <= reach_m[r] and b0[2] <= max_z_m
        sent_back = (b1[0] - b0[0]) * fps * end[r] < -SHOT_MIN_VX_MPS
        if not inside or sent_back:
            out[r] = False
            continue
        gap1 = math.sqrt((b1[0] - nxt[r, p, 0]) ** 2 + (b1[1] - nxt[r, p, 1]) ** 2)
        leaves = gap1 > reach_m[r]
        if not leaves and has_vel:
            leaves = _jolted(b0, b1, vel[r, BALL], fps, jolt_mps, jolt_min_z_m,
                             bounce_min_keep)
        if not leaves and not np.isnan(min_z_m):
            leaves = b1[2] < min_z_m and b1[2] < b0[2]
            if not leaves and has_vel:
                leaves = vel[r, BALL, 2] < 0 and \
                    _free_fall_z_m(b0[2], vel[r, BALL, 2], fps) < min_z_m
        if not leaves and not np.isnan(behind_m):
            leaves = (b1[0] - nxt[r, p, 0]) * end[r] > behind_m
        out[r] = leaves


@njit(cache=True)
def accel_rows(nxt, pos, vel, fps, limit, full_from, cos_keep, heading_from, out):
    """`kinematics.limit_player_acceleration` -> `out` (B, 3, 3), float32 as torch's: `fps`,
    `limit` (m/s a frame), `full_from` (NaN: none), `cos_keep` (the cosine of the heading
    angle; NaN: none) and `heading_from` (m/s) as np.float32."""
    tiny = np.float32(1e-12)
    near_limit = np.float32(limit * (1.0 - 1e-6))
    out[:] = nxt
    for r in range(nxt.shape[0]):
        for p in range(BALL):
            vx, vy = vel[r, p, 0], vel[r, p, 1]
            dvx = (nxt[r, p, 0] - pos[r, p, 0]) * fps - vx
            dvy = (nxt[r, p, 1] - pos[r, p, 1]) * fps - vy
            norm = np.sqrt(dvx * dvx + dvy * dvy)
            over = norm > limit if np.isnan(full_from) else norm >= full_from * limit
            if over:
                scale = limit / max(norm, tiny)
                dvx, dvy = dvx * scale, dvy * scale
            if not np.isnan(cos_keep):
                speed = np.sqrt(vx * vx + vy * vy)
                size = np.sqrt(dvx * dvx + dvy * dvy)
                cos = (dvx * vx + dvy * vy) / max(speed * size, tiny)
                if speed >= heading_from and size >= near_limit and cos >= cos_keep:
                    unit = max(speed, tiny)
                    dvx, dvy = vx / unit * size, vy / unit * size
            out[r, p, 0] = pos[r, p, 0] + (vx + dvx) / fps
            out[r, p, 1] = pos[r, p, 1] + (vy + dvy) / fps


@njit(cache=True)
def speed_rows(nxt, pos, fps, top_mps, out):
    """`kinematics.limit_player_speed` -> `out` (B, 3, 3), float32 as torch's; `top_mps`
    (B, 2) float32."""
    tiny = np.float32(1e-12)
    out[:] = nxt
    for r in range(nxt.shape[0]):
        for p in range(BALL):
            sx = nxt[r, p, 0] - pos[r, p, 0]
            sy = nxt[r, p, 1] - pos[r, p, 1]
            norm = np.sqrt(sx * sx + sy * sy)
            limit = top_mps[r, p] / fps
            scale = limit / max(norm, tiny) if norm > limit else np.float32(1.0)
            out[r, p, 0] = pos[r, p, 0] + sx * scale
            out[r, p, 1] = pos[r, p, 1] + sy * scale


@njit(cache=True)
def _nearest_playable(track, me_x, me_y, z_lo, z_hi, step_s, zs, out):
    """`forecast.nearest_playable` of one flight `track` (N, 3) and one player, the heights
    read from `zs` (N,) (the track's own, or masked): -> `out` (x, y less his, time s);
    (0, 0, -1) where the flight offers him none."""
    side = np.sign(me_x)
    best, k_best = np.inf, -1
    n = track.shape[0]
    for k in range(n):
        step_x = track[1, 0] - track[0, 0] if k == 0 else track[k, 0] - track[k - 1, 0]
        if zs[k] >= z_lo and zs[k] <= z_hi and track[k, 0] * side > 0.5 and \
                step_x * side > 0:
            gap = math.sqrt((track[k, 0] - me_x) ** 2 + (track[k, 1] - me_y) ** 2)
            if gap < best:
                best, k_best = gap, k
    if k_best < 0:
        out[0], out[1], out[2] = 0.0, 0.0, -1.0
    else:
        out[0] = track[k_best, 0] - me_x
        out[1] = track[k_best, 1] - me_y
        out[2] = (k_best + 1) * step_s


@njit(cache=True)
def chase_rows(track, bounce_s, me, vel_me, bounced, band_lo, band_hi, z_lo, z_hi, step_s,
               horizon_s, strike_max_z_m, reach_m, fps, accel_mps2, cap_mps, late, unit,
               along, least):
    """`KeepChasing.late`'s reading of the due rows: each flight `track` (n, N, 3) (the
    forecast's path, `bounce_s` (n,) its next bounce's time), the player due at `me` (n, 2)
    running at `vel_me` (n, 2); `bounced` (n,) the ball has bounced already; `band_lo`,
    `band_hi` the high-ball band (NaN: none); `accel_mps2`, `cap_mps` (n,) -> `late` (n,)
    bool, `unit` (n, 2), `along`, `least` (n,)."""
    near = np.empty(3)
    band = np.empty(3)
    n_pts = track.shape[1]
    zs = np.empty(n_pts)
    for r in range(track.shape[0]):
        for k in range(n_pts):
            zs[k] = track[r, k, 2]
        _nearest_playable(track[r], me[r, 0], me[r, 1], z_lo, z_hi, step_s, zs, near)
        if not np.isnan(band_lo):
            high = False
            for k in range(n_pts):
                after = bounced[r] or ((k + 1) * step_s > bounce_s[r] and
                                       bounce_s[r] < horizon_s)
                zs[k] = track[r, k, 2] if after else -1.0
                high = high or zs[k] > strike_max_z_m
            if high:
                _nearest_playable(track[r], me[r, 0], me[r, 1], band_lo, band_hi, step_s, zs,
                                  band)
                if band[2] > 0:
                    near[:] = band
        dist = math.sqrt(near[0] * near[0] + near[1] * near[1])
        ux, uy = near[0] / max(dist, 1e-6), near[1] / max(dist, 1e-6)
        v_along = vel_me[r, 0] * ux + vel_me[r, 1] * uy
        need = dist - reach_m
        late[r] = near[2] > 0 and need > 0 and v_along * near[2] < need
        unit[r, 0], unit[r, 1] = ux, uy
        along[r] = v_along
        wanted = need / max(near[2], 1e-3)
        least[r] = min(min(v_along + accel_mps2[r] / fps, wanted), cap_mps[r])
