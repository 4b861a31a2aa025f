"""The serve head teacher-forced: its draws at recorded serves against the record, by serve.

A serve's fate in a rollout is decided by one draw of the serve head (`model.serve_head`,
`strike.solve_serve`); a double-fault rate off by ten points shows in a 500-point check only
after minutes and with several points of noise. Here the head draws at every recorded serve of
generated points from the decoder's states on the record itself (one pass, no rollout), each
draw is solved and flown as a rollout would, and its fault read the same way as the record's own
serve read through the same bins: long (beyond the service line), wide (outside the box,
the other box included) or into the net (the height over the net below the net's at the
landing's lateral, a close proxy for the crossing's). Seconds for a few hundred serves.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch
from torch.utils.data import default_collate

from sportsngen.data.tokens import BALL
from sportsngen.model import strike
from sportsngen.tennis.court import SERVICE_LINE_X_M, SINGLES_HALF_WIDTH_M, net_height_m
from sportsngen.train.metrics import window_states


def serve_faults(contact_m: np.ndarray, values: np.ndarray, fps: float) -> pd.DataFrame:
    """Serves struck at `contact_m` (N, 3) toward `values` (N, 4 `SERVE_DIMS`), each solved
    (`strike.solve_serve`) and flown -> per serve: found, long, wide, net, fault (NaN flags
    where the launch was not found)."""
    side = np.sign(contact_m[:, 0])
    v0, found = strike.solve_serve(contact_m, side, values, fps)
    frames = strike.launch_frames(contact_m, v0, values[:, 3], fps)
    over_net_m = strike.strike_labels(frames, side, fps)[:, 2]
    land_y = -side * values[:, 1]
    # The serve goes to the box diagonally opposite the server: the other sign of y.
    toward = -np.sign(contact_m[:, 1]) * land_y
    long = values[:, 0] > SERVICE_LINE_X_M
    wide = (toward < 0) | (toward > SINGLES_HALF_WIDTH_M)
    net = ~(over_net_m >= net_height_m(land_y))       # NaN (no crossing) is a net fault
    flags = {k: np.where(found, v, np.nan) for k, v in
             (("long", long), ("wide", wide), ("net", net), ("fault", long | wide | net))}
    return pd.DataFrame({"found": found, **flags})


@torch.no_grad()
def teacher_forced_serves(model, windows: list, draws: int = 6, seed: int = 0,
                          batch_size: int = 32) -> pd.DataFrame:
    """At every recorded serve of `windows` (`WindowDataset` items, e.g. each rally's first):
    the record's serve and `draws` draws of the serve head, each read by `serve_faults`.
    -> one row per (serve, source): rally_id, serve (0 first, 1 second), source ("record" or
    "model"), the fault flags (the model's: shares over its draws) and speed_mps."""
    if model.serve_head is None:
        raise ValueError("the model has no serve head (model.serve_head is off)")
    fps = model.cfg.fps
    edges = strike.serve_edges()
    gen = torch.Generator().manual_seed(seed)
    rng = np.random.default_rng(seed)
    rows = []
    for b0 in range(0, len(windows), batch_size):
        batch = default_collate(windows[b0:b0 + batch_size])
        h = window_states(model, batch)
        mask, bins = model.strike_targets(batch["pos_m"], batch["vel_mps"], batch["next_pos_m"],
                                          batch["has_next"], serves=True)
        if not bool(mask.any()):
            continue
        hb = h[..., BALL, :][mask]
        idx = torch.stack([model.serve_head.sample(hb, 1.0, gen) for _ in range(draws)], 1)
        bi, ti = (x.numpy() for x in mask.nonzero(as_tuple=True))
        contact = batch["pos_m"].numpy().astype(float)[bi, ti, BALL]
        rec_vals = strike.strike_bin_value(bins[mask].numpy(), rng.random((len(bi), 4)), edges)
        mod_vals = strike.strike_bin_value(idx.numpy(), rng.random(tuple(idx.shape)), edges)
        rec = serve_faults(contact, rec_vals, fps)
        mod = serve_faults(np.repeat(contact, draws, 0), mod_vals.reshape(-1, 4), fps)
        mod_mean = mod.astype(float).groupby(np.repeat(np.arange(len(bi)), draws)).mean()
        base = {"rally_id": batch["rally_id"].numpy()[bi], "serve": batch["serve"].numpy()[bi]}
        rows.append(pd.DataFrame({**base, "source": "record", **rec.astype(float),
                                  "speed_mps": rec_vals[:, 2]}))
        rows.append(pd.DataFrame({**base, "source": "model", **mod_mean.reset_index(drop=True),
                                  "speed_mps": mod_vals[..., 2].mean(1)}))
    if not rows:
        raise ValueError("no recorded serve in the windows given")
    return pd.concat(rows, ignore_index=True)


def serve_fault_table(rows: pd.DataFrame) -> pd.DataFrame:
    """`teacher_forced_serves` rows -> per serve number and source: n, the fault shares
    (long, wide, net, any) and the median speed (km/h)."""
    g = rows.groupby(["serve", "source"])
    out = g[["long", "wide", "net", "fault"]].mean()
    out.insert(0, "n", g.size())
    out["speed_kmh"] = g["speed_mps"].median() * 3.6
    out = out.reset_index()
    out["serve"] = out["serve"].map({0: "first", 1: "second"})
    return out


def serve_draw_table(sim, truth, draws: int = 6, seed: int = 0) -> pd.DataFrame:
    """`serve_fault_table` of `sim`'s model at the serves of `truth` (a `RallyData`), read from
    each rally's first window."""
    from sportsngen.data.tokens import WindowDataset, rally_arrays

    arr = rally_arrays(truth, sim.vocab, unknown="generic")
    items = WindowDataset(arr, sim.model.cfg.window_frames)
    first = [items[i] for i, (_, start) in enumerate(items.items) if start == 0]
    return serve_fault_table(teacher_forced_serves(sim.model, first, draws, seed))
