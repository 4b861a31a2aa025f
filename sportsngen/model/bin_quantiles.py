"""Where a player's draw falls inside its bin: the record's own spread there, not a uniform one.

The player head draws a bin of each offset from constant velocity (`bins.Bins`), and the
rollout used to put the offset uniformly inside it. Where players accelerate, the bins are wide:
the one that holds the generator's flat-out start (6 m/s², 0.0096 m a frame at 25 Hz) runs from
0.0087 to 0.0130 m, a change of speed of 0.22-0.33 m/s a frame, while the record's offsets in it
sit at its cap (quantiles 0 / 0.25 / 0.5 / 0.75 / 1: 0.0087 / 0.0091 / 0.0094 / 0.0096 /
0.0096 m). Uniform placement, cut by the
acceleration limit, took 0.232 ± 0.013 m/s a frame from a receiver who in the truth gains 0.240
every frame of his run, and over the ten frames to a serve's bounce that noise (0.108 m/s in
speed) decided which serves he reached: his speed 12 frames into aces read 0.38-0.41 in the
leak check's AUC where the truth's receivers tie (docs/evaluation.md, seventy-sixth part).

`fit_bin_quantiles` reads, per dimension and bin, the quantiles of the training offsets that
fall in it (in the model's frame); `place_in_bins` puts a draw at quantile `u` of its bin (linear
between the stored quantiles), so a uniform `u` draws from the record's spread inside the bin.
A bin with fewer than `MIN_OFFSETS` offsets keeps the uniform spread. The head, its bins and its
likelihood are unchanged: only where inside the chosen bin a draw lands.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import torch
from numba import njit

from sportsngen.model.packed import kernel_inputs

N_QUANTILES = 16           # quantiles 0, 1/16, ..., 1 of each bin
MIN_OFFSETS = 50           # fewer offsets in a bin: its spread stays uniform


def fit_bin_quantiles(offsets_m: np.ndarray, edges_m: np.ndarray, n_quantiles: int = N_QUANTILES,
                      min_offsets: int = MIN_OFFSETS) -> np.ndarray:
    """Offsets (N, dims) and each dimension's bin edges (dims, n_bins + 1) -> (dims, n_bins,
    n_quantiles + 1): per bin, the quantiles of the offsets inside it (NaN offsets and those
    beyond the outer edges ignored), or its edges spread evenly where it holds fewer than
    `min_offsets`."""
    off = np.asarray(offsets_m, dtype=np.float64)
    edges = np.asarray(edges_m, dtype=np.float64)
    if off.ndim != 2 or edges.ndim != 2 or off.shape[1] != edges.shape[0]:
        raise ValueError(f"offsets (N, dims) and edges (dims, n_bins + 1) must agree, got "
                         f"{off.shape} and {edges.shape}")
    if n_quantiles < 1 or min_offsets < 2:
        raise ValueError(f"need n_quantiles >= 1 and min_offsets >= 2, got {n_quantiles}, "
                         f"{min_offsets}")
    q = np.linspace(0.0, 1.0, n_quantiles + 1)
    dims, n_bins = edges.shape[0], edges.shape[1] - 1
    table = edges[:, :-1, None] + q * np.diff(edges, axis=1)[..., None]   # uniform spread
    for d in range(dims):
        v = off[:, d]
        v = v[np.isfinite(v) & (v >= edges[d, 0]) & (v <= edges[d, -1])]
        idx = np.clip(np.searchsorted(edges[d], v, side="right") - 1, 0, n_bins - 1)
        order = np.argsort(idx, kind="stable")
        v, idx = v[order], idx[order]
        starts = np.searchsorted(idx, np.arange(n_bins + 1))
        for k in range(n_bins):
            part = v[starts[k]:starts[k + 1]]
            if len(part) >= min_offsets:
                table[d, k] = np.quantile(part, q)
    return table


def place_in_bins(quantiles_m: torch.Tensor, idx: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
    """`fit_bin_quantiles`' table (dims, n_bins, n_quantiles + 1), bin indices (..., dims) and
    fractions `u` (..., dims) in [0, 1) -> offsets (..., dims) at quantile `u` of each bin."""
    n_q = quantiles_m.shape[-1] - 1
    if kernel_inputs(quantiles_m, u) and idx.device.type == "cpu":
        return torch.from_numpy(_place_in_bins_compiled(quantiles_m.numpy(), idx.numpy(),
                                                     u.numpy()))
    dim = torch.arange(idx.shape[-1], device=idx.device).expand_as(idx)
    rows = quantiles_m[dim, idx]                                      # (..., dims, n_q + 1)
    at = u.to(rows.dtype) * n_q
    i = at.floor().long().clamp(0, n_q - 1)
    lo = rows.gather(-1, i.unsqueeze(-1)).squeeze(-1)
    hi = rows.gather(-1, (i + 1).unsqueeze(-1)).squeeze(-1)
    return lo + (at - i) * (hi - lo)


def _place_in_bins_compiled(quantiles_m: np.ndarray, idx: np.ndarray, u: np.ndarray) -> np.ndarray:
    """`place_in_bins` by the compiled loop `_place_rows`, float32 throughout (the torch
    lines' roundings): a rollout frame's one or two rows cost a tenth of the torch dispatch."""
    out = np.empty(u.shape, dtype=np.float32)
    dims = idx.shape[-1]
    _place_rows(quantiles_m, np.ascontiguousarray(idx.reshape(-1, dims), dtype=np.int64),
                np.ascontiguousarray(u.reshape(-1, dims)), out.reshape(-1, dims))
    return out


@njit(cache=True)
def _place_rows(quantiles_m, idx, u, out):
    n_q = quantiles_m.shape[-1] - 1
    for r in range(idx.shape[0]):
        for d in range(idx.shape[1]):
            at = u[r, d] * np.float32(n_q)
            i = min(max(int(math.floor(at)), 0), n_q - 1)
            lo = quantiles_m[d, idx[r, d], i]
            hi = quantiles_m[d, idx[r, d], i + 1]
            out[r, d] = lo + (at - np.float32(i)) * (hi - lo)


def player_offsets(frames: pd.DataFrame, rallies: pd.DataFrame,
                   server_frame: bool = True) -> np.ndarray:
    """Recorded rallies (`RallyData.frames`, `.rallies`) -> (N, 2) each player's offsets from
    constant velocity (x[t+1] - 2 x[t] + x[t-1], m) over three consecutive frames, the player
    head's targets; with `server_frame` turned as the model's frame turns them (the server at
    +x, `SportsNGEN.frame_sign`). Read from the tables directly, not through training windows
    (`data.tokens`): the same numbers without windowing or augmentation, for 14 million
    offsets in seconds."""
    r = rallies.set_index("rally_id")[["server", "receiver"]].astype(str)
    f = frames[["rally_id", "frame", "object", "x", "y"]]
    f = f.assign(object=f["object"].astype(str))
    names = r.reindex(f["rally_id"].to_numpy())
    server = f["object"].to_numpy() == names["server"].to_numpy()
    f = f.assign(server=server)[server | (f["object"].to_numpy() == names["receiver"].to_numpy())]
    f = f.sort_values(["rally_id", "object", "frame"]).reset_index(drop=True)
    key = f["rally_id"].astype(str) + "|" + f["object"]
    inner = (key.shift(1) == key) & (key.shift(-1) == key) & \
        (f["frame"].diff() == 1) & (f["frame"].diff(-1) == -1)
    xy = f[["x", "y"]].to_numpy(np.float64)
    off = np.full_like(xy, np.nan)
    off[1:-1] = xy[2:] - 2.0 * xy[1:-1] + xy[:-2]
    if server_frame:
        first_x = f[f["server"]].groupby("rally_id")["x"].first()
        sign = np.where(first_x.reindex(f["rally_id"].to_numpy()).to_numpy() < 0, -1.0, 1.0)
        off = off * sign[:, None]
    return off[inner.to_numpy()]
