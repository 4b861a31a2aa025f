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

from sportsngen.model import strike
from sportsngen.model.serve_bias import serve_wide
from sportsngen.tennis.court import SERVICE_LINE_X_M, net_height_m


def serve_faults(contact_m: np.ndarray, values: np.ndarray, fps: float) -> pd.DataFrame:
    """Serves struck at `contact_m` (N, 3) toward `values` (N, 4 `SERVE_DIMS`), each solved
    (`strike.solve_serve`) and flown -> per serve: found, long, wide, net, fault (NaN flags
    where the launch was not found)."""
    side = np.sign(contact_m[:, 0])
    v0, found = strike.solve_serve(contact_m, side, values, fps)
    frames = strike.launch_frames(contact_m, v0, values[:, 3], fps)
    over_net_m = strike.strike_labels(frames, side, fps)[:, 2]
    land_y = -side * values[:, 1]
    long = values[:, 0] > SERVICE_LINE_X_M
    wide = serve_wide(contact_m, values[:, 1])      # the box diagonally opposite the server
    net = ~(over_net_m >= net_height_m(land_y))       # NaN (no crossing) is a net fault
    flags = {k: np.where(found, v, np.nan) for k, v in
             (("long", long), ("wide", wide), ("net", net), ("fault", long | wide | net))}
    return pd.DataFrame({"found": found, **flags})


@torch.no_grad()
def teacher_forced_serves(model, arrays, draws: int = 6, seed: int = 0,
                          top_p: float = 1.0) -> pd.DataFrame:
    """At every recorded serve of `arrays` (`RallyArrays`; the states read by
    `train.head_fit.collect_head_states`): the record's serve and `draws` draws of the serve
    head (nucleus `top_p`, as a rollout's `top_p_serve`), each read by `serve_faults`. -> one
    row per (serve, source): rally_id, serve (0 first, 1 second), source ("record" or
    "model"), the fault flags (the model's: shares over its draws) and speed_mps."""
    from sportsngen.train.head_fit import collect_head_states

    if model.serve_head is None:
        raise ValueError("the model has no serve head (model.serve_head is off)")
    st = collect_head_states(model, arrays, "serve", progress=False)
    edges = strike.serve_edges()
    gen = torch.Generator().manual_seed(seed)
    rng = np.random.default_rng(seed)
    bias = model.serve_head_bias(torch.as_tensor(st.server_id), torch.as_tensor(st.serve),
                                 torch.as_tensor(st.contact_m, dtype=torch.float32))
    idx = torch.stack([model.serve_head.sample(st.h, top_p, gen, dim_bias=bias)
                       for _ in range(draws)], 1)
    rec_vals = strike.strike_bin_value(st.bins.numpy(), rng.random((len(st), 4)), edges)
    mod_vals = strike.strike_bin_value(idx.numpy(), rng.random(tuple(idx.shape)), edges)
    fps = model.cfg.fps
    rec = serve_faults(st.contact_m, rec_vals, fps)
    mod = serve_faults(np.repeat(st.contact_m, draws, 0), mod_vals.reshape(-1, 4), fps)
    mod_mean = mod.astype(float).groupby(np.repeat(np.arange(len(st)), draws)).mean()
    base = {"rally_id": st.rally_id, "serve": st.serve}
    return pd.concat([
        pd.DataFrame({**base, "source": "record", **rec.astype(float),
                      "speed_mps": rec_vals[:, 2]}),
        pd.DataFrame({**base, "source": "model", **mod_mean.reset_index(drop=True),
                      "speed_mps": mod_vals[..., 2].mean(1)})], ignore_index=True)


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
    """`serve_fault_table` of `sim`'s model at the serves of `truth` (a `RallyData`), drawn
    with its serve nucleus (`sim.top_p_serve`, as its rollouts draw)."""
    from sportsngen.data.tokens import rally_arrays

    arr = rally_arrays(truth, sim.vocab, unknown="generic")
    return serve_fault_table(teacher_forced_serves(sim.model, arr, draws, seed,
                                                   top_p=sim.top_p_serve))
