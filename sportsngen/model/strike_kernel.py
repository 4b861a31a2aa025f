"""The strike's numpy flight (`strike.fly_on`: the physics centre's step flown on from a
flight's last three frames) compiled with numba, one ball a loop iteration.

Why compiled: solving a strike's launch (`strike.solve_launch`) flies four probes a Newton
round, a second at a time, and each frame of `fly_on` was some 30 numpy calls on (N, 3)
arrays: the launches were 3 % of a simulated frame (py-spy of a match, docs/benchmarks.md,
issue 19). The formulas are `strike`'s numpy ones (`_gravity_drag`, `_lift_direction`,
`_turned_lift`, `_centre_acceleration`, `centre.magnus_ratio`), written per ball in float64;
the sums of three squares are taken in numpy's order, so the flights agree with numpy's to
rounding (tests/test_strike.py).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sportsngen.model.centre import (
    DRAG_PER_M,
    GRAVITY_MPS2,
    MAGNUS_PER_M,
    MAX_LIFT_COEFFICIENT,
    MAX_LIFT_MPS2,
    MAX_LIFT_PER_M,
)


@njit(cache=True)
def _norm3(x, y, z):
    return math.sqrt(x * x + y * y + z * z)


@njit(cache=True)
def _gravity_drag(v, out):
    k = -DRAG_PER_M * _norm3(v[0], v[1], v[2])
    out[0], out[1], out[2] = k * v[0], k * v[1], k * v[2] - GRAVITY_MPS2


@njit(cache=True)
def _lift_direction(v, out):
    vu = math.sqrt(v[0] * v[0] + v[1] * v[1])
    d = max(vu, 1e-6)
    out[0], out[1], out[2] = -v[2] * (v[0] / d), -v[2] * (v[1] / d), vu


@njit(cache=True)
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True)
def _centre_acceleration(v, prev, fps, s, out):
    """`strike._centre_acceleration` of one ball; `s` (8, 3) scratch."""
    base, track, mid, lift, at_t, d_prev, d_now, tmp = s[0], s[1], s[2], s[3], s[4], s[5], \
        s[6], s[7]
    _gravity_drag(v, base)
    for i in range(3):
        track[i] = (v[i] - prev[i]) * fps
    limit = min(MAX_LIFT_PER_M * _dot(v, v), MAX_LIFT_MPS2)
    if not _norm3(track[0] - base[0], track[1] - base[1], track[2] - base[2]) <= limit:
        out[:] = base
        return
    for i in range(3):
        mid[i] = 0.5 * (prev[i] + v[i])
    _gravity_drag(mid, tmp)
    for i in range(3):
        lift[i] = track[i] - tmp[i]
        tmp[i] = 1.5 * v[i] - 0.5 * prev[i]
    _gravity_drag(tmp, at_t)
    # `_turned_lift`: the lift's part along the flight removed, its part across turned with
    # the flight and scaled as the Magnus force goes with the speed.
    mid2 = max(_dot(mid, mid), 1e-6)
    along = _dot(lift, mid) / mid2
    for i in range(3):
        lift[i] = lift[i] - along * mid[i]
    v2_prev = max(_dot(prev, prev), 1e-6)
    _lift_direction(prev, d_prev)
    across = _dot(lift, d_prev) / v2_prev
    u = math.sqrt(v2_prev)
    c = min(abs(across) / (MAGNUS_PER_M * u), MAX_LIFT_COEFFICIENT)
    speed_to = _norm3(v[0], v[1], v[2])
    two_spin = 2.0 * c * u / (1.0 - 2.0 * c)
    scale = speed_to * (two_spin + u) / (u * (two_spin + speed_to) + 1e-12)
    _lift_direction(v, d_now)
    for i in range(3):
        out[i] = at_t[i] + (lift[i] - across * d_prev[i] + across * scale * d_now[i])


@njit(cache=True)
def fly_on_rows(frames_m, fps, out):
    """`strike.fly_on`: `frames_m` (N, >= 3, 3) -> `out` (N, n_frames, 3)."""
    last = frames_m.shape[1] - 1
    p, v, prev, acc, nxt = np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    s = np.empty((8, 3))
    for r in range(frames_m.shape[0]):
        for i in range(3):
            p[i] = frames_m[r, last, i]
            v[i] = (frames_m[r, last, i] - frames_m[r, last - 1, i]) * fps
            prev[i] = (frames_m[r, last - 1, i] - frames_m[r, last - 2, i]) * fps
        for k in range(out.shape[1]):
            _centre_acceleration(v, prev, fps, s, acc)
            for i in range(3):
                nxt[i] = p[i] + v[i] / fps + acc[i] / (fps * fps)
            for i in range(3):
                prev[i] = v[i]
                v[i] = (nxt[i] - p[i]) * fps
                p[i] = nxt[i]
                out[r, k, i] = p[i]
