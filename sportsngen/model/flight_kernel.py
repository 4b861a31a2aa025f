"""The ball forecast's flight loop (`forecast.ball_forecast`) compiled with numba, one ball a
loop iteration.

Why compiled: the forecast runs at every rollout frame (in the decoder's embedding and in the
chase rule), and in torch its 40 steps of flight are some 1,600 tensor operations whose
dispatch, not arithmetic, set its cost: 1.5-2.2 ms a call at any batch size up to 256, about a
third of a simulated frame at one rally (profile of a match, docs/benchmarks.md). Compiled it
is a loop of scalar arithmetic. `torch.compile` of the same loop gave 0.44 ms a call but took
28 s to start even from a warm cache (111 s cold), longer than the demo's whole budget.

Every value is float32 as the torch reference's is (constants cast, so no operation widens
to float64); the square roots and the sums inside norms may round differently from torch's
reductions, so the two agree to float32 rounding, not to the bit (tests/test_forecast.py).
The formulas are those of `model.centre` (`flight_acceleration_mps2`, `read_lift_mps2`,
`split_lift`, `lift_direction`, `magnus_ratio`), written per ball.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sportsngen.model.centre import (
    BOUNCE_RESTITUTION,
    DRAG_PER_M,
    GRAVITY_MPS2,
    MAGNUS_PER_M,
    MAX_LIFT_COEFFICIENT,
    MAX_LIFT_MPS2,
    MAX_LIFT_PER_M,
    NET_KEEP_ACROSS,
    NET_REBOUND,
)
from sportsngen.tennis.court import (
    BALL_RADIUS_M,
    NET_HEIGHT_CENTRE_M,
    NET_HEIGHT_POST_M,
    NET_POST_Y_M,
)

_F = np.float32
_DRAG = _F(DRAG_PER_M)
_G = _F(GRAVITY_MPS2)
_MAGNUS = _F(MAGNUS_PER_M)
_MAX_C = _F(MAX_LIFT_COEFFICIENT)
_MAX_LIFT = _F(MAX_LIFT_MPS2)
_LIFT_PER_M = _F(MAX_LIFT_PER_M)
_REST = _F(BOUNCE_RESTITUTION)
_R = _F(BALL_RADIUS_M)
_TWO_R = _F(2 * BALL_RADIUS_M)
_HALF = _F(0.5)
_ONE = _F(1.0)
_TWO = _F(2.0)
_ZERO = _F(0.0)
_TINY = _F(1e-6)
_EPS = _F(1e-12)
_REBOUND = _F(NET_REBOUND)
_KEEP = _F(NET_KEEP_ACROSS)
_POST_Y = _F(NET_POST_Y_M)
_CORD = _F(NET_HEIGHT_CENTRE_M)
_CORD_RISE = _F(NET_HEIGHT_POST_M - NET_HEIGHT_CENTRE_M)


@njit(cache=True, inline="always")
def _norm3(x, y, z):
    return np.sqrt(x * x + y * y + z * z)


@njit(cache=True, inline="always")
def _flight_acc(vx, vy, vz):
    s = _norm3(vx, vy, vz)
    return -_DRAG * s * vx, -_DRAG * s * vy, -_DRAG * s * vz - _G


@njit(cache=True, inline="always")
def _direction(vx, vy, vz):
    """`centre.lift_direction`."""
    vu = np.sqrt(vx * vx + vy * vy)
    d = max(vu, _TINY)
    return -vz * (vx / d), -vz * (vy / d), vu


@njit(cache=True, inline="always")
def _ratio(c, s0, s):
    """`centre.magnus_ratio`."""
    two_spin = _TWO * c * s0 / (_ONE - _TWO * c)
    return s * (two_spin + s0) / (s0 * (two_spin + s) + _EPS)


@njit(cache=True, inline="always")
def _split(lx, ly, lz, ax, ay, az, cx, cy, cz):
    """`centre.split_lift`: lift less its part along a, split across c's flight and aside."""
    a2 = max(ax * ax + ay * ay + az * az, _TINY)
    k = (lx * ax + ly * ay + lz * az) / a2
    lx, ly, lz = lx - k * ax, ly - k * ay, lz - k * az
    v2 = max(cx * cx + cy * cy + cz * cz, _TINY)
    dx, dy, dz = _direction(cx, cy, cz)
    across = (lx * dx + ly * dy + lz * dz) / v2
    return across, lx - across * dx, ly - across * dy, lz - across * dz


