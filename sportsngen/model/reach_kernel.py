"""The ball head's contact-reach shifts (`SportsNGEN.contact_reach_bias`: `contact_reach.bin_kinds`
then `ball_dim_bias`) compiled with numba, one frame a loop iteration.

Why: at a rally's one row they were some 25 tensor operations a frame for a (3, n_bins) table of
shifts, 4 % of a simulated frame (py-spy of a match, docs/benchmarks.md, issue 19). The
formulas are `contact_reach`'s, in float32 as torch's; the bucket searches and the strike test
compare the same float32 values, so the shifts are torch's to the bit but where a quotient
rounds across a cell's edge (tests/test_model.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

BALL = 2


@njit(cache=True)
def _bucket(value, edges):
    """`torch.bucketize(value, edges, right=True)`: how many edges are <= value."""
    k = 0
    while k < edges.shape[0] and edges[k] <= value:
        k += 1
    return k


@njit(cache=True)
def reach_bias_rows(pos, vel, centre_x, sign, bin_x, contact, table, frames_edges,
                    aside_edges, fps, min_incoming, out):
    """`pos`, `vel` (B, 3, 3) float32, `centre_x` (B,) the ball's bin centre along x, `sign`
    (B,) the model frame's turn (1 in the world frame), `bin_x` (n,) the ball's first-axis bin
    offsets, `contact` (n,) bool, `table` (2, F, A) -> `out` (B, 3, n) float32, zero but on
    axis 0."""
    n_aside = table.shape[2]
    out[:] = 0.0
    for r in range(pos.shape[0]):
        bx = pos[r, BALL, 0]
        end = np.float32(np.sign(bx))
        # The hitter: the player on the ball's end (the receiver where it is not the server's).
        hitter = 1 if np.sign(bx) != np.sign(pos[r, 0, 0]) else 0
        vx = vel[r, BALL, 0]
        if not vx * end >= min_incoming:
            continue
        frames = (pos[r, hitter, 0] - bx) * end * fps / max(abs(vx), min_incoming)
        aside = abs(pos[r, hitter, 1] - pos[r, BALL, 1])
        cell = _bucket(frames, frames_edges) * n_aside + _bucket(aside, aside_edges)
        strike_shift = table[0].ravel()[cell]
        jolt_shift = table[1].ravel()[cell]
        step_x = centre_x[r] - bx
        for j in range(bin_x.shape[0]):
            if not contact[j]:
                continue
            v_out = (step_x + bin_x[j] * sign[r]) * fps
            if end * v_out < -min_incoming:
                out[r, 0, j] = strike_shift
            else:
                out[r, 0, j] = jolt_shift
