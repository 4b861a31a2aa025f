"""Nucleus (top-p) sampling over binned offsets, batched, with a seeded torch.Generator."""

from __future__ import annotations

import numpy as np
import torch
from numba import njit


def top_p_filter(logits: torch.Tensor, top_p: float) -> torch.Tensor:
    """Logits with every class outside the nucleus set to -inf (last dimension = classes).

    The nucleus is the smallest set of most probable classes whose total probability reaches
    `top_p`; the most probable class is always kept. top_p >= 1 keeps everything.
    """
    if not 0.0 < top_p <= 1.0:
        raise ValueError(f"top_p must be in (0, 1], got {top_p}")
    if top_p >= 1.0:
        return logits
    sorted_logits, order = torch.sort(logits, dim=-1, descending=True)
    probs = torch.softmax(sorted_logits, dim=-1)
    # Mass strictly before each class: a class is kept while that mass is still below top_p.
    before = torch.cumsum(probs, dim=-1) - probs
    drop_sorted = before >= top_p
    drop = torch.zeros_like(drop_sorted).scatter(-1, order, drop_sorted)
    return logits.masked_fill(drop, float("-inf"))


def sample_top_p(logits: torch.Tensor, top_p: float | torch.Tensor,
                 generator: torch.Generator | None = None) -> torch.Tensor:
    """One class index per row of `logits` (..., n) -> (...) int64, nucleus-filtered.
    `top_p`: one value, or one per row (a tensor of shape (...)).

    Inverse-CDF sampling on the sorted probabilities: the nucleus is the sorted prefix whose
    mass first reaches `top_p`, so a uniform draw scaled to that prefix's mass picks a class of
    the nucleus with probability proportional to its own. One sort, one cumsum and one
    search: about half the operations of masking, renormalising and `torch.multinomial`,
    which matters in rollouts that sample five distributions a frame.
    """
    flat = logits.float().reshape(-1, logits.shape[-1])
    if isinstance(top_p, torch.Tensor):
        p = top_p.to(device=flat.device, dtype=flat.dtype).expand(logits.shape[:-1])
        p = p.reshape(-1, 1)
        if not bool(((p > 0.0) & (p <= 1.0)).all()):
            raise ValueError("top_p must be in (0, 1] on every row")
    else:
        if not 0.0 < top_p <= 1.0:
            raise ValueError(f"top_p must be in (0, 1], got {top_p}")
        p = torch.full((len(flat), 1), float(top_p), device=flat.device)
    u = torch.rand(len(flat), 1, generator=generator, device=flat.device)
    if flat.device.type == "cpu":
        pick = np.empty(len(flat), dtype=np.int64)
        _nucleus_rows(flat.detach().contiguous().numpy(),
                      p.detach().reshape(-1).contiguous().numpy(),
                      u.reshape(-1).numpy(), pick)
        return torch.from_numpy(pick).reshape(logits.shape[:-1])
    return _nucleus_torch(flat, p, u).reshape(logits.shape[:-1])


def _nucleus_torch(flat: torch.Tensor, p: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
    """`sample_top_p`'s draw in torch operations: rows `flat` (n, classes), nuclei `p` and
    uniforms `u` (n, 1) -> (n,) class indices (`_nucleus_rows` is the same on the CPU)."""
    sorted_logits, order = torch.sort(flat, dim=-1, descending=True)
    cdf = torch.cumsum(torch.softmax(sorted_logits, dim=-1), dim=-1)
    # Mass of the nucleus: the first cumulative value reaching top_p (the whole row at 1).
    n_keep = torch.searchsorted(cdf, p, right=False)
    n_keep = n_keep.clamp_max(cdf.shape[-1] - 1)
    mass = torch.where(p < 1.0, cdf.gather(-1, n_keep), cdf[:, -1:])
    pick = torch.searchsorted(cdf, u * mass, right=True).clamp_max(n_keep)
    return order.gather(-1, pick)[:, 0]


@njit(cache=True)
def nucleus_one(logits, top_p, u, cdf):
    """One row of `_nucleus_torch` compiled: the class drawn from `logits` (n,) at nucleus
    `top_p` with uniform `u`; `cdf` (n,) float32 scratch. Float32 as torch's; the softmax's
    sum may round differently, so a draw can differ from torch's only where a uniform falls
    within float32 rounding of a class's edge. Shared by `_nucleus_rows` and the fused head
    draw (`model.head_kernel`)."""
    n = logits.shape[0]
    order = np.argsort(-logits, kind="mergesort")
    top = logits[order[0]]
    total = np.float32(0.0)
    for j in range(n):
        e = np.float32(np.exp(logits[order[j]] - top))
        cdf[j] = e
        total += e
    acc = np.float32(0.0)
    for j in range(n):
        acc += cdf[j] / total
        cdf[j] = acc
    # The nucleus: the first class whose cumulative mass reaches top_p (the row at 1).
    keep = n - 1
    if top_p < 1.0:
        for j in range(n):
            if cdf[j] >= top_p:
                keep = j
                break
    target = u * cdf[keep]
    pick = keep
    for j in range(keep):
        if cdf[j] > target:
            pick = j
            break
    return order[pick]


@njit(cache=True)
def _nucleus_rows(logits, top_p, u, out):
    """`_nucleus_torch` compiled, one row a loop: about 15 tensor operations whose dispatch was
    most of a draw's cost at a rally's 2-3 rows, five draws a frame."""
    cdf = np.empty(logits.shape[1], dtype=np.float32)
    for i in range(logits.shape[0]):
        out[i] = nucleus_one(logits[i], top_p[i], u[i], cdf)


def sample_top_p_in_regions(logits: torch.Tensor, regions: torch.Tensor, top_p: float,
                            generator: torch.Generator | None = None,
                            top_p_inside: float | None = None) -> torch.Tensor:
    """Like `sample_top_p`, but first chooses between the classes in `regions` (a (n,) bool
    mask) and the others at their full probability, then samples the nucleus of the chosen
    side. The two sides keep the model's odds whatever `top_p`; inside each, the nucleus
    trims the tails as usual. For the ball's first axis, split into racket contacts and the
    rest: a plain nucleus drops a contact whose frame holds less than 1 - top-p of the mass, and
    a model that spreads a return over several frames then returns none of them.
    `top_p_inside` (default `top_p`): the nucleus inside `regions`, so a strike can keep more
    of its spread than a flight."""
    if not 0.0 < top_p <= 1.0:
        raise ValueError(f"top_p must be in (0, 1], got {top_p}")
    inner = top_p if top_p_inside is None else float(top_p_inside)
    if not 0.0 < inner <= 1.0:
        raise ValueError(f"top_p_inside must be in (0, 1], got {top_p_inside}")
    if top_p >= 1.0 and inner >= 1.0:
        return sample_top_p(logits, top_p, generator)
    regions = regions.to(device=logits.device, dtype=torch.bool)
    p_in = torch.softmax(logits.float(), dim=-1)[..., regions].sum(-1)
    inside = torch.rand(p_in.shape, generator=generator, device=logits.device) < p_in
    keep = torch.where(inside[..., None], regions, ~regions)
    row_p = top_p if inner == top_p else torch.where(inside, inner, top_p)
    return sample_top_p(logits.masked_fill(~keep, float("-inf")), row_p, generator)


def uniform_in_bin(shape: torch.Size | tuple, device: torch.device | str = "cpu",
                   generator: torch.Generator | None = None) -> torch.Tensor:
    """Fractions in [0, 1) for placing a sample uniformly inside its chosen bin."""
    return torch.rand(shape, generator=generator, device=device)
