"""Output heads over binned offsets: joint (the paper) or an exact factorisation.

Joint: one softmax over all n^dims cells (61^2 for a player, 61^3 = 226,981 for the ball).
Factorised: p(x) p(y | x) p(z | x, y); each conditional is a small MLP over the hidden state and
learned embeddings of the bins already chosen. It is exact (any joint distribution can be
written so) and needs O(n) outputs instead of O(n^dims).

Every head offers the same calls: `nll(h, idx)`, `top1(h)` and `sample(h, top_p, generator,
regions, top_p_regions)`. With `regions` (a bool mask over the first dimension's bins) and a
nucleus, `sample` first chooses between the masked bins and the rest at the model's own
probability, then takes the nucleus inside the chosen side
(`sportsngen.model.sampling.sample_top_p_in_regions`), `top_p_regions` inside the regions.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from sportsngen.model import head_kernel
from sportsngen.model.bins import flat_index, unflat_index
from sportsngen.model.embedding import run_mlp
from sportsngen.model.packed import kernel_inputs, packed
from sportsngen.model.sampling import sample_top_p, sample_top_p_in_regions


class JointHead(nn.Module):
    def __init__(self, d_model: int, n_bins: int, dims: int):
        super().__init__()
        self.n_bins, self.dims = n_bins, dims
        self.proj = nn.Linear(d_model, n_bins ** dims)

    def _unflat(self, flat: torch.Tensor) -> torch.Tensor:
        return unflat_index(flat, self.n_bins, self.dims)

    def logits(self, h: torch.Tensor) -> torch.Tensor:
        return self.proj(h)

    def nll(self, h: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:
        """(..., d), (..., dims) -> (...) negative log-likelihood in nats."""
        logits = self.proj(h)
        target = flat_index(idx, self.n_bins).reshape(-1)
        return F.cross_entropy(logits.reshape(-1, logits.shape[-1]), target,
                               reduction="none").reshape(idx.shape[:-1])

    def top1(self, h: torch.Tensor) -> torch.Tensor:
        return self._unflat(self.proj(h).argmax(dim=-1))

    def sample(self, h: torch.Tensor, top_p: float = 1.0,
               generator: torch.Generator | None = None,
               regions: torch.Tensor | None = None,
               top_p_regions: float | None = None) -> torch.Tensor:
        logits = self.proj(h)
        if regions is None:
            return self._unflat(sample_top_p(logits, top_p, generator))
        joint = regions.repeat_interleave(self.n_bins ** (self.dims - 1))
        return self._unflat(sample_top_p_in_regions(logits, joint, top_p, generator,
                                                    top_p_regions))


class FactorisedHead(nn.Module):
    def __init__(self, d_model: int, n_bins: int, dims: int, hidden: int = 128,
                 bin_emb: int = 32):
        super().__init__()
        self.n_bins, self.dims = n_bins, dims
        self.first = nn.Linear(d_model, n_bins)
        self.bin_emb = nn.ModuleList(nn.Embedding(n_bins, bin_emb) for _ in range(dims - 1))
        self.cond = nn.ModuleList(
            nn.Sequential(nn.Linear(d_model + (k + 1) * bin_emb, hidden), nn.GELU(),
                          nn.Linear(hidden, n_bins))
            for k in range(dims - 1))

    def dim_logits(self, h: torch.Tensor, prev: torch.Tensor, k: int,
                   dim_bias: torch.Tensor | None = None) -> torch.Tensor:
        """Logits of dimension k given the bins `prev` (..., >= k) of dimensions 0..k-1;
        `dim_bias` (..., dims, n_bins): added to each dimension's logits (e.g. the serve head's
        per-server shift, `model.serve_bias`)."""
        if k == 0:
            out = F.linear(h, self.first.weight, self.first.bias)
        else:
            embs = [F.embedding(prev[..., j], self.bin_emb[j].weight) for j in range(k)]
            out = run_mlp(self.cond[k - 1], torch.cat([h, *embs], dim=-1))
        return out if dim_bias is None else out + dim_bias[..., k, :]

    def nll(self, h: torch.Tensor, idx: torch.Tensor,
            dim_bias: torch.Tensor | None = None) -> torch.Tensor:
        """Teacher-forced: sum over dimensions of -log p(idx_k | h, idx_<k)."""
        total = 0.0
        for k in range(self.dims):
            logits = self.dim_logits(h, idx, k, dim_bias)
            total = total + F.cross_entropy(logits.reshape(-1, self.n_bins),
                                            idx[..., k].reshape(-1),
                                            reduction="none").reshape(idx.shape[:-1])
        return total

    def _decode(self, h: torch.Tensor, pick, dim_bias: torch.Tensor | None = None
                ) -> torch.Tensor:
        chosen = torch.zeros(*h.shape[:-1], self.dims, dtype=torch.long, device=h.device)
        for k in range(self.dims):
            chosen[..., k] = pick(self.dim_logits(h, chosen, k, dim_bias))
        return chosen

    def top1(self, h: torch.Tensor) -> torch.Tensor:
        """Greedy, dimension by dimension (not always the joint argmax)."""
        return self._decode(h, lambda lg: lg.argmax(dim=-1))

    def sample(self, h: torch.Tensor, top_p: float = 1.0,
               generator: torch.Generator | None = None,
               regions: torch.Tensor | None = None,
               top_p_regions: float | None = None,
               dim_bias: torch.Tensor | None = None) -> torch.Tensor:
        """Dimension by dimension, each with its own nucleus (the first inside `regions`).
        `top_p_regions`: the nucleus of every dimension of a row whose first falls in
        `regions` (default `top_p`); `dim_bias` as in `dim_logits` (the regions' odds are
        read after it)."""
        if _compiled_draw(h):
            return self._sample_compiled(h, top_p, generator, regions, top_p_regions, dim_bias)
        if regions is None:
            return self._decode(h, lambda lg: sample_top_p(lg, top_p, generator), dim_bias)
        chosen = torch.zeros(*h.shape[:-1], self.dims, dtype=torch.long, device=h.device)
        chosen[..., 0] = sample_top_p_in_regions(self.dim_logits(h, chosen, 0, dim_bias),
                                                 regions, top_p, generator, top_p_regions)
        row_p = top_p
        if top_p_regions is not None and top_p_regions != top_p:
            inside = regions.to(h.device)[chosen[..., 0]]
            row_p = torch.where(inside, float(top_p_regions), float(top_p))
        for k in range(1, self.dims):
            chosen[..., k] = sample_top_p(self.dim_logits(h, chosen, k, dim_bias), row_p,
                                          generator)
        return chosen

    def _sample_compiled(self, h: torch.Tensor, top_p: float | torch.Tensor,
                         generator: torch.Generator | None, regions: torch.Tensor | None,
                         top_p_regions: float | None, dim_bias: torch.Tensor | None
                         ) -> torch.Tensor:
        """`sample` by `head_kernel.factorised_rows`, reading the same uniforms as the torch
        path in the same order."""
        lead = h.shape[:-1]
        flat = h.detach().reshape(-1, h.shape[-1]).contiguous().numpy()
        rows = len(flat)
        if isinstance(top_p, torch.Tensor):
            p = np.ascontiguousarray(np.broadcast_to(
                top_p.detach().cpu().numpy().astype(np.float32), lead).reshape(rows))
        else:
            p = np.full(rows, top_p, dtype=np.float32)
        inner = p if top_p_regions is None else np.full(rows, top_p_regions, np.float32)
        for name, q in (("top_p", p), ("top_p_regions", inner)):
            if not (q.min() > 0.0 and q.max() <= 1.0):
                raise ValueError(f"{name} must be in (0, 1], got {q}")
        if regions is None:
            mask = np.zeros(self.n_bins, dtype=np.bool_)
            split = False
        else:
            mask = regions.detach().cpu().numpy().astype(np.bool_, copy=False)
            split = not ((p >= 1.0) & (inner >= 1.0)).all()
        bias = np.zeros((rows, self.dims, self.n_bins), dtype=np.float32) if dim_bias is None \
            else np.ascontiguousarray(dim_bias.detach().float().expand(
                *lead, self.dims, self.n_bins).reshape(rows, self.dims, self.n_bins).numpy())
        u = torch.rand(int(split) + self.dims, rows, generator=generator).numpy()
        out = np.empty((rows, self.dims), dtype=np.int64)
        weights = packed(self, lambda: head_kernel.pack_factorised(self))
        head_kernel.factorised_rows(flat, *weights, bias, p, inner, mask, split, u, out)
        return torch.from_numpy(out).reshape(*lead, self.dims)


# Up to this many rows a head's draw is compiled: one player row and frame costs ~0.03 ms
# there, and torch's batched matrix products win from about 32 rows on (32 rallies: 1.08
# against 1.14 ms for both heads; 100: 3.1 against 2.4; scratch outputs/s102/head_batch.py).
HEAD_KERNEL_ROWS = 32


def _compiled_draw(h: torch.Tensor) -> bool:
    """Whether a head's draw takes the compiled kernel: a few float32 CPU rows outside
    autograd (training, large batches and other devices keep the torch path; both read the
    same uniforms)."""
    return h.numel() <= HEAD_KERNEL_ROWS * h.shape[-1] and kernel_inputs(h)


class SubBinHead(nn.Module):
    """Where inside its chosen bins an offset lies: each dimension's bin split into `n_sub`
    equal parts, p(part_0 | h, bins) p(part_1 | h, bins, part_0) ... Exact like the
    factorised head; with it a frame's offset is placed to 1 / n_sub of a bin (the rest
    uniform), so a strike, whose offset falls where the bins are widest, keeps its speed."""

    def __init__(self, d_model: int, n_bins: int, dims: int, n_sub: int, hidden: int = 128,
                 bin_emb: int = 16, sub_emb: int = 8):
        super().__init__()
        self.dims, self.n_sub = dims, n_sub
        self.bin_emb = nn.ModuleList(nn.Embedding(n_bins, bin_emb) for _ in range(dims))
        self.sub_emb = nn.ModuleList(nn.Embedding(n_sub, sub_emb) for _ in range(dims - 1))
        self.cond = nn.ModuleList(
            nn.Sequential(nn.Linear(d_model + dims * bin_emb + k * sub_emb, hidden), nn.GELU(),
                          nn.Linear(hidden, n_sub))
            for k in range(dims))

    def dim_logits(self, h: torch.Tensor, bins: torch.Tensor, prev: torch.Tensor,
                   k: int) -> torch.Tensor:
        """Logits (..., n_sub) of dimension k's part given all bins and parts 0..k-1."""
        embs = [F.embedding(bins[..., j], self.bin_emb[j].weight) for j in range(self.dims)]
        embs += [F.embedding(prev[..., j], self.sub_emb[j].weight) for j in range(k)]
        return run_mlp(self.cond[k], torch.cat([h, *embs], dim=-1))

    def nll(self, h: torch.Tensor, bins: torch.Tensor, sub: torch.Tensor) -> torch.Tensor:
        """Teacher-forced: sum over dimensions of -log p(sub_k | h, bins, sub_<k), (...)."""
        total = torch.zeros(h.shape[:-1], device=h.device, dtype=h.dtype)
        for k in range(self.dims):
            lg = self.dim_logits(h, bins, sub, k)
            total = total + F.cross_entropy(lg.reshape(-1, self.n_sub), sub[..., k].reshape(-1),
                                            reduction="none").reshape(total.shape)
        return total

    def sample(self, h: torch.Tensor, bins: torch.Tensor,
               generator: torch.Generator | None = None) -> torch.Tensor:
        """(..., dims) parts drawn from the whole distribution, dimension by dimension."""
        chosen = torch.zeros_like(bins)
        for k in range(self.dims):
            chosen[..., k] = sample_top_p(self.dim_logits(h, bins, chosen, k), 1.0, generator)
        return chosen


def make_head(kind: str, d_model: int, n_bins: int, dims: int, hidden: int) -> nn.Module:
    if kind == "joint":
        return JointHead(d_model, n_bins, dims)
    if kind == "factorised":
        return FactorisedHead(d_model, n_bins, dims, hidden)
    raise ValueError(f"head kind must be 'joint' or 'factorised', got {kind!r}")
