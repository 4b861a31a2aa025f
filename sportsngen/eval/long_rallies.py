"""Shots struck after a rally outgrows the model's window: how the cached rollout reads them.

The decoder is trained on windows of `window_frames` frames cut from the rallies, so every
token it learned from saw at most that many frames, the earliest with no history at all. A
cached rollout (`sportsngen.sim.rollout`, mode "cache") keeps a band: each new token attends to
the last `window_frames` frames, whose own states were computed from the band before theirs,
so past the window a token's lower layers reach back over the whole rally, a view training
never gave. `late_shot_contact_odds` measures what that costs where it decides a rally, on the
recorded rallies and free of sampling noise: the teacher-forced chance of a racket contact
over each recorded approach (`sportsngen.eval.contact_odds.approach_frames`) of a shot struck
after the first window, read once with the band (the rollout's view) and once from a
truncated window that ends just after the contact (training's view). `points_after_window`
counts what a rollout's view past the window costs the score: the share of points decided
after the serve has left the window and the server's share of them, whose gap to the truth's
the band opened and a refresh to training's view (`refresh_frames`) mostly closed
(docs/evaluation.md, twenty-ninth part).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from sportsngen.data.tokens import rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.contact_odds import approach_frames, approach_odds, far_probability
from sportsngen.model.inputs import BALL
from sportsngen.sim.rollout import window_features


@torch.no_grad()
def late_shot_contact_odds(sim, truth: RallyData, rules: pd.DataFrame) -> dict:
    """Mean teacher-forced P(contact) over the approach of every recorded shot after the
    return whose contact comes at or after frame `window_frames` -> {"band", "window",
    "shots"}. `rules`: `analyse_rally_data(truth)`."""
    model = sim.model.eval()
    w = model.cfg.window_frames
    arr = rally_arrays(truth, sim.vocab, unknown="generic")
    band, window = [], []
    for ri, rid in enumerate(arr.rally_id):
        n = int(arr.length[ri])
        rule = rules.loc[rid]
        shots = [(lo, hi) for shot, lo, hi in approach_frames(list(rule["contact_frames"]),
                                                              list(rule["bounce_frames"]))
                 if shot >= 2 and hi >= w and hi + 1 < n]
        if not shots:
            continue
        pos = torch.as_tensor(arr.pos_m[arr.start[ri]:arr.start[ri] + n])[None]
        ident = torch.as_tensor(arr.ident[ri])[None]
        ctx = model.context_tokens(*(torch.as_tensor(np.asarray(v[ri]))[None] for v in
                                     (arr.surface, arr.tournament, arr.serve, arr.score)))
        feats = window_features(pos, 0, n, arr.fps)
        p_band = far_probability(model, model(feats, ident, ctx)[0, :, BALL]).numpy()
        for lo, hi in shots:
            s = hi + 2 - w     # a training window's tokens are the rally's, sliced
            p_win = far_probability(model, model(feats[:, s:hi + 2], ident, ctx)[0, :, BALL])
            band.append(approach_odds(p_band[lo:hi + 1]))
            window.append(approach_odds(p_win.numpy()[lo - s:hi + 1 - s]))
    nan = float("nan")
    return {"band": float(np.mean(band)) if band else nan,
            "window": float(np.mean(window)) if window else nan, "shots": len(band)}


def points_after_window(data: RallyData, window_frames: int) -> pd.DataFrame:
    """Decided points (a winner recorded) split by whether their last shot came
    `window_frames` or more after the serve's contact, when the serve has left a window that
    ends at that shot -> index ("before", "after"): points, share (of the decided points with a
    serve in the shots table) and server_won (his share of them; NaN where none)."""
    if window_frames < 1:
        raise ValueError(f"window_frames must be >= 1, got {window_frames}")
    r = data.rallies[data.rallies["winner"].fillna("") != ""]
    shots = data.shots[data.shots["rally_id"].isin(r["rally_id"])]
    serve = shots[shots["shot_index"] == 0].groupby("rally_id")["frame"].min()
    last = shots.groupby("rally_id")["frame"].max()
    gap = (r["rally_id"].map(last) - r["rally_id"].map(serve)).to_numpy(dtype=float)
    keep = ~np.isnan(gap)
    after = gap[keep] >= window_frames
    won = (r["winner"] == r["server"]).to_numpy()[keep]
    rows = {}
    for name, sel in (("before", ~after), ("after", after)):
        n = int(sel.sum())
        rows[name] = {"points": n, "share": n / max(len(after), 1),
                      "server_won": float(won[sel].mean()) if n else float("nan")}
    return pd.DataFrame.from_dict(rows, orient="index")
