"""Shots struck after a rally outgrows the model's window: how the cached rollout reads them.

The decoder is trained on windows of `window_frames` frames cut from the rallies, so every
token it learned from saw at most that many frames, the earliest with no history at all. A
cached rollout (`sportsngen.sim.rollout`, mode "cache") keeps a band: each new token attends to
the last `window_frames` frames, whose own states were computed from the band before theirs,
so past the window a token's lower layers reach back over the whole rally, a view training
never gave. `late_shot_contact_odds` measures what that costs where it decides a rally, on the
recorded rallies and free of sampling noise: the teacher-forced chance of a racket contact
over each recorded approach (`sportsngen.eval.diagnostics.approach_frames`) of a shot struck
after the first window, read once with the band (the rollout's view) and once from a
truncated window that ends just after the contact (training's view).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch
from torch.utils.data import default_collate

from sportsngen.data.tokens import BALL, WindowDataset, object_features, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.diagnostics import approach_frames, far_probability


def _approach_odds(p: np.ndarray) -> float:
    return float(1.0 - np.prod(1.0 - p.astype(float)))


@torch.no_grad()
def late_shot_contact_odds(sim, truth: RallyData, rules: pd.DataFrame) -> dict:
    """Mean teacher-forced P(contact) over the approach of every recorded shot after the
    return whose contact comes at or after frame `window_frames` -> {"band", "window",
    "shots"}. `rules`: `analyse_rally_data(truth)`."""
    model = sim.model.eval()
    w = model.cfg.window_frames
    arr = rally_arrays(truth, sim.vocab, unknown="generic")
    items = WindowDataset(arr, w)
    first = {ri: i for i, (ri, s) in enumerate(items.items) if s == 0}
    band, window = [], []
    for ri, rid in enumerate(arr.rally_id):
        n = int(arr.length[ri])
        rule = rules.loc[rid]
        shots = [(lo, hi) for shot, lo, hi in approach_frames(list(rule["contact_frames"]),
                                                              list(rule["bounce_frames"]))
                 if shot >= 2 and hi >= w and hi + 1 < n]
        if not shots:
            continue
        meta = default_collate([items[first[ri]]])
        pos = torch.as_tensor(arr.pos_m[arr.start[ri]:arr.start[ri] + n])[None]
        vel = torch.zeros_like(pos)
        vel[:, 1:] = (pos[:, 1:] - pos[:, :-1]) * arr.fps
        feats = object_features(pos, vel, (torch.arange(n, dtype=pos.dtype) / arr.fps)[None])
        ctx = model.context_tokens(meta["surface"], meta["tournament"], meta["serve"],
                                   meta["score"])
        p_band = far_probability(model, model(feats, meta["ident"], ctx)[0, :, BALL]).numpy()
        for lo, hi in shots:
            s = hi + 2 - w
            h = model(feats[:, s:hi + 2], meta["ident"], ctx)[0, :, BALL]
            p_win = far_probability(model, h).numpy()
            band.append(_approach_odds(p_band[lo:hi + 1]))
            window.append(_approach_odds(p_win[lo - s:hi + 1 - s]))
    nan = float("nan")
    return {"band": float(np.mean(band)) if band else nan,
            "window": float(np.mean(window)) if window else nan, "shots": len(band)}