@njit(cache=True, inline="always")
def _read_lift(vx, vy, vz, qx, qy, qz, fps):
    """`centre.read_lift_mps2` of one ball (q: the frame before's velocity): whether the
    second difference reads as a flight (near gravity plus drag), and then its lift carried
    to this frame (`turned_lift_mps2`), else zeros."""
    bx, by, bz = _flight_acc(vx, vy, vz)
    tx, ty, tz = (vx - qx) * fps, (vy - qy) * fps, (vz - qz) * fps
    limit = min(_LIFT_PER_M * (vx * vx + vy * vy + vz * vz), _MAX_LIFT)
    if not _norm3(tx - bx, ty - by, tz - bz) <= limit:
        return False, _ZERO, _ZERO, _ZERO
    mx, my, mz = _HALF * (qx + vx), _HALF * (qy + vy), _HALF * (qz + vz)
    fx, fy, fz = _flight_acc(mx, my, mz)
    across, sx, sy, sz = _split(tx - fx, ty - fy, tz - fz, mx, my, mz, qx, qy, qz)
    u = max(_norm3(qx, qy, qz), _TINY)
    c = min(abs(across) / (_MAGNUS * u), _MAX_C)
    scale = _ratio(c, u, _norm3(vx, vy, vz))
    dx, dy, dz = _direction(vx, vy, vz)
    return True, sx + across * scale * dx, sy + across * scale * dy, sz + across * scale * dz


@njit(cache=True)
def flight_rows(pos, vel, prev, has_prev, fps, step_s, n_steps, n_path, mark1, mark2,
                horizon_s, keep_xy, columns, track):
    """pos, vel, prev (n, 3) float32 -> fills columns (n, 9) and track (n, n_path, 3): the
    forecast of each ball (`forecast.ball_forecast`'s columns and path)."""
    fps = _F(fps)
    dt = _F(step_s)
    keep_xy = _F(keep_xy)
    for i in range(pos.shape[0]):
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        vx, vy, vz = vel[i, 0], vel[i, 1], vel[i, 2]
        lx = ly = lz = _ZERO
        if has_prev:
            qx, qy, qz = prev[i, 0], prev[i, 1], prev[i, 2]
            known = np.isfinite(qx) and np.isfinite(qy) and np.isfinite(qz)
            if not known:
                qx, qy, qz = vx, vy, vz
            # `centre.read_lift_mps2`: the second difference, a flight where near gravity
            # plus drag, its lift carried to this frame (`turned_lift_mps2`).
            flight, rx, ry, rz = _read_lift(vx, vy, vz, qx, qy, qz, fps)
            if flight and known:
                lx, ly, lz = rx, ry, rz
        # The lift split once: across the flight (a coefficient, resized with the speed as
        # the generator's Magnus) and the sideways rest.
        across, sx, sy, sz = _split(lx, ly, lz, vx, vy, vz, vx, vy, vz)
        speed0 = max(_norm3(vx, vy, vz), _TINY)
        coef = min(abs(across) / (_MAGNUS * speed0), _MAX_C)
        dx, dy, dz = _direction(vx, vy, vz)
        lx, ly, lz = sx + across * dx, sy + across * dy, sz + across * dz
        found = False
        bounce_x, bounce_y, bounce_t = _ZERO, _ZERO, _F(horizon_s)
        for k in range(1, n_path + 1):
            ax, ay, az = _flight_acc(vx, vy, vz)
            nx = vx + (ax + lx) * dt
            ny = vy + (ay + ly) * dt
            nz = vz + (az + lz) * dt
            px = px + _HALF * (vx + nx) * dt
            py = py + _HALF * (vy + ny) * dt
            pz = pz + _HALF * (vz + nz) * dt
            r = _ratio(coef, speed0, _norm3(nx, ny, nz))
            dx, dy, dz = _direction(nx, ny, nz)
            lx = across * r * dx + sx
            ly = across * r * dy + sy
            lz = across * r * dz + sz
            vx, vy, vz = nx, ny, nz
            if pz < _R and vz < _ZERO:
                if not found and k <= n_steps:
                    bounce_x, bounce_y, bounce_t = px, py, _F(k * step_s)
                found = True
                vx, vy, vz = vx * keep_xy, vy * keep_xy, vz * -_REST
                # A bounce changes the spin in ways the track has not shown yet.
                across = sx = sy = sz = lx = ly = lz = _ZERO
                pz = _TWO_R - pz
            if k == mark1:
                columns[i, 0], columns[i, 1], columns[i, 2] = px, py, pz
            if k == mark2:
                columns[i, 3], columns[i, 4], columns[i, 5] = px, py, pz
            if k == n_steps:
                if not found:
                    bounce_x, bounce_y = px, py
            track[i, k - 1, 0], track[i, k - 1, 1], track[i, k - 1, 2] = px, py, pz
        columns[i, 6], columns[i, 7], columns[i, 8] = bounce_x, bounce_y, bounce_t


@njit(cache=True, inline="always")
def _acceleration(vx, vy, vz, qx, qy, qz, fps, has_prev):
    """`centre.ball_acceleration_mps2` of one ball (q: the frame before's velocity)."""
    if has_prev:
        flight, lx, ly, lz = _read_lift(vx, vy, vz, qx, qy, qz, fps)
        if flight:
            ax, ay, az = _flight_acc(_F(1.5) * vx - _HALF * qx, _F(1.5) * vy - _HALF * qy,
                                     _F(1.5) * vz - _HALF * qz)
            return ax + lx, ay + ly, az + lz
    return _flight_acc(vx, vy, vz)


