"""A "what if she had gone down the line?" page with a model (the paper's Fig. 16);
`scripts/counterfactual_demo.py` is the command line.

Takes a generated Federer v Nadal rally of at least 5 shots (held out: a generator seed the
training never used), branches just before one of its shots, forces it cross court and down the
line, rolls continuations of each, and writes counterfactual.png and counterfactual.md (the
table of `sportsngen.sim.whatif.counterfactual`).
"""

from __future__ import annotations

import time
from pathlib import Path

from sportsngen.eval.markdown import markdown_table
from sportsngen.sim import Simulator
from sportsngen.sim.whatif import counterfactual
from sportsngen.synth.generate import generate_matches
from sportsngen.viz.counterfactual_plot import plot_counterfactual

HELD_OUT_SEED = 60_000  # generator seeds from here were never used in training
MIN_SHOTS = 5


def counterfactual_page(sim: Simulator, out: Path, n: int = 100, seed: int = 0,
                        shot: int = 2) -> str:
    """Branch the first held-out rally of `MIN_SHOTS` shots or more before shot `shot`, roll
    `n` continuations of each option, write ``counterfactual.png`` and ``counterfactual.md``
    into `out`; -> the page's markdown."""
    data = generate_matches([("Roger Federer", "Rafael Nadal")], "hard", 60,
                            seed=HELD_OUT_SEED + seed)
    counts = data.shots.groupby("rally_id").size()
    rid = int(counts[counts >= MIN_SHOTS].index[0])
    t0 = time.perf_counter()
    table, branches = counterfactual(sim, data, rid, shot, n=n, seed=seed,
                                     return_branches=True)
    wall = time.perf_counter() - t0
    row = data.shots[data.shots["rally_id"] == rid].sort_values("shot_index").iloc[shot]
    first = int(data.frames.loc[data.frames["rally_id"] == rid, "frame"].min())
    out.mkdir(parents=True, exist_ok=True)
    plot_counterfactual(data, rid, table, branches, int(row["frame"]) - first - 1,
                        out / "counterfactual.png")
    real = data.rallies[data.rallies["rally_id"] == rid].iloc[0]
    lines = ["# Counterfactual: where should the shot have gone?", "",
             f"`python scripts/counterfactual_demo.py --n {n} --seed {seed}`: rally "
             f"{rid} ({real['server']} serving to {real['receiver']}, hard), shot {shot} "
             f"by {row['hitter']} ({row['stroke']}, really hit {row['direction']}); "
             f"{n} rollouts an option, {wall:.0f} s. Win probability is the hitter's "
             "(95 % Wilson interval), over realistic decided branches.", "",
             *markdown_table(list(table.columns), table.itertuples(index=False)), "",
             "![counterfactual](counterfactual.png)"]
    page = "\n".join(lines) + "\n"
    (out / "counterfactual.md").write_text(page)
    return page
