"""Event labelling of simulated rallies with the event classifier g, as the paper does.

g labels every frame (stroke, direction, outcome, error kind of the shot in progress); the rally
tracker (`sportsngen.tennis.rally`) finds the racket contacts. A shot's labels are the majority
of g's labels over its frames (contact to next contact), ignoring "none"; the last shot's
outcome says how the rally ended by g's reading (winner: the hitter won; error: he lost), which
`classifier_winner` turns into a point winner to set beside the rules' winner.
"""

from __future__ import annotations

import numpy as np
import torch

from sportsngen.data.tokens import LABELS
from sportsngen.model.event_classifier import EventClassifier
from sportsngen.model.inputs import object_features

LABEL_NAMES = tuple(LABELS)            # stroke, direction, outcome, error_kind


@torch.inference_mode()
def frame_labels(event_model: EventClassifier, pos_m: np.ndarray, length: np.ndarray,
                 fps: float, window_frames: int, batch_size: int = 64) -> np.ndarray:
    """g's per-frame label indices (B, T, 4) (order `LABEL_NAMES`; 0 = "none" after `length`).

    Rallies are tiled into windows of `window_frames` frames from their start (padded with
    zeros, as in training); each window is labelled on its own.
    """
    pos_m = np.asarray(pos_m, dtype=np.float32)
    b, t = pos_m.shape[:2]
    out = np.zeros((b, t, len(LABEL_NAMES)), dtype=np.int64)
    if b == 0:
        return out
    event_model.eval()
    dev = next(event_model.parameters()).device
    w = int(window_frames)
    n_win = -(-t // w)
    pad = np.zeros((b, n_win * w, 3, 3), dtype=np.float32)
    valid = np.arange(n_win * w)[None, :] < np.asarray(length)[:, None]
    pad[:, :t] = np.nan_to_num(pos_m)
    pad[~valid] = 0.0
    prev = np.concatenate([pad[:, :1], pad[:, :-1]], axis=1)
    vel = (pad - prev) * fps
    vel[:, ::w] = np.where(np.arange(n_win)[None, :, None, None] == 0, 0.0,
                           vel[:, ::w])          # the rally's first frame has velocity 0
    vel[~valid] = 0.0
    ts = np.broadcast_to((np.arange(n_win * w) / fps).astype(np.float32), (b, n_win * w))
    pos_w = torch.from_numpy(pad.reshape(b * n_win, w, 3, 3))
    vel_w = torch.from_numpy(vel.reshape(b * n_win, w, 3, 3).astype(np.float32))
    t_w = torch.from_numpy(np.array(ts).reshape(b * n_win, w))
    keep = valid.reshape(b * n_win, w).any(axis=1)
    labels = np.zeros((b * n_win, w, len(LABEL_NAMES)), dtype=np.int64)
    idx = np.flatnonzero(keep)
    for s in range(0, len(idx), batch_size):
        sel = torch.as_tensor(idx[s:s + batch_size])
        feats = object_features(pos_w[sel].to(dev), vel_w[sel].to(dev), t_w[sel].to(dev))
        logits = event_model(feats)
        labels[idx[s:s + batch_size]] = torch.stack(
            [logits[name].argmax(-1) for name in LABEL_NAMES], dim=-1).cpu().numpy()
    labels = labels.reshape(b, n_win * w, -1)[:, :t]
    labels[~valid[:, :t]] = 0
    out[:] = labels
    return out


def shot_labels(labels: np.ndarray, contact_frames: list[int], length: int) -> np.ndarray:
    """(n_shots, 4) label indices of a rally's shots from its per-frame labels (T, 4): the
    most common non-"none" label over each shot's frames (0 when all are "none")."""
    bounds = list(contact_frames) + [int(length)]
    out = np.zeros((len(contact_frames), labels.shape[1]), dtype=np.int64)
    for i in range(len(contact_frames)):
        seg = labels[max(bounds[i], 0):max(bounds[i + 1], bounds[i] + 1)]
        for j in range(labels.shape[1]):
            vals = seg[:, j][seg[:, j] > 0]
            if len(vals):
                out[i, j] = np.bincount(vals).argmax()
    return out


def classifier_winner(last_outcome: str, last_hitter: int) -> int:
    """Point winner (0 server, 1 receiver, -1 undecided) by g's reading of the last shot."""
    if last_hitter not in (0, 1):
        return -1
    if last_outcome == "winner":
        return last_hitter
    if last_outcome == "error":
        return 1 - last_hitter
    return -1
