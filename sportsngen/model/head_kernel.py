"""A factorised head's whole draw (`heads.FactorisedHead.sample`) compiled with numba, one row a
loop iteration: every dimension's logits (the first linear layer, the conditional MLPs over
the bins already chosen), the optional split between `regions` and the rest, and the nucleus.

Why compiled: at a rally's 1-3 rows a head's draw is some 15 tensor operations a dimension,
each paying dispatch far above its arithmetic; the heads' draws were 16 % of a simulated frame
(docs/benchmarks.md, issue 19). Compiled, a dimension is a few small matrix-vector products.

The uniforms are drawn by the caller in one `torch.rand` call, in the order the torch path
draws them one call a dimension (a CPU generator's stream is the same cut either way), so the
two paths read the same numbers. The logits are float32 like torch's, from the decoder step's
matrix-vector product and GELU (`step_kernel.affine`, `gelu`), summed in another order, so
they agree to float32 rounding, not to the bit; a draw differs only where a
uniform falls within that rounding of a class's edge (tests/test_model.py).
"""

from __future__ import annotations

import numpy as np
import torch
from numba import njit

from sportsngen.model.sampling import nucleus_one
from sportsngen.model.step_kernel import affine, gelu


@njit(cache=True)
def factorised_rows(h, first_t, first_b, emb, w1_t, b1, w2_t, b2, bias, top_p, top_p_in,
                    regions, split, u, out):
    """Draw `out` (R, dims) int64 for states `h` (R, d).

    `first_t` (d, n), `first_b` (n,): dimension 0's layer. For k >= 1: `emb[k - 1]` (n, e) the
    bin embedding of dimension k - 1, `w1_t[k - 1]` (d + (dims - 1) e, hidden) the hidden
    layer transposed (its first d + k e rows used), `b1[k - 1]`, `w2_t[k - 1]` (hidden, n),
    `b2[k - 1]`. `bias` (R, dims, n): added to each dimension's logits. `top_p`, `top_p_in`
    (R,): each row's nucleus outside and inside `regions` (n,) bool. `split`: first choose
    the side of `regions` at the model's odds (one uniform more a row). `u` (U, R): the
    uniforms in the torch path's order, the side's first when `split`."""
    n_rows, d = h.shape
    dims = out.shape[1]
    n = first_b.shape[0]
    e = emb.shape[2]
    hidden = b1.shape[1]
    # One-row 2-D buffers for `step_kernel.affine`, and their rows.
    logits_1 = np.empty((1, n), dtype=np.float32)
    x_1 = np.empty((1, d + (dims - 1) * e), dtype=np.float32)
    hid_1 = np.empty((1, hidden), dtype=np.float32)
    logits, x, hid = logits_1[0], x_1[0], hid_1[0]
    cdf = np.empty(n, dtype=np.float32)
    neg_inf = np.float32(-np.inf)
    for r in range(n_rows):
        for i in range(d):
            x[i] = h[r, i]
        affine(first_t, first_b, x_1[:, :d], logits_1)
        for j in range(n):
            logits[j] += bias[r, 0, j]
        row_p = top_p[r]
        first_u = 0
        if split:
            top = logits[0]
            for j in range(n):
                top = max(top, logits[j])
            total = np.float32(0.0)
            inner = np.float32(0.0)
            for j in range(n):
                ex = np.float32(np.exp(logits[j] - top))
                total += ex
                if regions[j]:
                    inner += ex
            inside = u[0, r] < inner / total
            for j in range(n):
                if regions[j] != inside:
                    logits[j] = neg_inf
            if inside:
                row_p = top_p_in[r]
            first_u = 1
        chosen = nucleus_one(logits, row_p, u[first_u, r], cdf)
        out[r, 0] = chosen
        # Every later dimension of a row whose first fell in the regions takes their nucleus.
        if regions[chosen]:
            row_p = top_p_in[r]
        else:
            row_p = top_p[r]
        for k in range(1, dims):
            base = d + (k - 1) * e
            for i in range(e):
                x[base + i] = emb[k - 1, out[r, k - 1], i]
            affine(w1_t[k - 1], b1[k - 1], x_1[:, :d + k * e], hid_1)
            for i in range(hidden):
                hid[i] = gelu(hid[i])
            affine(w2_t[k - 1], b2[k - 1], hid_1, logits_1)
            for j in range(n):
                logits[j] += bias[r, k, j]
            out[r, k] = nucleus_one(logits, row_p, u[first_u + k, r], cdf)


def pack_factorised(head: torch.nn.Module) -> tuple[np.ndarray, ...]:
    """The arrays `factorised_rows` reads from a `FactorisedHead`, as float32 numpy copies
    (weights transposed, the conditional layers stacked, the narrower ones zero-padded)."""
    def np32(t: torch.Tensor) -> np.ndarray:
        return np.ascontiguousarray(t.detach().float().cpu().numpy())

    first_t = np32(head.first.weight.T)
    first_b = np32(head.first.bias)
    n_cond = len(head.cond)
    d, n = first_t.shape
    if n_cond == 0:
        z = np.zeros((1, 1, 1), dtype=np.float32)
        return first_t, first_b, z, z, np.zeros((1, 1), np.float32), z, \
            np.zeros((1, n), np.float32)
    emb = np.stack([np32(m.weight) for m in head.bin_emb])
    hidden = head.cond[0][0].out_features
    width = head.cond[-1][0].in_features
    w1_t = np.zeros((n_cond, width, hidden), dtype=np.float32)
    for k, seq in enumerate(head.cond):
        w = np32(seq[0].weight.T)
        w1_t[k, :w.shape[0]] = w
    b1 = np.stack([np32(seq[0].bias) for seq in head.cond])
    w2_t = np.stack([np32(seq[2].weight.T) for seq in head.cond])
    b2 = np.stack([np32(seq[2].bias) for seq in head.cond])
    return first_t, first_b, emb, w1_t, b1, w2_t, b2
