"""The strike head teacher-forced shot by shot: its errors at recorded rally strikes against the
record's, by shot and serve number.

A rally ball's fate in a rollout is one draw of the strike head (`model.strike_head`,
`strike.solve_launch`). In the generator the server keeps the initiative all rally on a first
serve: the receiver's balls go out or into the net a quarter of the time at every one of his
shots, the server's a tenth, so serve points are won by the receiver's errors at his second,
third and fourth shots. A head that draws the same error share for both players loses that,
and a 500-point check shows it only as serve points won a few points low, after minutes and
with several points of noise. Here the head draws at every recorded rally strike of generated
points from the decoder's state on the record itself, each strike read from a window that ends
`LEAD_FRAMES` after it (the full history that training's crops and a rollout's band give a
strike; a window that starts just before a strike gives another state), and the draw's error
(long, wide or into the net) read from its bins, as the record's own strike through the same
bins. One decoder pass a strike: about half a minute for 1,000 points on 2 cores.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch
from torch.utils.data import DataLoader, default_collate

from sportsngen.data.tokens import RallyArrays
from sportsngen.data.tracking import RallyData
from sportsngen.model import strike, strike_heads
from sportsngen.model.inputs import BALL
from sportsngen.tennis.court import BASELINE_X_M, SINGLES_HALF_WIDTH_M, net_height_m
from sportsngen.train.metrics import window_states
from sportsngen.train.windows import WindowDataset

LEAD_FRAMES = 8        # a strike's window ends this many frames after it (its targets' frames)
MATCH_FRAMES = 2       # a head target this close to the shots table's contact frame is its strike
LAST_SHOT = 7          # shots from this one on are pooled ("7+")


def strike_errors(values: np.ndarray) -> np.ndarray:
    """(..., 4) `strike.STRIKE_DIMS` values -> (...) bool: the ball lands long (beyond the
    baseline), wide (outside a singles line) or crosses the net's plane lower than the net at
    that lateral. Depth and lateral bin edges fall on the lines, so a bin is read exactly."""
    depth, lateral, over_net = values[..., 0], values[..., 1], values[..., 2]
    return (depth > BASELINE_X_M) | (np.abs(lateral) > SINGLES_HALF_WIDTH_M) | \
        (over_net < net_height_m(lateral))


@torch.no_grad()
def teacher_forced_strikes(model, arrays: RallyArrays, truth: RallyData, draws: int = 6,
                           seed: int = 0, lead_frames: int = LEAD_FRAMES,
                           batch_size: int = 32) -> pd.DataFrame:
    """At every recorded rally strike (shot_index >= 1) of `truth` (whose rallies `arrays`
    holds): the record's strike read through the strike head's bins and `draws` draws of the
    head. -> one row per strike found: rally_id, shot, serve (0 first, 1 second), receiver (the
    hitter is the receiver), record_error (bool) and model_error (share of the draws)."""
    if model.strike_head is None:
        raise ValueError("the model has no strike head (model.strike_head is off)")
    if draws < 1 or lead_frames < 3:
        raise ValueError(f"draws must be >= 1 and lead_frames >= 3 (the strike's three next "
                         f"frames are its target), got {draws} and {lead_frames}")
    window = model.cfg.window_frames
    index = {int(r): i for i, r in enumerate(arrays.rally_id)}
    first = truth.frames.groupby("rally_id")["frame"].min()
    shots = truth.shots[(truth.shots["shot_index"] >= 1)
                        & truth.shots["rally_id"].isin(list(index))]
    if shots.empty:
        raise ValueError("no recorded rally strike (shot_index >= 1) in the rallies given")
    at = (shots["frame"] - shots["rally_id"].map(first)).to_numpy(np.int64)
    ri = shots["rally_id"].map(index).to_numpy(np.int64)
    number = torch.as_tensor(shots["shot_index"].to_numpy(np.int64, copy=True))
    starts = np.maximum(at - (window - lead_frames), 0)
    ds = WindowDataset(arrays, window, None, items=list(zip(ri.tolist(), starts.tolist())))
    loader = DataLoader(ds, batch_size=batch_size, shuffle=False, collate_fn=default_collate)
    gen = torch.Generator().manual_seed(seed)
    rng = np.random.default_rng(seed)
    was_training = model.training
    model.eval()
    found, h_rows, bin_rows, hitters, opponents, receivers, ball_x, surfaces = \
        ([] for _ in range(8))
    for b0, batch in enumerate(loader):
        mask, bins = model.strike_targets(batch["pos_m"], batch["vel_mps"], batch["next_pos_m"],
                                          batch["has_next"])
        want = at[b0 * batch_size:b0 * batch_size + len(mask)] - \
            starts[b0 * batch_size:b0 * batch_size + len(mask)]
        t = _nearest_target(mask.numpy(), want)
        ok = np.flatnonzero(t >= 0)
        if len(ok) == 0:
            continue
        h = window_states(model, batch)[..., BALL, :]
        recv = strike_heads.ball_on_receivers_end(batch["pos_m"][ok, t[ok]])
        role = strike_heads.role_index(recv, batch["serve"][ok])
        hitters.append(torch.where(recv, batch["ident"][ok, 1], batch["ident"][ok, 0]))
        opponents.append(torch.where(recv, batch["ident"][ok, 0], batch["ident"][ok, 1]))
        h_rows.append(model.strike_input(h[ok, t[ok]], role,
                                         number[b0 * batch_size + torch.as_tensor(ok)],
                                         hitters[-1], opponents[-1]))
        bin_rows.append(bins[ok, t[ok]])
        ball_x.append(batch["pos_m"][ok, t[ok], BALL, 0])
        surfaces.append(batch["surface"][ok])
        receivers.append(recv)
        found.append(b0 * batch_size + ok)
    model.train(was_training)
    if not found:
        raise ValueError("the strike head's targets found none of the recorded strikes")
    rows, h, rec_bins = np.concatenate(found), torch.cat(h_rows), torch.cat(bin_rows).numpy()
    picked = shots.iloc[rows]
    shot = picked["shot_index"].to_numpy(np.int64)
    serve = picked["rally_id"].map(truth.rallies.set_index("rally_id")["serve_number"])
    serve = serve.to_numpy(np.int64) - 1
    # The file's per-hitter shifts, where it has them (`model.strike_bias`; the returns' own
    # with `model.strike_return`, the opponents' with `model.strike_pressure`, the late
    # strikes' with `model.strike_late`, the surfaces' returns table with
    # `model.strike_return_surface`).
    bias = model.strike_head_bias(torch.cat(hitters), torch.cat(receivers),
                                  torch.as_tensor(shot == 1), torch.cat(opponents),
                                  torch.as_tensor(shot), torch.cat(ball_x),
                                  torch.as_tensor(serve), torch.cat(surfaces))
    idx = torch.stack([model.strike_head.sample(h, 1.0, gen, dim_bias=bias)
                       for _ in range(draws)], 1).numpy()
    rec = strike_errors(strike.strike_bin_value(rec_bins, rng.random(rec_bins.shape)))
    mod = strike_errors(strike.strike_bin_value(idx, rng.random(idx.shape))).mean(axis=1)
    return pd.DataFrame({"rally_id": picked["rally_id"].to_numpy(), "shot": shot,
                         "serve": serve, "receiver": shot % 2 == 1,
                         "record_error": rec, "model_error": mod})


def _nearest_target(mask: np.ndarray, want: np.ndarray) -> np.ndarray:
    """(B, T) head targets, (B,) wanted frames -> (B,) the target within `MATCH_FRAMES` of
    each wanted frame, the nearest (the earlier on a tie), -1 where there is none."""
    out = np.full(len(mask), -1, dtype=np.int64)
    for off in sorted(range(-MATCH_FRAMES, MATCH_FRAMES + 1), key=lambda o: (abs(o), o)):
        t = want + off
        inside = (out < 0) & (t >= 0) & (t < mask.shape[1])
        hit = np.zeros(len(mask), dtype=bool)
        hit[inside] = mask[np.flatnonzero(inside), t[inside]]
        out[hit] = t[hit]
    return out


def strike_error_table(rows: pd.DataFrame) -> pd.DataFrame:
    """`teacher_forced_strikes` rows -> per shot (1 the return; `LAST_SHOT` and later pooled)
    and serve number: the hitter ("both" for the pooled shots), n, and the record's and the
    model's error shares."""
    r = rows.assign(shot=rows["shot"].clip(upper=LAST_SHOT))
    g = r.groupby(["shot", "serve"])
    out = g[["record_error", "model_error"]].mean()
    out.insert(0, "n", g.size())
    out = out.reset_index()
    out.insert(1, "hitter", np.where(out["shot"] >= LAST_SHOT, "both",
                                     np.where(out["shot"] % 2 == 1, "receiver", "server")))
    out["shot"] = out["shot"].astype(str).where(out["shot"] < LAST_SHOT, f"{LAST_SHOT}+")
    out["serve"] = out["serve"].map({0: "first", 1: "second"})
    return out.rename(columns={"record_error": "record", "model_error": "model"})


def strike_draw_table(sim, truth: RallyData, draws: int = 6, seed: int = 0) -> pd.DataFrame:
    """`strike_error_table` of `sim`'s model at the rally strikes of `truth` (a `RallyData`)."""
    from sportsngen.data.tokens import rally_arrays

    arr = rally_arrays(truth, sim.vocab, unknown="generic")
    return strike_error_table(teacher_forced_strikes(sim.model, arr, truth, draws, seed))
