"""Token embeddings: object tokens (identity + features through an MLP) and context tokens."""

from __future__ import annotations

import torch
from torch import nn

from sportsngen.data.tokens import N_FEATURES, SCORE_FIELDS
from sportsngen.model.config import ModelConfig

N_CONTEXT = 4  # surface, tournament, serve number, score


def mlp(sizes: list[int], dropout: float = 0.0) -> nn.Sequential:
    """Linear layers with GELU between them (none after the last)."""
    layers: list[nn.Module] = []
    for i in range(len(sizes) - 1):
        layers.append(nn.Linear(sizes[i], sizes[i + 1]))
        if i < len(sizes) - 2:
            layers += [nn.GELU(), nn.Dropout(dropout)]
    return nn.Sequential(*layers)


class ObjectEmbedding(nn.Module):
    """[identity embedding, 8 features] -> MLP (the paper's 30 -> 256 -> 512 -> d)."""

    def __init__(self, cfg: ModelConfig, with_identity: bool = True, d_model: int | None = None):
        super().__init__()
        self.with_identity = with_identity
        d = d_model or cfg.d_model
        in_dim = N_FEATURES + (cfg.id_dim if with_identity else 0)
        self.identity = nn.Embedding(cfg.n_ids, cfg.id_dim) if with_identity else None
        self.mlp = mlp([in_dim, *cfg.embed_hidden, d], cfg.dropout)

    def forward(self, feats: torch.Tensor, ident: torch.Tensor | None = None) -> torch.Tensor:
        """(B, T, K, F) features, (B, K) identity indices -> (B, T, K, d)."""
        if self.identity is not None:
            if ident is None:
                raise ValueError("this embedding needs identity indices")
            e = self.identity(ident)[:, None].expand(*feats.shape[:-1], -1)
            feats = torch.cat([e, feats], dim=-1)
        return self.mlp(feats)


class ContextEmbedding(nn.Module):
    """Four context tokens: surface, tournament, first/second serve, score (an MLP)."""

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        d = cfg.d_model
        self.surface = nn.Embedding(cfg.n_surfaces, d)
        self.tournament = nn.Embedding(cfg.n_tournaments, d)
        self.serve = nn.Embedding(2, d)
        self.score = mlp([len(SCORE_FIELDS), cfg.score_hidden, d])

    def forward(self, surface: torch.Tensor, tournament: torch.Tensor, serve: torch.Tensor,
                score: torch.Tensor) -> torch.Tensor:
        """(B,), (B,), (B,), (B, 7) -> (B, 4, d)."""
        return torch.stack([self.surface(surface), self.tournament(tournament),
                            self.serve(serve), self.score(score)], dim=1)
