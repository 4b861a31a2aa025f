"""A "what if she had gone down the line?" figure with the bundled model (the paper's Fig. 16).

    .venv/bin/python scripts/counterfactual_demo.py [--model PATH] [--n 100] [--seed 0]
        [--out docs/figures/counterfactual]

Takes a generated Federer v Nadal rally of at least 5 shots (held out: a generator seed the
training never used), branches just before its third shot, forces it cross court and down the
line, rolls `--n` continuations of each, and writes counterfactual.png and counterfactual.md
(the table of `Simulator.counterfactual`).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

from sportsngen.sim import Simulator
from sportsngen.sim.whatif import counterfactual
from sportsngen.synth.generate import generate_matches
from sportsngen.viz.counterfactual_plot import plot_counterfactual


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--shot", type=int, default=2)
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--out", type=Path, default=Path("docs/figures/counterfactual"))
    args = ap.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    sim = Simulator.from_pretrained(args.model)
    data = generate_matches([("Roger Federer", "Rafael Nadal")], "hard", 60,
                            seed=60_000 + args.seed)
    counts = data.shots.groupby("rally_id").size()
    rid = int(counts[counts >= 5].index[0])
    t0 = time.perf_counter()
    table, branches = counterfactual(sim, data, rid, args.shot, n=args.n, seed=args.seed,
                                     return_branches=True)
    wall = time.perf_counter() - t0
    shot = data.shots[data.shots["rally_id"] == rid].sort_values("shot_index").iloc[args.shot]
    first = int(data.frames.loc[data.frames["rally_id"] == rid, "frame"].min())
    args.out.mkdir(parents=True, exist_ok=True)
    plot_counterfactual(data, rid, table, branches, int(shot["frame"]) - first - 1,
                        args.out / "counterfactual.png")
    real = data.rallies[data.rallies["rally_id"] == rid].iloc[0]
    lines = ["# Counterfactual: where should the shot have gone?", "",
             f"`python scripts/counterfactual_demo.py --n {args.n} --seed {args.seed}`: rally "
             f"{rid} ({real['server']} serving to {real['receiver']}, hard), shot {args.shot} "
             f"by {shot['hitter']} ({shot['stroke']}, really hit {shot['direction']}); "
             f"{args.n} rollouts an option, {wall:.0f} s. Win probability is the hitter's "
             "(95 % Wilson interval), over realistic decided branches.", "",
             "| " + " | ".join(table.columns) + " |", "|" + "---|" * len(table.columns),
             *("| " + " | ".join(f"{v:.3f}" if isinstance(v, float) else str(v) for v in r)
               + " |" for r in table.itertuples(index=False)), "",
             "![counterfactual](counterfactual.png)"]
    (args.out / "counterfactual.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
