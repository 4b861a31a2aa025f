"""The decoder's cached step through its blocks (`SportsNGEN.step_tokens` after the embedding:
every `Block.step` and the final layer norm) compiled with numba, one rally a loop iteration.

Why compiled: at a rally's one batch row the step is some 90 tensor operations (layer norms,
projections, the ring writes, two attention matmuls, a softmax, the feed-forward) on three
tokens, their dispatch most of its cost; the step was a fifth of a simulated frame (py-spy of
a match, docs/benchmarks.md, issue 19). Compiled, it is the same arithmetic in loops: each
matrix-vector product runs along a transposed weight's contiguous rows, so the inner loop is
the outputs' (vectorised by LLVM without reordering any sum).

Float32 like torch's, but summed in another order (and the softmax's and layer norms' sums in
float32 one term at a time), so the states agree with the torch step to float32 rounding
(about 1e-5 relative), not to the bit (tests/test_model.py). The keys and values are written
into the same rings (`KVCache`), so the torch step and a full window's forward read them as
before. Used for float32 CPU models outside autograd; a batch of many rallies keeps the torch
step, whose matrix products use the machine's BLAS.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from numba import njit

_INV_SQRT2 = 0.7071067811865476
# Sums may be reordered (so LLVM vectorises the dot products); no infinities or NaNs assumed.
_FAST = {"reassoc", "contract", "nsz", "arcp"}


@njit(cache=True)
def gelu(v):
    """The exact GELU (torch's default) of one float32 value."""
    return np.float32(0.5 * v * (1.0 + math.erf(v * _INV_SQRT2)))


@njit(cache=True, fastmath=_FAST)
def _layer_norm(x, w, b, eps, out):
    n = x.shape[0]
    mean = np.float32(0.0)
    for i in range(n):
        mean += x[i]
    mean /= n
    var = np.float32(0.0)
    for i in range(n):
        dv = x[i] - mean
        var += dv * dv
    var /= n
    inv = np.float32(1.0 / math.sqrt(var + eps))
    for i in range(n):
        out[i] = (x[i] - mean) * inv * w[i] + b[i]


@njit(cache=True, fastmath=_FAST)
def affine(w_t, b, x, out):
    """out = b + x @ w_t for every token: `x` (T, n_in), `out` (T, n_out), `w_t` (n_in, n_out)
    a layer's weight transposed; a weight row is read once for all the tokens."""
    for t in range(out.shape[0]):
        for j in range(out.shape[1]):
            out[t, j] = b[j]
    for i in range(x.shape[1]):
        for t in range(out.shape[0]):
            xi = x[t, i]
            for j in range(out.shape[1]):
                out[t, j] += xi * w_t[i, j]


@njit(cache=True, fastmath=_FAST)
def blocks_rows(x, k_rings, v_rings, lo, n_keys, ln1_w, ln1_b, qkv_t, qkv_b, out_t, out_b,
                ln2_w, ln2_b, ff1_t, ff1_b, ff2_t, ff2_b, lnf_w, lnf_b, eps, n_heads, h_out):
    """`x` (B, T, d) the frame's token embeddings -> `h_out` (B, T, d) the output states;
    writes the tokens' keys and values into slots lo:lo+T of the rings `k_rings`, `v_rings`
    (layers, B, heads, slots, d_head), then attends over their first `n_keys` slots. Weights
    stacked over layers, transposed (`pack_blocks`)."""
    n_rows, n_tok, d = x.shape
    n_layers = ln1_w.shape[0]
    dh = d // n_heads
    scale = np.float32(dh ** -0.5)
    hidden = ff1_b.shape[1]
    cur = np.empty((n_tok, d), dtype=np.float32)
    xn = np.empty((n_tok, d), dtype=np.float32)
    qkv = np.empty((n_tok, 3 * d), dtype=np.float32)
    y = np.empty((n_tok, d), dtype=np.float32)
    a = np.empty((n_tok, d), dtype=np.float32)
    hid = np.empty((n_tok, hidden), dtype=np.float32)
    att = np.empty(n_keys, dtype=np.float32)
    for r in range(n_rows):
        for t in range(n_tok):
            for i in range(d):
                cur[t, i] = x[r, t, i]
        for layer in range(n_layers):
            kr, vr = k_rings[layer], v_rings[layer]
            for t in range(n_tok):
                _layer_norm(cur[t], ln1_w[layer], ln1_b[layer], eps, xn[t])
            affine(qkv_t[layer], qkv_b[layer], xn, qkv)
            for t in range(n_tok):
                for hh in range(n_heads):
                    for i in range(dh):
                        kr[r, hh, lo + t, i] = qkv[t, d + hh * dh + i]
                        vr[r, hh, lo + t, i] = qkv[t, 2 * d + hh * dh + i]
            for t in range(n_tok):
                for hh in range(n_heads):
                    q0 = hh * dh
                    top = np.float32(-3.0e38)
                    for s in range(n_keys):
                        acc = np.float32(0.0)
                        for i in range(dh):
                            acc += qkv[t, q0 + i] * kr[r, hh, s, i]
                        acc *= scale
                        att[s] = acc
                        top = max(top, acc)
                    total = np.float32(0.0)
                    for s in range(n_keys):
                        e = np.float32(math.exp(att[s] - top))
                        att[s] = e
                        total += e
                    for i in range(dh):
                        y[t, q0 + i] = 0.0
                    for s in range(n_keys):
                        p = att[s] / total
                        for i in range(dh):
                            y[t, q0 + i] += p * vr[r, hh, s, i]
            affine(out_t[layer], out_b[layer], y, a)
            for t in range(n_tok):
                for i in range(d):
                    cur[t, i] += a[t, i]
                _layer_norm(cur[t], ln2_w[layer], ln2_b[layer], eps, xn[t])
            affine(ff1_t[layer], ff1_b[layer], xn, hid)
            for t in range(n_tok):
                for i in range(hidden):
                    hid[t, i] = gelu(hid[t, i])
            affine(ff2_t[layer], ff2_b[layer], hid, a)
            for t in range(n_tok):
                for i in range(d):
                    cur[t, i] += a[t, i]
        for t in range(n_tok):
            _layer_norm(cur[t], lnf_w, lnf_b, eps, h_out[r, t])


def pack_blocks(blocks: torch.nn.ModuleList, ln_f: torch.nn.LayerNorm) -> tuple:
    """The weights `blocks_rows` reads, float32 numpy copies stacked over layers (the linear
    layers' transposed), after `eps` and the number of heads: (arrays..., eps, n_heads)."""
    def stack(get) -> np.ndarray:
        return np.ascontiguousarray(np.stack([get(b).detach().float().cpu().numpy()
                                              for b in blocks]))

    def lin(get):
        return stack(lambda b: get(b).weight.T), stack(lambda b: get(b).bias)

    eps = {b.ln1.eps for b in blocks} | {b.ln2.eps for b in blocks} | {ln_f.eps}
    if len(eps) != 1:
        raise ValueError(f"the compiled step needs one layer-norm eps, got {sorted(eps)}")
    return (stack(lambda b: b.ln1.weight), stack(lambda b: b.ln1.bias),
            *lin(lambda b: b.attn.qkv), *lin(lambda b: b.attn.out),
            stack(lambda b: b.ln2.weight), stack(lambda b: b.ln2.bias),
            *lin(lambda b: b.ff[0]), *lin(lambda b: b.ff[2]),
            ln_f.weight.detach().float().cpu().numpy(), ln_f.bias.detach().float().cpu().numpy(),
            np.float32(eps.pop()), blocks[0].attn.n_heads)
