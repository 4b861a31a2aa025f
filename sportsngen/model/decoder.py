"""Decoder f: context tokens + object tokens -> a transformer with the baller2vec mask -> heads.

Token order: the 4 context tokens, then frame-major object tokens (frame 0: server, receiver,
ball; frame 1: ...). Mask: context attends to context only; an object token attends to the
context and to the object tokens of its own frame and of the `window_frames - 1` frames before
it (a band: sliding-window attention at every layer). Training windows are never longer than
`window_frames`, so there the band is the plain causal baller2vec mask.

There is no positional encoding (time is a token feature), so a token's keys and values do not
depend on where it sits in the sequence, and attention does not depend on the order of the keys.
That makes the key/value cache (`init_cache`, `forward_step`) a ring buffer: each frame's keys
and values go to slot `frame % window_frames` of every layer, overwriting the frame that just
left the band. It is exact at any rally length: `forward_step` frame by frame equals `forward`
on the whole rally so far with the band mask (tested to 1e-4). It is not the same as re-running
only the last `window_frames` frames from scratch (a truncated history, whose first frames see
nothing before them) once a rally outgrows the window; `sportsngen.sim.rollout` measures both.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from sportsngen.model import (
    contact_reach,
    reach_kernel,
    receiver_start,
    serve_bias,
    step_kernel,
    strike,
    strike_heads,
)
from sportsngen.model import strike_bias as strike_bias_table
from sportsngen.model.bin_quantiles import place_in_bins
from sportsngen.model.bins import ball_bins, player_bins
from sportsngen.model.centre import object_centres_m
from sportsngen.model.config import FEATURE_GROUPS, ModelConfig
from sportsngen.model.embedding import ContextEmbedding, ObjectEmbedding, run_mlp
from sportsngen.model.forecast import (
    clock_columns,
    extra_columns,
    forecast_columns,
    forecast_outside_graph,
)
from sportsngen.model.heads import FactorisedHead, SubBinHead, make_head
from sportsngen.model.inputs import BALL, GENERIC_ID, N_FEATURES, N_OBJECTS, N_SPECIAL_IDS
from sportsngen.model.packed import kernel_inputs, packed
from sportsngen.model.sampling import uniform_in_bin

# Object-feature columns that change sign when the court is turned about the vertical through
# the net's centre: position and velocity x and y.
TURNED_FEATURES = tuple(FEATURE_GROUPS[g][0] + i for g in ("position", "velocity") for i in (0, 1))


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

    def step(self, x: torch.Tensor, k_ring: torch.Tensor, v_ring: torch.Tensor, lo: int,
             n_keys: int) -> torch.Tensor:
        """One frame's tokens x (B, 3, d): write their keys/values into ring slots lo:lo+3, then
        attend to the first n_keys slots (no mask: every filled slot is visible)."""
        b, n, d = x.shape
        q, k, v = F.linear(x, self.qkv.weight, self.qkv.bias).view(
            b, n, 3, self.n_heads, d // self.n_heads).permute(2, 0, 3, 1, 4)
        k_ring[:, :, lo:lo + n] = k
        v_ring[:, :, lo:lo + n] = v
        # Two batched matmuls on (rows x heads)-major 3-D views, the scale inside the first:
        # with 3 queries a row they beat the fused CPU kernel at every batch size (~6x at
        # B = 1; rollouts 13-18 % faster at B = 64-256, docs/benchmarks.md).
        bh, slots, dh = b * self.n_heads, k_ring.shape[2], q.shape[-1]
        keys = k_ring.view(bh, slots, dh)[:, :n_keys]
        values = v_ring.view(bh, slots, dh)[:, :n_keys]
        att = torch.baddbmm(q.new_zeros(()), q.reshape(bh, n, dh), keys.transpose(1, 2),
                            beta=0.0, alpha=dh ** -0.5)
        y = torch.bmm(att.softmax(dim=-1), values).view(b, self.n_heads, n, dh)
        return F.linear(y.transpose(1, 2).reshape(b, n, d), self.out.weight, self.out.bias)


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

    def step(self, x, k_ring, v_ring, lo: int, n_keys: int):
        if self.training:
            x = x + self.drop(self.attn.step(self.ln1(x), k_ring, v_ring, lo, n_keys))
            return x + self.ff(self.ln2(x))
        # Inference: functional calls, no module-call overhead (the step is latency-bound).
        x = x + self.attn.step(_layer_norm(self.ln1, x), k_ring, v_ring, lo, n_keys)
        return x + run_mlp(self.ff, _layer_norm(self.ln2, x))


# Up to this many rallies a cached step runs `step_kernel.blocks_rows`: 0.36 ms a step at one
# against 0.79 in torch, 0.73 against 1.12 at two; at four, torch's BLAS is as fast
# (scratch outputs/s102/step_check.py, one thread).
STEP_KERNEL_ROWS = 2


_FRAMES_EDGES = np.array(contact_reach.FRAMES_EDGES, dtype=np.float32)
_ASIDE_EDGES_M = np.array(contact_reach.ASIDE_EDGES_M, dtype=np.float32)


def _compiled_blocks(x: torch.Tensor, k_rings: list[torch.Tensor], training: bool) -> bool:
    """Whether a cached step's blocks run compiled: a few rallies outside training, the rings
    contiguous (they are as `KVCache` makes them) and `kernel_inputs`."""
    return (len(x) <= STEP_KERNEL_ROWS and not training
            and all(k.is_contiguous() for k in k_rings) and kernel_inputs(x))


def _layer_norm(ln: nn.LayerNorm, x: torch.Tensor) -> torch.Tensor:
    return F.layer_norm(x, ln.normalized_shape, ln.weight, ln.bias, ln.eps)


def baller2vec_mask(n_ctx: int, n_frames: int, n_objects: int = N_OBJECTS,
                    device: torch.device | str = "cpu",
                    window_frames: int | None = None) -> torch.Tensor:
    """(L, L) bool, True where query row may attend to key column; L = n_ctx + frames*objects.
    With `window_frames`, an object token sees object tokens of at most that many frames
    (its own included); context tokens stay visible to all."""
    frame = torch.cat([torch.full((n_ctx,), -1, device=device),
                       torch.arange(n_frames, device=device).repeat_interleave(n_objects)])
    is_ctx = frame < 0
    mask = frame[None, :] <= frame[:, None]           # keys of earlier frames (and context)
    mask &= ~(is_ctx[:, None] & ~is_ctx[None, :])     # context never attends to objects
    if window_frames is not None and n_frames > window_frames:
        mask &= is_ctx[None, :] | (frame[None, :] > frame[:, None] - window_frames)
    return mask


@dataclass
class KVCache:
    """Per-layer ring buffers of keys/values: the context tokens, then `max_frames` frame slots
    of 3 object tokens each (frame f lives in slot f % max_frames)."""

    k: list[torch.Tensor]     # per layer (B, heads, n_ctx + max_frames * 3, d_head)
    v: list[torch.Tensor]
    ident: torch.Tensor       # (B, 3) identity indices
    n_ctx: int
    n_frames: int             # frames seen so far (the ring holds the last max_frames of them)
    max_frames: int
    # The last frame's object features (B, 3, F), for the ball's forecast (its spin is read
    # from two velocities); None before the first frame.
    last_feats: torch.Tensor | None = None

    @property
    def n_keys(self) -> int:
        """How many key slots are filled."""
        return self.n_ctx + N_OBJECTS * min(self.n_frames, self.max_frames)

    def select(self, idx: torch.Tensor) -> KVCache:
        """The cache of the batch rows `idx` (the rollout compacts finished rallies away). Only
        the filled slots are copied: attention reads no others, and a rollout compacts at every
        finished rally, so copying whole rings was a sixth of the diagnostics' rollout time."""
        n = self.n_keys

        def rows(ring: torch.Tensor) -> torch.Tensor:
            out = ring.new_empty((len(idx), *ring.shape[1:]))
            out[:, :, :n] = ring[idx, :, :n]
            return out

        return KVCache([rows(k) for k in self.k], [rows(v) for v in self.v], self.ident[idx],
                       self.n_ctx, self.n_frames, self.max_frames,
                       None if self.last_feats is None else self.last_feats[idx])


