"""Token embeddings: object tokens (identity + features through an MLP) and context tokens.

Ablation switches of `ModelConfig` act here, so the decoder needs no change: feature groups not
in `cfg.features` are dropped from the object MLP's input (a smaller first layer; changing them
cannot change the output), `id_dim = 0` concatenates no identity, and `use_context = False`
replaces the four context tokens by learned constants of the same shape (B, 4, d).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from sportsngen.model.config import FEATURE_GROUPS, ModelConfig
from sportsngen.model.inputs import N_FEATURES, SCORE_FIELDS

N_CONTEXT = 4  # surface, tournament, serve number, score


def mlp(sizes: list[int], dropout: float = 0.0) -> nn.Sequential:
    """Linear layers with GELU between them (none after the last)."""
    layers: list[nn.Module] = []
    for i in range(len(sizes) - 1):
        layers.append(nn.Linear(sizes[i], sizes[i + 1]))
        if i < len(sizes) - 2:
            layers += [nn.GELU(), nn.Dropout(dropout)]
    return nn.Sequential(*layers)


def run_mlp(seq: nn.Sequential, x: torch.Tensor) -> torch.Tensor:
    """`seq(x)` for an `mlp` outside training, as plain functional calls: a rollout step is a
    few hundred tiny operations at batch 1, and module calls (and no-op dropouts) add to each."""
    if seq.training:
        return seq(x)
    for m in seq:
        if isinstance(m, nn.Linear):
            x = F.linear(x, m.weight, m.bias)
        elif isinstance(m, nn.GELU):
            x = F.gelu(x, approximate=m.approximate)
        elif not isinstance(m, nn.Dropout):
            x = m(x)
    return x


def feature_columns(features: tuple[str, ...]) -> list[int]:
    """Columns of the N_FEATURES object features that the groups `features` cover."""
    assert max(end for _, end in FEATURE_GROUPS.values()) == N_FEATURES
    return [c for g in features for c in range(*FEATURE_GROUPS[g])]


class ObjectEmbedding(nn.Module):
    """[identity embedding, kept features] -> MLP (the paper's 22 + 8 = 30 -> 256 -> 512 -> d).

    The identity table exists even when `id_dim` is 0 (zero-width rows), so code that reaches
    for `embed.identity` (fine-tuning) keeps working; nothing is concatenated then.
    """

    def __init__(self, cfg: ModelConfig, with_identity: bool = True, d_model: int | None = None,
                 n_extra: int = 0):
        super().__init__()
        self.with_identity = with_identity
        d = d_model or cfg.d_model
        cols = feature_columns(cfg.features)
        # None keeps the full-feature path exactly the pre-ablation computation (no gather).
        self.columns = None if len(cols) == N_FEATURES else cols
        # `n_extra` columns computed by the model from the features (the ball's forecast,
        # `sportsngen.model.forecast`) come last, so a model given them later starts from the
        # same function with zero weights on them (`widen_for_extra`).
        in_dim = len(cols) + (cfg.id_dim if with_identity else 0) + n_extra
        self.identity = nn.Embedding(cfg.n_ids, cfg.id_dim) if with_identity else None
        self.mlp = mlp([in_dim, *cfg.embed_hidden, d], cfg.dropout)

    def forward(self, feats: torch.Tensor, ident: torch.Tensor | None = None,
                extra: torch.Tensor | None = None) -> torch.Tensor:
        """(B, T, K, N_FEATURES) features, (B, K) identity indices, (B, T, K, n_extra) extra
        columns or None -> (B, T, K, d)."""
        if self.columns is not None:
            feats = feats[..., self.columns]
        if self.identity is not None:
            if ident is None:
                raise ValueError("this embedding needs identity indices")
            if self.identity.embedding_dim > 0:
                e = F.embedding(ident, self.identity.weight)[:, None]
                feats = torch.cat([e.expand(*feats.shape[:-1], -1), feats], dim=-1)
        if extra is not None:
            feats = torch.cat([feats, extra.to(feats.dtype)], dim=-1)
        return run_mlp(self.mlp, feats)


def widen_for_extra(state: dict, prefix: str, n_extra: int) -> dict:
    """A state dict whose `ObjectEmbedding` at `prefix` (e.g. "embed.") takes `n_extra` more
    input columns, with zero weights on them: the widened model computes what the old one did."""
    key = f"{prefix}mlp.0.weight"
    w = state[key]
    return {**state, key: torch.cat([w, w.new_zeros(w.shape[0], n_extra)], dim=1)}


class ContextEmbedding(nn.Module):
    """Four context tokens: surface, tournament, first/second serve, score (an MLP); with
    `cfg.use_context` False, four learned constants that ignore the inputs (the paper's
    baseline has no context; keeping the tokens keeps the decoder's shapes)."""

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        d = cfg.d_model
        self.use_context = cfg.use_context
        if not self.use_context:
            # Scaled like the nn.Embedding rows they replace (N(0, 1)).
            self.constant = nn.Parameter(torch.randn(N_CONTEXT, d))
            return
        self.surface = nn.Embedding(cfg.n_surfaces, d)
        self.tournament = nn.Embedding(cfg.n_tournaments, d)
        self.serve = nn.Embedding(2, d)
        self.score = mlp([len(SCORE_FIELDS), cfg.score_hidden, d])

    def forward(self, surface: torch.Tensor, tournament: torch.Tensor, serve: torch.Tensor,
                score: torch.Tensor) -> torch.Tensor:
        """(B,), (B,), (B,), (B, 7) -> (B, 4, d)."""
        if not self.use_context:
            return self.constant.expand(surface.shape[0], -1, -1)
        return torch.stack([self.surface(surface), self.tournament(tournament),
                            self.serve(serve), self.score(score)], dim=1)
