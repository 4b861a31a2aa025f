"""Nucleus (top-p) sampling over binned offsets, batched, with a seeded torch.Generator."""

from __future__ import annotations

import torch


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


def sample_top_p(logits: torch.Tensor, top_p: float,
                 generator: torch.Generator | None = None) -> torch.Tensor:
    """One class index per row of `logits` (..., n) -> (...) int64, nucleus-filtered.

    Inverse-CDF sampling on the sorted probabilities: the nucleus is the sorted prefix whose
    mass first reaches `top_p`, so a uniform draw scaled to that prefix's mass picks a class of
    the nucleus with probability proportional to its own. One sort, one cumsum and one
    search: about half the operations of masking, renormalising and `torch.multinomial`,
    which matters in rollouts that sample five distributions a frame.
    """
    if not 0.0 < top_p <= 1.0:
        raise ValueError(f"top_p must be in (0, 1], got {top_p}")
    flat = logits.float().reshape(-1, logits.shape[-1])
    sorted_logits, order = torch.sort(flat, dim=-1, descending=True)
    cdf = torch.cumsum(torch.softmax(sorted_logits, dim=-1), dim=-1)
    # Mass of the nucleus: the first cumulative value reaching top_p (the whole row at 1).
    n_keep = torch.searchsorted(cdf, torch.full((len(cdf), 1), min(top_p, 1.0),
                                                device=cdf.device), right=False)
    n_keep = n_keep.clamp_max(cdf.shape[-1] - 1)
    mass = cdf.gather(-1, n_keep) if top_p < 1.0 else cdf[:, -1:]
    u = torch.rand(len(cdf), 1, generator=generator, device=cdf.device) * mass
    pick = torch.searchsorted(cdf, u, right=True).clamp_max(n_keep)
    return order.gather(-1, pick).reshape(logits.shape[:-1])


def uniform_in_bin(shape: torch.Size | tuple, device: torch.device | str = "cpu",
                   generator: torch.Generator | None = None) -> torch.Tensor:
    """Fractions in [0, 1) for placing a sample uniformly inside its chosen bin."""
    return torch.rand(shape, generator=generator, device=device)