def _empty_ring(ctx_kv: torch.Tensor, max_frames: int) -> torch.Tensor:
    b, h, n_ctx, d = ctx_kv.shape
    ring = ctx_kv.new_zeros(b, h, n_ctx + N_OBJECTS * max_frames, d)
    ring[:, :, :n_ctx] = ctx_kv
    return ring


# A next ball frame this far from its bin centre along the first axis is a racket contact (or a
# bounce): free flight stays within centimetres of the velocity step.
CONTACT_OFFSET_M = 0.5


def _input_shift(cfg: ModelConfig, flag: str, rows: int) -> nn.Embedding | None:
    """A learned shift of the strike head's input with `rows` rows where `cfg.<flag>` is on,
    at zero: a file without the shift reads the same with it."""
    if not getattr(cfg, flag):
        return None
    if not cfg.strike_head:
        raise ValueError(f"{flag} shifts the strike head's input: it needs strike_head=True")
    shift = nn.Embedding(rows, cfg.d_model)
    nn.init.zeros_(shift.weight)
    return shift


class SportsNGEN(nn.Module):
    """Decoder f with its output bins and heads (players 2-D, ball 3-D)."""

    # The buffers with a row per identity, (n_ids, ...) where the config has them: a player
    # added for fine-tuning gets a row at zero in each (`train.finetune.add_player`).
    PER_IDENTITY_TABLES = ("serve_bias", "serve_aim", "serve_short", "serve_lateral",
                           "receiver_start",
                           "strike_bias",
                           "strike_width", "strike_return", "strike_pressure",
                           "strike_shape", "strike_shape_opponent", "strike_player",
                           "strike_opponent", "strike_late", "strike_surface",
                           "strike_second")

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        self.cfg = cfg
        self._compiled_step = None      # `compile_step`
        self.embed = ObjectEmbedding(cfg, n_extra=extra_columns(cfg))
        self.context = ContextEmbedding(cfg)
        self.blocks = nn.ModuleList(Block(cfg.d_model, cfg.n_heads, cfg.ff_mult, cfg.dropout,
                                          cfg.attn_dropout)
                                    for _ in range(cfg.n_layers))
        self.ln_f = nn.LayerNorm(cfg.d_model)
        self.player_bins = player_bins(cfg)
        self.ball_bins = ball_bins(cfg)
        mid = (self.ball_bins.edges[0, :-1] + self.ball_bins.edges[0, 1:]) / 2
        self.register_buffer("_contact_bins", mid.abs() > CONTACT_OFFSET_M, persistent=False)
        self.register_buffer("_ball_bin_x_m", mid, persistent=False)
        turn = torch.ones(N_FEATURES)
        turn[list(TURNED_FEATURES)] = -1.0
        self.register_buffer("_turn", turn, persistent=False)   # the object features turned
        self.player_head = make_head(cfg.head, cfg.d_model, cfg.n_bins, 2, cfg.head_hidden)
        self.ball_head = make_head(cfg.head, cfg.d_model, cfg.n_bins, 3, cfg.head_hidden)
        self.ball_sub_head = SubBinHead(cfg.d_model, cfg.n_bins, 3, cfg.ball_sub_bins,
                                        cfg.head_hidden) if cfg.ball_sub_bins else None
        self.strike_head = FactorisedHead(cfg.d_model, strike.STRIKE_BINS, 4, cfg.head_hidden) \
            if cfg.strike_head else None
        self.serve_head = FactorisedHead(cfg.d_model, strike.STRIKE_BINS, 4, cfg.head_hidden) \
            if cfg.serve_head else None
        self.strike_role = _input_shift(cfg, "strike_roles", strike_heads.N_STRIKE_ROLES)
        self.strike_shot = _input_shift(cfg, "strike_shots", strike_heads.N_SHOT_BUCKETS)
        self.strike_player = self.strike_opponent = None
        if cfg.strike_players:
            self.strike_player = nn.Parameter(torch.zeros(cfg.n_ids, 2, cfg.d_model))
            self.strike_opponent = nn.Parameter(torch.zeros(cfg.n_ids, 2, cfg.d_model))
        # Fitted by moment matching (`train.serve_bias`), not by gradient: a buffer, zero until
        # then, so the head draws as without it.
        self.register_buffer("serve_bias", torch.zeros(cfg.n_ids, serve_bias.N_SERVES,
                                                       serve_bias.N_KINDS)
                             if cfg.serve_bias else None)
        self.register_buffer("serve_aim", torch.zeros(cfg.n_ids, serve_bias.N_SERVES)
                             if cfg.serve_aim else None)
        self.register_buffer("serve_short", torch.zeros(cfg.n_ids, serve_bias.N_SERVES)
                             if cfg.serve_short else None)
        self.register_buffer("serve_lateral", torch.zeros(cfg.n_ids, serve_bias.N_SERVES,
                                                          serve_bias.N_LATERAL_BANDS)
                             if cfg.serve_lateral else None)
        self.register_buffer("strike_bias", torch.zeros(cfg.n_ids, strike_bias_table.N_ROLES,
                                                        strike_bias_table.N_KINDS)
                             if cfg.strike_bias else None)
        self.register_buffer("strike_width", torch.zeros(cfg.n_ids, strike_bias_table.N_ROLES)
                             if cfg.strike_width else None)
        self.register_buffer("strike_return", torch.zeros(cfg.n_ids, strike_bias_table.N_KINDS)
                             if cfg.strike_return else None)
        # By surface and serve, not by identity: not among PER_IDENTITY_TABLES.
        self.register_buffer("strike_return_surface",
                             torch.zeros(cfg.n_surfaces, serve_bias.N_SERVES,
                                         strike_bias_table.N_KINDS)
                             if cfg.strike_return_surface else None)
        self.register_buffer("strike_surface",
                             torch.zeros(cfg.n_ids, cfg.n_surfaces, strike_bias_table.N_STROKES,
                                         strike_bias_table.N_KINDS)
                             if cfg.strike_surface else None)
        self.register_buffer("strike_pressure",
                             torch.zeros(cfg.n_ids, strike_bias_table.N_ROLES,
                                         strike_bias_table.N_KINDS)
                             if cfg.strike_pressure else None)
        self.register_buffer("strike_late",
                             torch.zeros(cfg.n_ids, strike_bias_table.N_ROLES,
                                         strike_bias_table.N_KINDS)
                             if cfg.strike_late else None)
        self.register_buffer("strike_second",
                             torch.zeros(cfg.n_ids, strike_bias_table.N_ROLES,
                                         strike_bias_table.N_KINDS)
                             if cfg.strike_second else None)
        # By band of the contact's depth, not by identity: not among PER_IDENTITY_TABLES.
        self.register_buffer("strike_depth",
                             torch.zeros(strike_bias_table.N_DEPTH_BANDS,
                                         strike_bias_table.N_ROLES, strike_bias_table.N_KINDS)
                             if cfg.strike_depth else None)
        shape = (cfg.n_ids, strike_bias_table.N_ROLES, strike_bias_table.N_SHAPES)
        self.register_buffer("strike_shape", torch.zeros(shape) if cfg.strike_shape else None)
        self.register_buffer("strike_shape_opponent",
                             torch.zeros(shape) if cfg.strike_shape else None)
        self.register_buffer("receiver_start",
                             torch.zeros(cfg.n_ids, receiver_start.N_SERVES,
                                         receiver_start.N_WAIT)
                             if cfg.receiver_start else None)
        self.register_buffer("contact_reach",
                             torch.zeros(contact_reach.N_KINDS, contact_reach.N_FRAMES_CELLS,
                                         contact_reach.N_ASIDE_CELLS)
                             if cfg.contact_reach else None)

    # --- inputs -------------------------------------------------------------------------------
    def _ident(self, ident: torch.Tensor) -> torch.Tensor:
        if self.cfg.generic_identity:
            ident = torch.where(ident >= N_SPECIAL_IDS, torch.full_like(ident, GENERIC_ID), ident)
        if (ident < 0).any() or (ident >= self.cfg.n_ids).any():
            raise ValueError(f"identity index out of range [0, {self.cfg.n_ids}): "
                             f"{ident.unique().tolist()}")
        return ident

    # --- the model's court frame (`ModelConfig.frame`) ----------------------------------------
    def frame_sign(self, pos_m: torch.Tensor) -> torch.Tensor | None:
        """(..., 3, C) positions (or object features: column 0 is x over a positive scale) of
        a frame's objects -> (..., 1, 1) +1 / -1: the turn about the vertical through the net's
        centre that puts the server at +x (None in the world frame). It is its own inverse. The
        server never crosses the net, so his side of it says which end he serves from."""
        if self.cfg.frame == "world":
            return None
        return torch.where(pos_m[..., :1, :1] < 0, -1.0, 1.0).to(pos_m.dtype)

    def to_model_frame(self, vec: torch.Tensor, pos_m: torch.Tensor) -> torch.Tensor:
        """(..., 3, 3) per-object vectors (offsets, velocities) of frames whose objects stand
        at `pos_m` -> the same in the model's frame (x and y turned in the server frame); also
        back to the world, the turn being its own inverse."""
        sign = self.frame_sign(pos_m)
        if sign is None:
            return vec
        return torch.cat([vec[..., :2] * sign, vec[..., 2:]], dim=-1)

    def _frame_features(self, feats: torch.Tensor) -> torch.Tensor:
        """Object features (..., 3, N_FEATURES) in the model's frame: position and velocity x
        and y turned with the server's side."""
        sign = self.frame_sign(feats)
        if sign is None:
            return feats
        return torch.where(sign < 0, feats * self._turn.to(feats.dtype), feats)

    def _embed(self, feats: torch.Tensor, ident: torch.Tensor,
               before: torch.Tensor | None = None) -> torch.Tensor:
        """Object features (B, T, 3, N_FEATURES) in the world (and the frame before the first's,
        (B, 3, N_FEATURES) or None) -> token embeddings; with `ball_forecast`, the ball's flight
        forecast in the players' tokens (`forecast.forecast_columns`), read in the model's
        frame: flight is the same physics at either end."""
        clock = clock_columns(feats, self.cfg.clock_s) if self.cfg.clock_s > 0 else None
        if not self.cfg.ball_forecast:
            return self.embed(self._frame_features(feats), ident, clock)
        if before is None:
            before = torch.full_like(feats[:, 0], float("nan"))
        prev = torch.cat([before[:, None], feats[:, :-1]], dim=1)
        feats = self._frame_features(feats)
        # The frame before turned as its own frame: NaN rows stay NaN.
        prev = torch.where(torch.isnan(prev), prev, self._frame_features(prev.nan_to_num()))
        extra = forecast_columns(feats, prev, self.cfg.fps, self.cfg.ball_intercept)
        if clock is not None:
            extra = torch.cat([extra, clock.to(extra.dtype)], dim=-1)
        return self.embed(feats, ident, extra)

    def context_tokens(self, surface, tournament, serve, score) -> torch.Tensor:
        return self.context(surface, tournament, serve, score)

    # --- full window ----------------------------------------------------------------------
    def forward(self, feats: torch.Tensor, ident: torch.Tensor, ctx: torch.Tensor,
                return_cache: bool = False):
        """feats (B, T, 3, F) object features of frames 0..T-1 of the rally, ident (B, 3),
        ctx (B, 4, d) context tokens -> h (B, T, 3, d) output states [, KVCache after them]."""
        b, t, k, _ = feats.shape
        ident = self._ident(ident)
        x = torch.cat([ctx, self._embed(feats, ident).reshape(b, t * k, -1)], dim=1)
        mask = baller2vec_mask(ctx.shape[1], t, k, device=x.device,
                               window_frames=self.cfg.window_frames)
        ks, vs = [], []
        for blk in self.blocks:
            x, (kk, vv) = blk(x, mask)
            ks.append(kk)
            vs.append(vv)
        h = self.ln_f(x[:, ctx.shape[1]:]).reshape(b, t, k, -1)
        if not return_cache:
            return h
        n_ctx, w = ctx.shape[1], self.cfg.window_frames
        keep = torch.arange(max(0, t - w), t, device=x.device)   # frames still in the band
        slots = (n_ctx + (keep % w)[:, None] * k + torch.arange(k, device=x.device)).reshape(-1)
        src = (n_ctx + keep[:, None] * k + torch.arange(k, device=x.device)).reshape(-1)
        rings = []
        for kv in (ks, vs):
            layer = []
            for m in kv:
                ring = _empty_ring(m[:, :, :n_ctx], w)
                ring[:, :, slots] = m[:, :, src]
                layer.append(ring)
            rings.append(layer)
        return h, KVCache(rings[0], rings[1], ident, n_ctx, t, w, feats[:, -1])

    # --- incremental -----------------------------------------------------------------------
    def init_cache(self, ident: torch.Tensor, ctx: torch.Tensor) -> KVCache:
        """An empty ring holding the context tokens' keys/values (context sees only context)."""
        x = ctx
        ks, vs = [], []
        w = self.cfg.window_frames
        for blk in self.blocks:
            x, (kk, vv) = blk(x)
            ks.append(_empty_ring(kk, w))
            vs.append(_empty_ring(vv, w))
        return KVCache(ks, vs, self._ident(ident), ctx.shape[1], 0, w)

    def forward_step(self, new_frame_feats: torch.Tensor, cache: KVCache):
        """Append the next frame: new_frame_feats (B, 3, F) -> (h (B, 3, d), cache). Its three
        tokens attend to the context, to each other and to the cached frames of the band."""
        lo = cache.n_ctx + N_OBJECTS * (cache.n_frames % cache.max_frames)
        cache.n_frames += 1
        step = self._compiled_step if self._compiled_step is not None else self.step_tokens
        h = step(new_frame_feats, cache.ident, cache.k, cache.v, lo, cache.n_keys,
                 cache.last_feats)
        cache.last_feats = new_frame_feats
        return h, cache

    def step_tokens(self, new_frame_feats: torch.Tensor, ident: torch.Tensor,
                    k_rings: list[torch.Tensor], v_rings: list[torch.Tensor], lo: int,
                    n_keys: int, last_feats: torch.Tensor | None = None) -> torch.Tensor:
        """The cached step's computation (see `forward_step`): writes the frame's keys/values
        into ring slots lo:lo+3 of every layer and returns the output states (B, 3, d).
        `last_feats`: the frame before's features (the ball's forecast reads its spin)."""
        b = new_frame_feats.shape[0]
        x = self._embed(new_frame_feats[:, None], ident, last_feats)
        x = x.reshape(b, N_OBJECTS, -1)
        if _compiled_blocks(x, k_rings, self.training):
            weights = packed(self.blocks, lambda: step_kernel.pack_blocks(self.blocks, self.ln_f),
                             self.ln_f)
            h = np.empty(x.shape, dtype=np.float32)
            step_kernel.blocks_rows(x.detach().contiguous().numpy(),
                                    tuple(k.numpy() for k in k_rings),
                                    tuple(v.numpy() for v in v_rings), lo, n_keys, *weights, h)
            return torch.from_numpy(h)
        for blk, k_ring, v_ring in zip(self.blocks, k_rings, v_rings):
            x = blk.step(x, k_ring, v_ring, lo, n_keys)
        return _layer_norm(self.ln_f, x)

    def compile_step(self, enable: bool = True,
                     backend: str | Callable = "inductor") -> SportsNGEN:
        """Run the cached step through `torch.compile` (or back to eager with enable=False).

        On CPU, inductor fuses the layer norms, GELUs, residual adds and softmax between the
        matmuls, which at a few rallies are most of the step: ~25 % off a B = 1 step, but only
        a few per cent off a B = 1 rollout frame (sampling is the other half) and no gain at B >= 64
        (docs/architecture.md, docs/benchmarks.md). The first steps compile (~10 s; then cached
        on disk, ~2 s), and a new batch size or cache length may recompile once. Needs a C++
        compiler on CPU. Inference only: the compiled step reads the weights as they are when
        it runs. `backend`: torch.compile's (a name or a callable); the tests trace the same
        graphs through a backend that runs them as traced (seconds, where inductor's first
        compile on a cold cache took a minute on 2 cores)."""
        if enable:
            forecast_outside_graph()
        self._compiled_step = torch.compile(self.step_tokens, backend=backend) if enable else None
        return self

    # --- targets and sampling ------------------------------------------------------------
    def centres(self, pos_m: torch.Tensor, vel_mps: torch.Tensor,
                prev_vel_mps: torch.Tensor | None = None) -> torch.Tensor:
        """Where each object's bins are centred (..., 3, 3) (`sportsngen.model.centre`);
        `prev_vel_mps`, the velocities a frame earlier, lets the ball's physics step read its
        acceleration from the track (without it: gravity and drag)."""
        return object_centres_m(pos_m, vel_mps, prev_vel_mps, self.cfg.fps, self.cfg.bin_centre,
                                self.cfg.ball_centre, BALL, self.cfg.ball_net)

    def target_offsets(self, pos_m, vel_mps, next_pos_m, prev_vel_mps=None) -> torch.Tensor:
        """Next positions as offsets from the bins' centres, in the model's frame (..., 3, 3)."""
        return self.to_model_frame(next_pos_m - self.centres(pos_m, vel_mps, prev_vel_mps),
                                   pos_m)

    def offset_bins(self, off: torch.Tensor):
        """Bin indices of `target_offsets`: (players (..., 2, 2), ball (..., 3))."""
        return (self.player_bins.index(off[..., :BALL, :2]),
                self.ball_bins.index(off[..., BALL, :]))

    def target_bins(self, pos_m, vel_mps, next_pos_m, prev_vel_mps=None):
        """Bin indices of the next positions: (players (..., 2, 2), ball (..., 3))."""
        return self.offset_bins(self.target_offsets(pos_m, vel_mps, next_pos_m, prev_vel_mps))

    def ball_sub_nll(self, h: torch.Tensor, off: torch.Tensor,
                     ball_idx: torch.Tensor) -> torch.Tensor:
        """Per ball token (...): -log p(the part of its bins the next position lies in), from
        the output states h, the offsets `off` (`target_offsets`) and their ball bins; the
        sub-bin head's share of the ball's NLL (0 without one)."""
        if self.ball_sub_head is None:
            return torch.zeros(ball_idx.shape[:-1], device=ball_idx.device)
        sub = self.ball_bins.sub_index(off[..., BALL, :], ball_idx, self.cfg.ball_sub_bins)
        return self.ball_sub_head.nll(h[..., BALL, :], ball_idx, sub)

    def strike_targets(self, pos_m: torch.Tensor, vel_mps: torch.Tensor,
                       next_pos_m: torch.Tensor, has_next: torch.Tensor, serves: bool = False):
        """`strike_heads.strike_targets` at this model's frame rate: the windows' rally strikes
        (or `serves`) and their bins."""
        return strike_heads.strike_targets(pos_m, vel_mps, next_pos_m, has_next, self.cfg.fps,
                                           serves)

    def strike_input(self, h_ball: torch.Tensor, role: torch.Tensor | None,
                     shot: torch.Tensor | None = None, hitter: torch.Tensor | None = None,
                     opponent: torch.Tensor | None = None) -> torch.Tensor:
        """The strike head's input: the ball token's state (..., d), shifted by the learned
        row of `role` (..., `strike_heads.strike_role_index`) where `cfg.strike_roles`, by
        that of the strike's number `shot` (..., 1 the return) where `cfg.strike_shots` and
        the number is given, and by the rows of the `hitter`'s and the `opponent`'s identities
        (...) in the hitter's role where `cfg.strike_players` and they are given."""
        if self.strike_role is not None:
            if role is None:
                raise ValueError("this model's strike head reads the hitter's role and the "
                                 "serve (cfg.strike_roles): give them "
                                 "(strike_heads.strike_role_index)")
            h_ball = h_ball + self.strike_role(role)
        if self.strike_shot is not None and shot is not None:
            h_ball = h_ball + self.strike_shot(strike_heads.shot_bucket(shot))
        if self.strike_player is not None and role is not None:
            receiver = torch.div(role, 2, rounding_mode="floor")
            if hitter is not None:
                h_ball = h_ball + self.strike_player[self._ident(hitter), receiver]
            if opponent is not None:
                h_ball = h_ball + self.strike_opponent[self._ident(opponent), receiver]
        return h_ball

    def strike_nll(self, h: torch.Tensor, mask: torch.Tensor, bins: torch.Tensor,
                   pos_m: torch.Tensor | None = None,
                   serve: torch.Tensor | None = None) -> torch.Tensor:
        """(B, T) -log p(strike bins | ball state) at the `strike_targets`, 0 elsewhere. With
        `cfg.strike_roles` the frames' positions `pos_m` (B, T, 3, 3) and the rallies' serve
        (B,) (0 first, 1 second) say whose strike each is."""
        role = None
        if self.strike_role is not None:
            if pos_m is None or serve is None:
                raise ValueError("this model's strike head reads the hitter's role and the "
                                 "serve (cfg.strike_roles): give pos_m and serve")
            role = strike_heads.strike_role_index(pos_m[mask],
                                                  serve[:, None].expand(mask.shape)[mask])
        return self._head_nll(self.strike_head, h, mask, bins, role)

    def serve_nll(self, h: torch.Tensor, mask: torch.Tensor, bins: torch.Tensor) -> torch.Tensor:
        """(B, T) -log p(serve bins | ball state) at the serves' `strike_targets`, 0 elsewhere."""
        return self._head_nll(self.serve_head, h, mask, bins)

    def _head_nll(self, head, h: torch.Tensor, mask: torch.Tensor, bins: torch.Tensor,
                  role: torch.Tensor | None = None) -> torch.Tensor:
        """(B, T) -log p(bins | input) of `head` at `mask`, 0 elsewhere; its input the ball
        token's state, shifted by the strike `role` rows (one a target) where given."""
        out = torch.zeros(mask.shape, device=h.device, dtype=h.dtype)
        if head is not None and bool(mask.any()):
            x = h[..., BALL, :][mask]
            out[mask] = head.nll(x if role is None else self.strike_input(x, role), bins[mask])
        return out

    def serve_head_bias(self, server_ident: torch.Tensor | None, serve: torch.Tensor | None,
                        contact_m: torch.Tensor) -> torch.Tensor | None:
        """The serve head's logit shifts (N, 4, bins) for serves of `server_ident` (N,) on
        serve `serve` (N,) struck at `contact_m` (N, 3) (`model.serve_bias`, with the aim's
        tilt where the model has `serve_aim`, the short serves' shift where it has
        `serve_short` and the lateral bands' where it has `serve_lateral`); None where the model
        has no table or the server or the serve is not given."""
        if self.serve_bias is None or server_ident is None or serve is None:
            return None
        return serve_bias.serve_dim_bias(self.serve_bias, self._ident(server_ident), serve,
                                         contact_m, self.serve_aim, self.serve_short,
                                         self.serve_lateral)

    def strike_head_bias(self, hitter_ident: torch.Tensor | None,
                         receiver: torch.Tensor | None,
                         returning: torch.Tensor | None = None,
                         opponent_ident: torch.Tensor | None = None,
                         shot: torch.Tensor | None = None,
                         ball_x_m: torch.Tensor | None = None,
                         serve: torch.Tensor | None = None,
                         surface: torch.Tensor | None = None) -> torch.Tensor | None:
        """The strike head's logit shifts (N, 4, bins) for strikes of `hitter_ident` (N,), the
        point's receiver where `receiver` (N,) bool (`model.strike_bias`, with the width's tilt
        where the model has `strike_width`, the returns' table on the rows `returning` (N,)
        bool where it has `strike_return`, and the row of `opponent_ident` (N,) on the others
        where it has `strike_pressure`, and the depth's and net height's tilts of both where it
        has `strike_shape`, and the late table on the strikes `shot` (N,) numbered
        `strike_bias.LATE_SHOT` or more where it has `strike_late`, and the depth table's row by
        where the ball is struck, `ball_x_m` (N,), on the rally strikes where it has
        `strike_depth`, and on the returns the row of `surface` (N,) (the surfaces' indices)
        and `serve` (N,) (0 first, 1 second) where it has `strike_return_surface`, and the
        hitter's row for the surface and stroke (rally ball or return) where it has
        `strike_surface`, and his second serves' row on the rally strikes of points whose
        `serve` is the second where it has `strike_second`); None where the model has no table
        or the hitter is not given."""
        if self.strike_bias is None or hitter_ident is None or receiver is None:
            return None
        opponent = None if opponent_ident is None else self._ident(opponent_ident)
        return strike_bias_table.strike_dim_bias(self.strike_bias, self._ident(hitter_ident),
                                                 receiver, self.strike_width,
                                                 self.strike_return, returning,
                                                 self.strike_pressure, opponent,
                                                 self.strike_shape,
                                                 self.strike_shape_opponent,
                                                 self.strike_late, shot,
                                                 self.strike_depth, ball_x_m,
                                                 self.strike_return_surface, serve, surface,
                                                 self.strike_surface, self.strike_second)

    def receiver_start_bias(self, server_ident: torch.Tensor | None,
                            serve: torch.Tensor | None,
                            wait_count: torch.Tensor) -> torch.Tensor | None:
        """The players' head's logit shifts (B, 2, 2, n_bins) for rallies served by
        `server_ident` (B,) on serve `serve` (B,) whose receivers have waited `wait_count`
        (B,) frames for the serve (`receiver_start.wait_frames`; 0: not waiting): his centre
        bin shifted by `model.receiver_start`; None where the model has no table or the server
        or the serve is not given."""
        if self.receiver_start is None or server_ident is None or serve is None:
            return None
        return receiver_start.player_dim_bias(self.receiver_start, self._ident(server_ident),
                                              serve, wait_count, self.cfg.n_bins)

    def contact_bin_kinds(self, pos_m: torch.Tensor, centre_m: torch.Tensor
                          ) -> tuple[torch.Tensor, torch.Tensor]:
        """Frames (..., 3, 3) whose bins are centred at `centre_m` -> which of the ball's
        first-axis bins strike it and which only jolt it ((..., n_bins) bool each,
        `contact_reach.bin_kinds`)."""
        sign = self.frame_sign(pos_m)
        bin_x = self._ball_bin_x_m if sign is None else self._ball_bin_x_m * sign[..., 0, :]
        step_x = centre_m[..., BALL, 0] - pos_m[..., BALL, 0]
        return contact_reach.bin_kinds(pos_m, step_x, bin_x.expand(*step_x.shape, -1),
                                       self.contact_bins(), self.cfg.fps)

    def contact_reach_bias(self, pos_m: torch.Tensor, vel_mps: torch.Tensor,
                           centre_m: torch.Tensor) -> torch.Tensor | None:
        """The ball head's logit shifts (..., 3, n_bins) for frames (..., 3, 3) whose bins are
        centred at `centre_m` (`centres`): a strike's and a jolt's contact bins shifted by
        `model.contact_reach` at where each ball is from its hitter; None where the model has
        no table."""
        if self.contact_reach is None:
            return None
        if pos_m.dim() == 3 and kernel_inputs(pos_m, vel_mps, centre_m, self.contact_reach):
            return self._contact_reach_bias_compiled(pos_m, vel_mps, centre_m)
        strike, jolt = self.contact_bin_kinds(pos_m, centre_m)
        return contact_reach.ball_dim_bias(self.contact_reach, pos_m, vel_mps, strike, jolt,
                                           self.cfg.fps)

    def _contact_reach_bias_compiled(self, pos_m: torch.Tensor, vel_mps: torch.Tensor,
                                     centre_m: torch.Tensor) -> torch.Tensor:
        """`contact_reach_bias` of (B, 3, 3) frames by `reach_kernel.reach_bias_rows`."""
        sign = self.frame_sign(pos_m)
        sign = np.ones(len(pos_m), np.float32) if sign is None else \
            sign.reshape(-1).float().numpy()
        out = np.empty((len(pos_m), 3, self.cfg.n_bins), dtype=np.float32)
        reach_kernel.reach_bias_rows(
            pos_m.numpy(), vel_mps.numpy(), centre_m[:, BALL, 0].contiguous().numpy(), sign,
            self._ball_bin_x_m.numpy(), self.contact_bins().numpy(),
            self.contact_reach.float().numpy(), _FRAMES_EDGES, _ASIDE_EDGES_M,
            np.float32(self.cfg.fps), np.float32(contact_reach.MIN_INCOMING_MPS), out)
        return torch.from_numpy(out)

    @torch.no_grad()
    def place_strikes(self, h: torch.Tensor, pos_m: torch.Tensor, vel_mps: torch.Tensor,
                      nxt: torch.Tensor, generator: torch.Generator | None = None,
                      top_p: float = 1.0,
                      allowed: torch.Tensor | None = None,
                      forced: torch.Tensor | None = None,
                      top_p_serve: float = 1.0,
                      serve: torch.Tensor | None = None,
                      server_ident: torch.Tensor | None = None,
                      receiver_ident: torch.Tensor | None = None,
                      returning: torch.Tensor | None = None,
                      shot: torch.Tensor | None = None,
                      surface: torch.Tensor | None = None,
                      veto: Callable[[np.ndarray, np.ndarray, bool], np.ndarray] | None = None
                      ) -> tuple[torch.Tensor, torch.Tensor]:
        """This model's strike and serve heads' draws placed in the sampled frames `nxt`
        (`strike_heads.place_strikes`; `serve` (B,) the rallies' serve, 0 first, 1 second,
        where `cfg.strike_roles` or `cfg.serve_bias`; `server_ident` (B,) the servers'
        identities, which `cfg.serve_bias` reads, and with `receiver_ident` (B,) the
        receivers', which `cfg.strike_bias` reads; `returning` (B,) bool: the rallies whose
        next contact is the return (only the serve struck so far), which `cfg.strike_return`
        reads on a strike from the receiver's end; `shot` (B,): the rallies' contacts so far,
        the number of a strike drawn now (1 the return), which `cfg.strike_shots` and
        `cfg.strike_late` read; `surface` (B,): the surfaces' indices, which
        `cfg.strike_return_surface` reads; `veto`: which launches may stand, as
        `strike_heads.place_strikes` takes it). -> (nxt, the launches' next two frames
        (B, 2, 3))."""
        # Whose strike a frame would be: the receiver's on his end, else the server's.
        recv = strike_heads.ball_on_receivers_end(pos_m)
        hitter = opponent = None
        if server_ident is not None and receiver_ident is not None:
            hitter = torch.where(recv, receiver_ident, server_ident)
            opponent = torch.where(recv, server_ident, receiver_ident)
        strike_h = None
        if self.strike_role is not None or (self.strike_shot is not None and shot is not None):
            if self.strike_role is not None and serve is None:
                raise ValueError("this model's strike head reads the serve (cfg.strike_roles): "
                                 "give serve")
            role = None if self.strike_role is None else strike_heads.role_index(recv, serve)

            def strike_h() -> torch.Tensor:     # asked only on a frame that holds a strike
                return self.strike_input(h[:, BALL], role, shot, hitter, opponent)
        serve_shift = None
        if self.serve_bias is not None and server_ident is not None and serve is not None:
            def serve_shift(rows: torch.Tensor) -> torch.Tensor:
                return self.serve_head_bias(server_ident[rows], serve[rows], pos_m[rows, BALL])
        strike_shift = None
        if self.strike_bias is not None and hitter is not None:
            def strike_shift(rows: torch.Tensor) -> torch.Tensor:
                ret = None if returning is None else recv[rows] & returning[rows]
                return self.strike_head_bias(hitter[rows], recv[rows], ret, opponent[rows],
                                             None if shot is None else shot[rows],
                                             pos_m[rows, BALL, 0],
                                             None if serve is None else serve[rows],
                                             None if surface is None else surface[rows])
        return strike_heads.place_strikes(self.strike_head, self.serve_head, h, pos_m, vel_mps,
                                          nxt, self.cfg.fps, generator, top_p, allowed, forced,
                                          top_p_serve, strike_h, serve_shift, strike_shift,
                                          veto)

    def nll(self, h: torch.Tensor, player_idx: torch.Tensor, ball_idx: torch.Tensor):
        """Per-token NLL: players (..., 2), ball (...)."""
        return (self.player_head.nll(h[..., :BALL, :], player_idx),
                self.ball_head.nll(h[..., BALL, :], ball_idx))

    def contact_bins(self) -> torch.Tensor:
        """(n_bins,) bool: the bins of the ball's first axis whose centre lies more than
        `CONTACT_OFFSET_M` from 0, a racket contact's (or a bounce's) change of course."""
        return self._contact_bins

    def sampling_frame(self, pos_m: torch.Tensor, vel_mps: torch.Tensor,
                       prev_vel_mps: torch.Tensor | None = None
                       ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """What `sample_next` reads from frames (..., 3, 3) besides the output states: the
        bins' centres (`centres`) and the ball head's contact-reach shifts
        (`contact_reach_bias`, None without a table). Deterministic, so a rollout computes it
        once a frame and its redraws of rejected rows take their rows of it: recomputed, it
        was a seventh of a frame at one rally, half of all frames being redrawn once."""
        centre = self.centres(pos_m, vel_mps, prev_vel_mps)
        return centre, self.contact_reach_bias(pos_m, vel_mps, centre)

    @torch.no_grad()
    def sample_next(self, h: torch.Tensor, pos_m: torch.Tensor, vel_mps: torch.Tensor,
                    top_p_player: float = 1.0, top_p_ball: float = 1.0,
                    generator: torch.Generator | None = None,
                    prev_vel_mps: torch.Tensor | None = None,
                    contact_odds: bool = False,
                    top_p_contact: float | None = None,
                    player_bias: torch.Tensor | None = None,
                    player_quantiles: torch.Tensor | None = None,
                    frame: tuple[torch.Tensor, torch.Tensor | None] | None = None
                    ) -> torch.Tensor:
        """Next positions (..., 3, 3) from output states h (..., 3, d): nucleus per object
        kind, then uniform inside the chosen bin. Players stay on the ground (z = 0).
        `player_bias` (..., 2, 2, n_bins): added to the players' head's logits (the
        receiver's start, `receiver_start_bias`). `player_quantiles` (2, n_bins, Q + 1): a
        player's draw lands inside its bin with the record's spread there, not uniformly
        (`bin_quantiles.place_in_bins`). With `cfg.contact_reach` the ball's odds of
        a contact are shifted by where it is from its hitter (`contact_reach_bias`).

        With the physics centre, a ball dimension that falls in the centre bin takes the
        centre itself: that step reads the acceleration from the track's last three frames, so
        noise put into a frame is integrated three times over the frames after it. Uniform
        inside the centre bin (+-0.4-0.9 mm), a free flight drifted 0.5 m (90th percentile)
        after 1 s and 1.6 m after 2 s although no frame missed by a millimetre, and the
        model's own tosses fell past the racket (docs/evaluation.md); the step now drops what
        it reads along the flight, and across it the drift is still 0.25 m after 1 s.

        `contact_odds`: the ball's nucleus is taken inside the contact bins (`contact_bins`)
        or inside the rest, chosen at the model's own odds, so a nucleus under 1 cannot cut a
        racket contact the model gives a few tens of per cent on a frame. `top_p_contact`
        (with `contact_odds`; default `top_p_ball`): the nucleus of every dimension of a
        ball that is struck, so a strike keeps more of the spread a flight does not need.

        `frame`: `sampling_frame` of these rows, computed already (a rollout's redraws of
        rejected rows reuse the frame's)."""
        centre, reach = self.sampling_frame(pos_m, vel_mps, prev_vel_mps) if frame is None \
            else frame
        shift = {} if player_bias is None else {"dim_bias": player_bias}   # factorised only
        pi = self.player_head.sample(h[..., :BALL, :], top_p_player, generator, **shift)
        bi = self.ball_head.sample(h[..., BALL, :], top_p_ball, generator,
                                   self.contact_bins() if contact_odds else None,
                                   top_p_contact if contact_odds else None,
                                   **({} if reach is None else {"dim_bias": reach}))
        u_player = uniform_in_bin(pi.shape, h.device, generator)
        p_off = self.player_bins.value(pi, u_player) if player_quantiles is None else \
            place_in_bins(player_quantiles, pi, u_player).to(centre.dtype)
        u_ball = uniform_in_bin(bi.shape, h.device, generator)
        if self.ball_sub_head is not None:
            # Under the physics centre a ball in the centre bin on every axis (free flight,
            # most frames) takes the step itself: its parts would be thrown away.
            rows = (bi != self.cfg.n_bins // 2).any(-1) if self.cfg.ball_centre == "physics" \
                else torch.ones(bi.shape[:-1], dtype=torch.bool, device=bi.device)
            part = torch.zeros_like(bi)
            if bool(rows.any()):
                part[rows] = self.ball_sub_head.sample(h[..., BALL, :][rows], bi[rows], generator)
            u_ball = (part + u_ball) / self.cfg.ball_sub_bins
        if self.cfg.ball_centre == "physics":
            u_ball = torch.where(bi == self.cfg.n_bins // 2, torch.full_like(u_ball, 0.5),
                                 u_ball)
        b_off = self.ball_bins.value(bi, u_ball)
        sign = self.frame_sign(pos_m)
        if sign is not None:    # offsets drawn in the server frame, back to the world
            p_off = p_off * sign
            b_off = torch.cat([b_off[..., :2] * sign[..., 0, :], b_off[..., 2:]], dim=-1)
        nxt = centre.clone()
        nxt[..., :BALL, :2] += p_off
        nxt[..., :BALL, 2] = 0.0
        nxt[..., BALL, :] += b_off
        return nxt
