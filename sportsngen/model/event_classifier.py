"""Event classifier g: per-frame shot labels from the object tracks.

The same object features as the decoder but without identity or context, a transformer with no
mask (every frame sees the whole window), and one head per label per frame: stroke, direction,
outcome (none / in play / winner / error) and error kind (vocabularies of
`sportsngen.data.tracking`). The three object tokens of a frame are concatenated into one
frame state before the heads.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from sportsngen.data.tokens import LABELS
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import Block
from sportsngen.model.embedding import ObjectEmbedding
from sportsngen.model.inputs import N_OBJECTS


class EventClassifier(nn.Module):
    def __init__(self, cfg: ModelConfig):
        super().__init__()
        self.cfg = cfg
        d = cfg.event_d_model
        self.embed = ObjectEmbedding(cfg, with_identity=False, d_model=d)
        self.blocks = nn.ModuleList(Block(d, cfg.event_heads, cfg.ff_mult, cfg.dropout,
                                          cfg.attn_dropout)
                                    for _ in range(cfg.event_layers))
        self.ln_f = nn.LayerNorm(N_OBJECTS * d)
        self.heads = nn.ModuleDict({name: nn.Linear(N_OBJECTS * d, len(vocab))
                                    for name, vocab in LABELS.items()})

    def forward(self, feats: torch.Tensor) -> dict[str, torch.Tensor]:
        """feats (B, T, 3, F) -> {label: logits (B, T, n_classes)}."""
        b, t, k, _ = feats.shape
        x = self.embed(feats).reshape(b, t * k, -1)
        for blk in self.blocks:
            x, _ = blk(x)
        frame = self.ln_f(x.reshape(b, t, -1))
        return {name: head(frame) for name, head in self.heads.items()}

    def loss(self, feats: torch.Tensor, labels: torch.Tensor, valid: torch.Tensor):
        """Mean cross-entropy over valid frames, summed over labels; also per-label accuracy.
        labels (B, T, 4) in the order of `LABELS`."""
        out = self(feats)
        total = feats.new_zeros(())
        acc = {}
        m = valid.reshape(-1)
        for j, (name, logits) in enumerate(out.items()):
            y = labels[..., j].reshape(-1)[m]
            lg = logits.reshape(-1, logits.shape[-1])[m]
            total = total + F.cross_entropy(lg, y)
            acc[name] = (lg.argmax(-1) == y).float().mean()
        return total, acc
