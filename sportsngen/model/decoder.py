"""Decoder f: context tokens + object tokens -> a transformer with the baller2vec mask -> heads.

Token order: the 4 context tokens, then frame-major object tokens (frame 0: server, receiver,
ball; frame 1: ...). Mask: context attends to context only; an object token attends to the
context and to every object token up to and including its own frame. There is no positional
encoding (time is a token feature), so a token's keys and values do not depend on where it sits
in the sequence; that is what makes the key/value cache (`init_cache`, `forward_step`) exact.

On the rolling window: while a rally has at most `window_frames` frames, `forward_step` equals
recomputing the whole window (tested to 1e-4). Once the oldest frame is dropped, the kept frames'
cached keys/values of layers >= 2 were computed while older frames were still visible, so the
cache then differs from recomputing the truncated window unless n_layers == 1 (the usual
sliding-window-attention behaviour); use `forward` on the window when that exactness matters.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from sportsngen.data.tokens import BALL, GENERIC_ID, N_OBJECTS, N_SPECIAL_IDS, centre_m
from sportsngen.model.bins import Bins
from sportsngen.model.config import ModelConfig
from sportsngen.model.embedding import N_CONTEXT, ContextEmbedding, ObjectEmbedding
from sportsngen.model.heads import make_head
from sportsngen.model.sampling import uniform_in_bin


class Attention(nn.Module):
    def __init__(self, d_model: int, n_heads: int, dropout: float):
        super().__init__()
        self.n_heads = n_heads
        self.qkv = nn.Linear(d_model, 3 * d_model)
        self.out = nn.Linear(d_model, d_model)
        self.dropout = dropout

    def forward(self, x: torch.Tensor, mask: torch.Tensor | None = None,
                past: tuple[torch.Tensor, torch.Tensor] | None = None):
        """x (B, L, d); mask (L, L_all) bool, True = may attend; past = cached (k, v) keys that
        come before x. Returns (out (B, L, d), (k, v) of x alone)."""
        b, n, d = x.shape
        q, k, v = self.qkv(x).view(b, n, 3, self.n_heads, d // self.n_heads).permute(
            2, 0, 3, 1, 4)
        k_all, v_all = (k, v) if past is None else (torch.cat([past[0], k], dim=2),
                                                    torch.cat([past[1], v], dim=2))
        y = F.scaled_dot_product_attention(q, k_all, v_all, attn_mask=mask,
                                           dropout_p=self.dropout if self.training else 0.0)
        return self.out(y.transpose(1, 2).reshape(b, n, d)), (k, v)


class Block(nn.Module):
    """Pre-norm transformer block."""

    def __init__(self, d_model: int, n_heads: int, ff_mult: int, dropout: float,
                 attn_dropout: float = 0.0):
        super().__init__()
        self.ln1 = nn.LayerNorm(d_model)
        self.attn = Attention(d_model, n_heads, attn_dropout)
        self.ln2 = nn.LayerNorm(d_model)
        self.ff = nn.Sequential(nn.Linear(d_model, ff_mult * d_model), nn.GELU(),
                                nn.Linear(ff_mult * d_model, d_model), nn.Dropout(dropout))
        self.drop = nn.Dropout(dropout)

    def forward(self, x, mask=None, past=None):
        a, kv = self.attn(self.ln1(x), mask, past)
        x = x + self.drop(a)
        return x + self.ff(self.ln2(x)), kv


def baller2vec_mask(n_ctx: int, n_frames: int, n_objects: int = N_OBJECTS,
                    device: torch.device | str = "cpu") -> torch.Tensor:
    """(L, L) bool, True where query row may attend to key column; L = n_ctx + frames*objects."""
    frame = torch.cat([torch.full((n_ctx,), -1, device=device),
                       torch.arange(n_frames, device=device).repeat_interleave(n_objects)])
    is_ctx = frame < 0
    mask = frame[None, :] <= frame[:, None]           # keys of earlier frames (and context)
    mask &= ~(is_ctx[:, None] & ~is_ctx[None, :])     # context never attends to objects
    return mask


@dataclass
class KVCache:
    """Per-layer keys/values of the context tokens and of the last `n_frames` frames."""

    k: list[torch.Tensor]     # per layer (B, heads, n_ctx + n_frames * 3, d_head)
    v: list[torch.Tensor]
    ident: torch.Tensor       # (B, 3) identity indices
    n_frames: int
    max_frames: int

    def drop_oldest(self) -> None:
        lo, hi = N_CONTEXT, N_CONTEXT + N_OBJECTS
        self.k = [torch.cat([k[:, :, :lo], k[:, :, hi:]], dim=2) for k in self.k]
        self.v = [torch.cat([v[:, :, :lo], v[:, :, hi:]], dim=2) for v in self.v]
        self.n_frames -= 1


class SportsNGEN(nn.Module):
    """Decoder f with its output bins and heads (players 2-D, ball 3-D)."""

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        self.cfg = cfg
        self.embed = ObjectEmbedding(cfg)
        self.context = ContextEmbedding(cfg)
        self.blocks = nn.ModuleList(Block(cfg.d_model, cfg.n_heads, cfg.ff_mult, cfg.dropout,
                                          cfg.attn_dropout)
                                    for _ in range(cfg.n_layers))
        self.ln_f = nn.LayerNorm(cfg.d_model)
        dt = 1.0 / cfg.fps
        self.player_bins = Bins((cfg.player_max_speed_mps * dt,) * 2, cfg.n_bins,
                                cfg.bin_spacing)
        self.ball_bins = Bins(tuple(s * dt for s in cfg.ball_max_speed_mps), cfg.n_bins,
                              cfg.bin_spacing)
        self.player_head = make_head(cfg.head, cfg.d_model, cfg.n_bins, 2, cfg.head_hidden)
        self.ball_head = make_head(cfg.head, cfg.d_model, cfg.n_bins, 3, cfg.head_hidden)

    # --- inputs -------------------------------------------------------------------------------
    def _ident(self, ident: torch.Tensor) -> torch.Tensor:
        if self.cfg.generic_identity:
            ident = torch.where(ident >= N_SPECIAL_IDS, torch.full_like(ident, GENERIC_ID), ident)
        if (ident < 0).any() or (ident >= self.cfg.n_ids).any():
            raise ValueError(f"identity index out of range [0, {self.cfg.n_ids}): "
                             f"{ident.unique().tolist()}")
        return ident

    def context_tokens(self, surface, tournament, serve, score) -> torch.Tensor:
        return self.context(surface, tournament, serve, score)

    # --- full window ----------------------------------------------------------------------
    def forward(self, feats: torch.Tensor, ident: torch.Tensor, ctx: torch.Tensor,
                return_cache: bool = False):
        """feats (B, T, 3, F) object features, ident (B, 3), ctx (B, 4, d) context tokens
        -> h (B, T, 3, d) output states [, KVCache of the window]."""
        b, t, k, _ = feats.shape
        ident = self._ident(ident)
        x = torch.cat([ctx, self.embed(feats, ident).reshape(b, t * k, -1)], dim=1)
        mask = baller2vec_mask(ctx.shape[1], t, k, device=x.device)
        ks, vs = [], []
        for blk in self.blocks:
            x, (kk, vv) = blk(x, mask)
            ks.append(kk)
            vs.append(vv)
        h = self.ln_f(x[:, ctx.shape[1]:]).reshape(b, t, k, -1)
        if not return_cache:
            return h
        cache = KVCache(ks, vs, ident, t, max(self.cfg.window_frames, t))
        return h, cache

    # --- incremental -----------------------------------------------------------------------
    def init_cache(self, ident: torch.Tensor, ctx: torch.Tensor,
                   max_frames: int | None = None) -> KVCache:
        """A cache holding the context tokens' keys/values (context sees only context)."""
        x = ctx
        ks, vs = [], []
        for blk in self.blocks:
            x, (kk, vv) = blk(x)
            ks.append(kk)
            vs.append(vv)
        return KVCache(ks, vs, self._ident(ident), 0, max_frames or self.cfg.window_frames)

    def forward_step(self, new_frame_feats: torch.Tensor, cache: KVCache):
        """Append one frame: new_frame_feats (B, 3, F) -> (h (B, 3, d), cache). The new tokens
        attend to the cached context and frames and to each other; the oldest frame is
        dropped first when the cache already holds `max_frames` frames."""
        if cache.n_frames >= cache.max_frames:
            cache.drop_oldest()
        b = new_frame_feats.shape[0]
        x = self.embed(new_frame_feats[:, None], cache.ident).reshape(b, N_OBJECTS, -1)
        for i, blk in enumerate(self.blocks):
            x, (kk, vv) = blk(x, None, (cache.k[i], cache.v[i]))
            cache.k[i] = torch.cat([cache.k[i], kk], dim=2)
            cache.v[i] = torch.cat([cache.v[i], vv], dim=2)
        cache.n_frames += 1
        return self.ln_f(x), cache

    # --- targets and sampling ------------------------------------------------------------
    def target_bins(self, pos_m, vel_mps, next_pos_m):
        """Bin indices of the next positions: (players (..., 2, 2), ball (..., 3))."""
        off = next_pos_m - centre_m(pos_m, vel_mps, self.cfg.fps, self.cfg.bin_centre)
        return (self.player_bins.index(off[..., :BALL, :2]),
                self.ball_bins.index(off[..., BALL, :]))

    def nll(self, h: torch.Tensor, player_idx: torch.Tensor, ball_idx: torch.Tensor):
        """Per-token NLL: players (..., 2), ball (...)."""
        return (self.player_head.nll(h[..., :BALL, :], player_idx),
                self.ball_head.nll(h[..., BALL, :], ball_idx))

    @torch.no_grad()
    def sample_next(self, h: torch.Tensor, pos_m: torch.Tensor, vel_mps: torch.Tensor,
                    top_p_player: float = 1.0, top_p_ball: float = 1.0,
                    generator: torch.Generator | None = None) -> torch.Tensor:
        """Next positions (..., 3, 3) from output states h (..., 3, d): nucleus per object
        kind, then uniform inside the chosen bin. Players stay on the ground (z = 0)."""
        centre = centre_m(pos_m, vel_mps, self.cfg.fps, self.cfg.bin_centre)
        pi = self.player_head.sample(h[..., :BALL, :], top_p_player, generator)
        bi = self.ball_head.sample(h[..., BALL, :], top_p_ball, generator)
        p_off = self.player_bins.value(pi, uniform_in_bin(pi.shape, h.device, generator))
        b_off = self.ball_bins.value(bi, uniform_in_bin(bi.shape, h.device, generator))
        nxt = centre.clone()
        nxt[..., :BALL, :2] += p_off
        nxt[..., :BALL, 2] = 0.0
        nxt[..., BALL, :] += b_off
        return nxt