@njit(cache=True)
def acceleration_rows(vel, prev, has_prev, fps, out):
    """vel, prev (n, 3) float32 -> out (n, 3): `centre.ball_acceleration_mps2` of each ball."""
    fps32 = _F(fps)
    for i in range(vel.shape[0]):
        qx = qy = qz = _ZERO
        if has_prev:
            qx, qy, qz = prev[i, 0], prev[i, 1], prev[i, 2]
        out[i, 0], out[i, 1], out[i, 2] = _acceleration(vel[i, 0], vel[i, 1], vel[i, 2],
                                                        qx, qy, qz, fps32, has_prev)


@njit(cache=True, inline="always")
def _net_cord(y):
    """`centre.net_cord_m` of one lateral position."""
    sag = min(abs(y), _POST_Y) / _POST_Y
    return _CORD + _CORD_RISE * (sag * sag)


@njit(cache=True)
def physics_rows(pos, vel, prev, has_prev, fps, net, out):
    """pos, vel, prev (n, 3) float32 -> out (n, 3): `centre.physics_step_m` of each ball (the
    net's stop as `centre.net_step_m`, then the bounce off the ground)."""
    inv_fps = _F(1.0 / fps)
    inv_fps2 = _F(1.0 / (fps * fps))
    half_dt = _F(0.5 * (1.0 / fps))
    fps32 = _F(fps)
    for i in range(pos.shape[0]):
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        vx, vy, vz = vel[i, 0], vel[i, 1], vel[i, 2]
        qx = qy = qz = _ZERO
        if has_prev:
            qx, qy, qz = prev[i, 0], prev[i, 1], prev[i, 2]
        ax, ay, az = _acceleration(vx, vy, vz, qx, qy, qz, fps32, has_prev)
        nx = px + vx * inv_fps + ax * inv_fps2
        ny = py + vy * inv_fps + ay * inv_fps2
        nz = pz + vz * inv_fps + az * inv_fps2
        if net:
            side = _ONE if px >= _ZERO else -_ONE
            gap = side * px - _R
            travel = side * (px - nx)
            ux, uy, uz = vx + half_dt * ax, vy + half_dt * ay, vz + half_dt * az
            frac = min(max(gap / max(travel, _F(1e-9)), _ZERO), _ONE)
            fdt = frac * inv_fps
            to_plane = side * (px + ux * fdt + _HALF * ax * (fdt * fdt)) - _R
            speed = side * (ux + ax * fdt) * inv_fps
            frac = min(max(frac - to_plane / (speed if speed < _ZERO else _F(-1e-9)), _ZERO),
                       _ONE)
            fdt = frac * inv_fps
            hx = px + ux * fdt + _HALF * ax * (fdt * fdt)
            hy = py + uy * fdt + _HALF * ay * (fdt * fdt)
            hz = pz + uz * fdt + _HALF * az * (fdt * fdt)
            if side * px > _ZERO and travel > _ZERO and travel >= gap and \
                    hz - _R < _net_cord(hy):
                rest = (_ONE - frac) * inv_fps
                nx = hx + -_REBOUND * (ux + ax * fdt) * rest
                ny = hy + _KEEP * (uy + ay * fdt) * rest
                nz = hz + _KEEP * (uz + az * fdt) * rest - _HALF * _G * (rest * rest)
        if nz < _R and vz < _ZERO:
            nz = _R + _REST * (_R - nz)
        out[i, 0], out[i, 1], out[i, 2] = nx, ny, nz


@njit(cache=True)
def feature_columns_rows(feats, prev_feats, col_scale, vel_scale, fps, step_s, n_steps, mark1,
                         mark2, horizon_s, keep_xy, out):
    """`forecast.forecast_columns` without the intercept: object features `feats` (n, 3, F)
    and the frame before's `prev_feats` (n, 3, F) (NaN rows: none) float32 -> `out` (n, 3, 9):
    each player's forecast columns, the ball's zeros. `col_scale` (9,) the columns' scales
    (its first three the positions'), `vel_scale` the velocities', float32 like torch's."""
    n = feats.shape[0]
    pos = np.empty((n, 3), dtype=np.float32)
    vel = np.empty((n, 3), dtype=np.float32)
    prev = np.empty((n, 3), dtype=np.float32)
    for i in range(n):
        for k in range(3):
            pos[i, k] = feats[i, 2, k] * col_scale[k]
            vel[i, k] = feats[i, 2, 3 + k] * vel_scale
            prev[i, k] = prev_feats[i, 2, 3 + k] * vel_scale
    columns = np.empty((n, out.shape[2]), dtype=np.float32)
    track = np.empty((n, n_steps, 3), dtype=np.float32)
    flight_rows(pos, vel, prev, True, fps, step_s, n_steps, n_steps, mark1, mark2, horizon_s,
                keep_xy, columns, track)
    n_cols = out.shape[2]
    for i in range(n):
        for p in range(2):
            for c in range(n_cols):
                ahead = columns[i, c] / col_scale[c]
                # Less his own position: x, y, z at each horizon; x, y at the bounce; 0 at its time.
                own = feats[i, p, c % 3] if c < n_cols - 3 else \
                    (feats[i, p, c - (n_cols - 3)] if c < n_cols - 1 else _ZERO)
                out[i, p, c] = ahead - own
        for c in range(n_cols):
            out[i, 2, c] = _ZERO
