"""Horizon study (the paper's Fig. 18): position error of rollouts against time after a branch.

    .venv/bin/python scripts/horizon_study.py [--model PATH] [--rallies 60] [--n 4]
        [--horizon-s 1.75] [--out docs/figures/horizon]

Held-out synthetic rallies (Federer v Nadal, hard, a generator seed the training never used) are
branched at 1, 2, 3 and 4 s after their start; `--n` rollouts of each run for `--horizon-s`
(no rally-end rules: a fixed horizon). At each time after the branch: RMSE of the ball's 3-D
position and of the players' 2-D positions against the recorded track, over every rollout whose
rally still lasts that long, beside linear extrapolation of the last recorded velocity (the
paper's reference). Writes horizon.png, horizon.md and horizon.csv into --out.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from sportsngen.sim import Simulator
from sportsngen.sim.rollout import rollout
from sportsngen.sim.whatif import _plan, _rally
from sportsngen.synth.generate import generate_matches

PLAYERS = ("Roger Federer", "Rafael Nadal")
BRANCH_S = (1.0, 2.0, 3.0, 4.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--rallies", type=int, default=60)
    ap.add_argument("--n", type=int, default=4)
    ap.add_argument("--horizon-s", type=float, default=1.75)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--out", type=Path, default=Path("docs/figures/horizon"))
    args = ap.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    sim = Simulator.from_pretrained(args.model)
    fps = sim.fps
    h = int(round(args.horizon_s * fps))
    held = generate_matches([PLAYERS], "hard", 3 * args.rallies, seed=30_000 + args.seed,
                            workers=1)
    rng = np.random.default_rng(args.seed)
    ids = held.rallies["rally_id"].to_numpy()[rng.permutation(len(held.rallies))[:args.rallies]]
    tracks = {int(i): _rally(held, int(i)) for i in ids}
    sq_model = {k: np.zeros(h) for k in ("ball", "players")}
    sq_lin = {k: np.zeros(h) for k in ("ball", "players")}
    count = np.zeros(h)
    t0 = time.perf_counter()
    for g, b in enumerate(BRANCH_S):
        k = int(round(b * fps))
        use = [i for i, (_, pos, _) in tracks.items() if len(pos) > k + 2]
        if not use:
            continue
        plan = pd.concat([_plan(tracks[i][0], args.n) for i in use], ignore_index=True)
        init = np.concatenate([np.repeat(tracks[i][1][None, :k + 1], args.n, axis=0)
                               for i in use])
        inputs = sim._inputs(plan, rng, init)
        gen = torch.Generator().manual_seed(args.seed + g)
        roll = rollout(sim.model, inputs, k + 1 + h, None, sim.top_p_player, sim.top_p_ball,
                       generator=gen)
        for j, i in enumerate(np.repeat(use, args.n)):
            pos = tracks[i][1]
            horizon = min(h, len(pos) - k - 1)
            truth = pos[k + 1:k + 1 + horizon]
            pred = roll.pos_m[j, k + 1:k + 1 + horizon]
            vel = (pos[k] - pos[k - 1]) * fps
            lin = pos[k] + vel * (np.arange(1, horizon + 1) / fps)[:, None, None]
            for name, sl, dims in (("ball", 2, 3), ("players", slice(0, 2), 2)):
                err_m = ((pred[:, sl, :dims] - truth[:, sl, :dims]) ** 2).reshape(horizon, -1)
                err_l = ((lin[:, sl, :dims] - truth[:, sl, :dims]) ** 2).reshape(horizon, -1)
                n_obj = 1 if name == "ball" else 2
                sq_model[name][:horizon] += err_m.sum(axis=1) / n_obj
                sq_lin[name][:horizon] += err_l.sum(axis=1) / n_obj
            count[:horizon] += 1
    wall = time.perf_counter() - t0
    t = np.arange(1, h + 1) / fps
    df = pd.DataFrame({"t_s": t, "n": count.astype(int),
                       **{f"{k}_rmse_model_m": np.sqrt(sq_model[k] / np.maximum(count, 1))
                          for k in sq_model},
                       **{f"{k}_rmse_linear_m": np.sqrt(sq_lin[k] / np.maximum(count, 1))
                          for k in sq_lin}})
    args.out.mkdir(parents=True, exist_ok=True)
    df.to_csv(args.out / "horizon.csv", index=False)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
    for ax, k in zip(axes, ("ball", "players")):
        ax.plot(t, df[f"{k}_rmse_model_m"], label="SportsNGEN rollout")
        ax.plot(t, df[f"{k}_rmse_linear_m"], label="linear extrapolation", ls="--")
        ax.set_xlabel("time after branch (s)")
        ax.set_ylabel("RMSE (m)")
        ax.set_title(k)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out / "horizon.png", dpi=110)
    plt.close(fig)
    marks = [x for x in (0.2, 0.5, 1.0, args.horizon_s) if x <= args.horizon_s]
    lines = ["# Horizon study", "",
             f"`python scripts/horizon_study.py --rallies {args.rallies} --n {args.n} --seed "
             f"{args.seed}`: branches at {', '.join(f'{b:g}' for b in BRANCH_S)} s of "
             f"{len(ids)} held-out rallies, {args.n} rollouts each, {wall:.0f} s.", "",
             "| t after branch (s) | rollouts | ball RMSE model (m) | ball RMSE linear (m) | "
             "players RMSE model (m) | players RMSE linear (m) |",
             "|---:|---:|---:|---:|---:|---:|"]
    for x in marks:
        r = df.iloc[int(round(x * fps)) - 1]
        lines.append(f"| {x:g} | {int(r['n'])} | {r['ball_rmse_model_m']:.2f} | "
                     f"{r['ball_rmse_linear_m']:.2f} | {r['players_rmse_model_m']:.2f} | "
                     f"{r['players_rmse_linear_m']:.2f} |")
    lines += ["", "![horizon](horizon.png)"]
    (args.out / "horizon.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
