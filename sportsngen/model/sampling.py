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
    """One class index per row of `logits` (..., n) -> (...) int64, nucleus-filtered."""
    filtered = top_p_filter(logits.float(), top_p)
    probs = torch.softmax(filtered, dim=-1)
    flat = probs.reshape(-1, probs.shape[-1])
    idx = torch.multinomial(flat, 1, generator=generator).squeeze(-1)
    return idx.reshape(probs.shape[:-1])


def uniform_in_bin(shape: torch.Size | tuple, device: torch.device | str = "cpu",
                   generator: torch.Generator | None = None) -> torch.Tensor:
    """Fractions in [0, 1) for placing a sample uniformly inside its chosen bin."""
    return torch.rand(shape, generator=generator, device=device)
