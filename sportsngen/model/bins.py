"""Output bins: next-frame offsets (metres, around a centre) <-> per-dimension bin indices.

Bins are symmetric about 0 with an odd count so one bin is centred on 0. "uniform" spacing is the
paper's; "nonuniform" makes bins finer near 0 (edges at R * sign(u) * u^2 for u uniform in
[-1, 1]), where most offsets fall when bins are centred on a constant-velocity extrapolation.
Offsets beyond the range fall in the outermost bins.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import torch
from torch import nn

if TYPE_CHECKING:
    from sportsngen.model.config import ModelConfig


def flat_index(idx: torch.Tensor, n_bins: int) -> torch.Tensor:
    """(..., dims) per-dimension bin indices -> (...) joint class index (first dimension major)."""
    out = idx[..., 0]
    for d in range(1, idx.shape[-1]):
        out = out * n_bins + idx[..., d]
    return out


def unflat_index(flat: torch.Tensor, n_bins: int, dims: int) -> torch.Tensor:
    """(...) joint class index -> (..., dims) per-dimension bin indices; inverse of flat_index."""
    out = []
    for _ in range(dims):
        out.append(flat % n_bins)
        flat = flat // n_bins
    return torch.stack(out[::-1], dim=-1)


def bin_edges(half_range_m: float, n_bins: int, spacing: str) -> torch.Tensor:
    """The n_bins + 1 edges of one dimension, from -half_range_m to +half_range_m."""
    if half_range_m <= 0:
        raise ValueError(f"bin half range must be positive, got {half_range_m}")
    u = torch.linspace(-1.0, 1.0, n_bins + 1, dtype=torch.float64)
    if spacing == "uniform":
        e = u
    elif spacing == "nonuniform":
        e = torch.sign(u) * u ** 2
    else:
        raise ValueError(f"bin spacing must be 'uniform' or 'nonuniform', got {spacing!r}")
    return (e * half_range_m).float()


class Bins(nn.Module):
    """Bins of a `dims`-dimensional offset (2 for a player, 3 for the ball)."""

    def __init__(self, half_range_m: tuple[float, ...], n_bins: int, spacing: str):
        super().__init__()
        self.n_bins = int(n_bins)
        self.dims = len(half_range_m)
        edges = torch.stack([bin_edges(r, n_bins, spacing) for r in half_range_m])
        self.register_buffer("edges", edges, persistent=False)  # (dims, n_bins + 1)
        self.register_buffer("_dim", torch.arange(self.dims), persistent=False)

    def index(self, offset_m: torch.Tensor) -> torch.Tensor:
        """(..., dims) offsets -> (..., dims) int64 bin indices (clamped to the outer bins)."""
        out = [torch.bucketize(offset_m[..., d].contiguous(), self.edges[d, 1:-1], right=True)
               for d in range(self.dims)]
        return torch.stack(out, dim=-1)

    def _bounds(self, idx: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(..., dims) bin indices -> their lower and upper edges, each (..., dims); one
        gather per bound (a rollout asks twice a frame, so per-dimension indexing showed)."""
        return self.edges[self._dim, idx], self.edges[self._dim, idx + 1]

    def value(self, idx: torch.Tensor, u: torch.Tensor | None = None) -> torch.Tensor:
        """(..., dims) bin indices -> offsets at fraction `u` in [0, 1) of each bin (default
        the centre)."""
        lo, hi = self._bounds(idx)
        if u is None:
            u = torch.full_like(lo, 0.5)
        return lo + u * (hi - lo)

    def sub_index(self, offset_m: torch.Tensor, idx: torch.Tensor, n_sub: int) -> torch.Tensor:
        """(..., dims) offsets and their bin indices -> which of `n_sub` equal parts of the bin
        each lies in (int64; offsets beyond the outer bins' edges take the outermost part)."""
        lo, hi = self._bounds(idx)
        frac = (offset_m - lo) / (hi - lo)
        return (frac * n_sub).floor().clamp(0, n_sub - 1).long()

    def width(self, idx: torch.Tensor) -> torch.Tensor:
        """(..., dims) widths of the bins."""
        return self.value(idx, torch.ones(*idx.shape, device=idx.device)) - \
            self.value(idx, torch.zeros(*idx.shape, device=idx.device))

    def gaussian_nll(self, offset_m: torch.Tensor, mean_m: torch.Tensor,
                     sigma_m: torch.Tensor) -> torch.Tensor:
        """Per-dimension NLL (nats, (..., dims)) of the bins of `offset_m` under independent
        Gaussians N(mean_m, sigma_m^2), discretised onto these bins (the outer bins take
        the tails). With `mean_m` a constant-velocity extrapolation this is the
        constant-velocity reference predictor."""
        idx = self.index(offset_m)
        lo, hi = self._bounds(idx)
        lo = torch.where(idx == 0, torch.full_like(lo, -math.inf), lo)
        hi = torch.where(idx == self.n_bins - 1, torch.full_like(hi, math.inf), hi)
        s = sigma_m.clamp_min(1e-6) * math.sqrt(2.0)
        mass = 0.5 * (torch.erf((hi - mean_m) / s) - torch.erf((lo - mean_m) / s))
        return -torch.log(mass.clamp_min(1e-12))


def player_bins(cfg: ModelConfig) -> Bins:
    """A player's bins of a model with config `cfg`: his top speed's step each way in x and y."""
    return Bins((cfg.player_max_speed_mps * (1.0 / cfg.fps),) * 2, cfg.n_bins, cfg.bin_spacing)


def ball_bins(cfg: ModelConfig) -> Bins:
    """The ball's bins of a model with config `cfg`, around its centre (`model.centre`): the one
    rule the decoder and the checks of its resolution read."""
    return Bins(cfg.ball_bin_half_ranges_m, cfg.n_bins, cfg.bin_spacing)
