"""Top-p sweep (the paper's Fig. 7): realism metrics of simulated play against nucleus top-p
(`scripts/top_p_sweep.py`).

For each top-p (`kind="both"`: the same for players and ball; `player` or `ball`: that kind's,
the other kind held at `other`), `points` simulated service points of each of Roger Federer
and Rafael Nadal against the other on hard, compared with the generator's ground truth of the
same matchup (`sportsngen.eval.physical.compare_data`): the non-realistic rally share, serve
statistics and the physical metrics (Wasserstein distances). The default top-p is the value
with the smallest score = non-realistic share + mean over the physical metrics of
(Wasserstein / reference IQR) + mean over the serve statistics of |sim - truth|; with
`write_default` it is stored in the model file (`sim_defaults`), where
`Simulator.from_pretrained` reads it.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from sportsngen.eval.physical import compare_data
from sportsngen.model.export import read_extra, update_extra
from sportsngen.sim import Simulator
from sportsngen.sim.simulator import model_path
from sportsngen.studies.tables import md_table, write_markdown
from sportsngen.synth.generate import generate_matches
from sportsngen.viz.study_figures import plot_top_p_sweep

PLAYERS = ("Roger Federer", "Rafael Nadal")
SERVE_KEYS = ("first_serve_in", "ace", "double_fault", "serve_points_won")


def score_rows(cmp: pd.DataFrame, unreal: float) -> dict:
    """The sweep's summary figures from one `compare_data` table."""
    c = cmp[cmp["group"] == "all"]
    w = c[c["statistic"] == "wasserstein"].set_index("metric")
    iqr = c[(c["statistic"] == "iqr")].set_index("metric")["ref"]
    # compare_data puts a distance in whichever column is filled (the other is NaN).
    dist = w[["sim", "ref"]].max(axis=1)
    phys = {m: float(dist[m]) / max(float(iqr[m]), 1e-6)
            for m in dist.index if m in iqr.index and np.isfinite(dist[m])
            and np.isfinite(iqr[m])}
    serve = {}
    for k in SERVE_KEYS:
        row = c[(c["metric"] == k) & (c["statistic"] == "value")]
        if len(row):
            serve[k] = abs(float(row["sim"].iat[0]) - float(row["ref"].iat[0]))
    score = unreal + (np.mean(list(phys.values())) if phys else 1.0) + \
        (np.mean(list(serve.values())) if serve else 1.0)
    return {"non_realistic": unreal, **{f"w_{m}": v for m, v in phys.items()},
            **{f"d_{k}": v for k, v in serve.items()}, "score": float(score)}


def top_p_sweep(model: str | None, values: list[float], points: int, seed: int,
                threads: int | None, out: Path, write_default: bool, kind: str,
                other: float) -> pd.DataFrame:
    """Simulate at each top-p, score against the truth, write top_p.png, top_p.md and
    top_p.csv into `out` (and with `write_default` the best into the model file)."""

    def top_ps(p: float) -> dict[str, float]:
        return {"top_p_player": p if kind in ("both", "player") else other,
                "top_p_ball": p if kind in ("both", "ball") else other}

    if threads:
        torch.set_num_threads(threads)
    truth = generate_matches([PLAYERS], "hard", 2000, seed=40_000 + seed, workers=2)
    rows = []
    for p in values:
        sim = Simulator.from_pretrained(model, **top_ps(p))
        t0 = time.perf_counter()
        d = sim.simulate_both_serving(*PLAYERS, "hard", points, seed=seed)
        unreal = float((~d.rallies["realistic"].astype(bool)).mean())
        cmp = compare_data(d, truth)
        row = {"top_p": p, "wall_s": time.perf_counter() - t0, **score_rows(cmp, unreal)}
        rows.append(row)
        print(f"top-p {p:.2f}: non-realistic {100 * unreal:.1f} %, score {row['score']:.3f}, "
              f"{row['wall_s']:.0f} s", flush=True)
    df = pd.DataFrame(rows)
    chosen = top_ps(float(df.loc[df["score"].idxmin(), "top_p"]))
    out.mkdir(parents=True, exist_ok=True)
    df.to_csv(out / "top_p.csv", index=False)
    best = float(df.loc[df["score"].idxmin(), "top_p"])
    plot_top_p_sweep(df, best, out / "top_p.png")
    swept = {"both": "players and ball", "player": f"the players (ball {other:g})",
             "ball": f"the ball (players {other:g})"}[kind]
    show = ["top_p", "non_realistic", "d_first_serve_in", "d_ace", "d_double_fault",
            "d_serve_points_won", "score"]
    show = [c for c in show if c in df.columns]
    lines = ["# Top-p sweep", "",
             f"`python scripts/top_p_sweep.py --points {points} --seed {seed} "
             f"--kind {kind}" + (f" --other {other:g}`" if kind != "both" else "`")
             + f": top-p of {swept}; "
             f"{points} service points per server (Federer v Nadal, hard) per value; "
             "ground truth 2000 generated points. Score = non-realistic share + mean "
             "Wasserstein/IQR of the physical metrics + mean |sim - truth| of the serve "
             f"statistics. Best: **top-p {best:g}** (player {chosen['top_p_player']:g}, ball "
             f"{chosen['top_p_ball']:g}).", "",
             *md_table(show, [[f"{r[c]:.3f}" for c in show] for _, r in df.iterrows()], left=0),
             "", "![top-p](top_p.png)"]
    write_markdown(out / "top_p.md", lines)
    print("\n".join(lines))
    if write_default:
        path = model_path(model)
        # The other stored defaults (contact odds) stay.
        kept = read_extra(path).get("sim_defaults") or {}
        update_extra(path, sim_defaults={**kept, **chosen})
        print(f"stored top-p {chosen} as the default of {path}")
    return df
