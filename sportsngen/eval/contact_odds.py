"""A model's teacher-forced odds of a racket contact, and the recorded approaches they are read
over: shared by the rollout diagnostics (`sportsngen.eval.diagnostics`) and the shots after the
window (`sportsngen.eval.long_rallies`)."""

from __future__ import annotations

import numpy as np
import torch

from sportsngen.model.decoder import CONTACT_OFFSET_M

REVERSAL_M = CONTACT_OFFSET_M
VOLLEY_GAP_FRAMES = 3     # a volley's approach starts this long after the previous contact


def far_probability(model, h: torch.Tensor, pos_m: torch.Tensor | None = None,
                    vel_mps: torch.Tensor | None = None,
                    prev_vel_mps: torch.Tensor | None = None) -> torch.Tensor:
    """P(contact) of ball output states h (N, d): the next ball frame more than `REVERSAL_M`
    from its bin centre along x (the decoder's `contact_bins`). Given the frames (N, 3, 3)
    (positions, velocities and the velocities a frame earlier), a model's contact table
    (`model.contact_reach`) shifts the odds as a rollout's draw has them."""
    p0 = model.ball_head.dim_logits(h, torch.zeros(len(h), 3, dtype=torch.long), 0)
    if pos_m is not None and getattr(model, "contact_reach", None) is not None:
        centre = model.centres(pos_m, vel_mps, prev_vel_mps)
        p0 = p0 + model.contact_reach_bias(pos_m, vel_mps, centre)[:, 0]
    return p0.softmax(-1)[:, model.contact_bins()].sum(-1)


def approach_frames(contacts: list[int], bounces: list[int]) -> list[tuple[int, int, int]]:
    """A rally's recorded shots after the serve -> (shot index, first, last token) of each
    shot's approach: from the bounce before the contact (for a volley, `VOLLEY_GAP_FRAMES`
    after the previous contact) to the token that predicts the contact (token t predicts
    frame t + 1; the rules put a contact on the nearer frame of its step, whose token carries
    the reversal)."""
    out = []
    for j in range(1, len(contacts)):
        before = [b for b in bounces if contacts[j - 1] < b < contacts[j]]
        lo = before[-1] + 1 if before else contacts[j - 1] + VOLLEY_GAP_FRAMES
        if lo < contacts[j]:
            out.append((j, lo, contacts[j]))
    return out


def approach_odds(p: np.ndarray) -> float:
    """The chance of at least one contact over an approach's per-token P(contact) `p`."""
    return float(1.0 - np.prod(1.0 - np.asarray(p, dtype=float)))
