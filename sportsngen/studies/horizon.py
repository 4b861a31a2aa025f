"""Horizon study (the paper's Fig. 18): position error of rollouts against time after a branch
(`scripts/horizon_study.py`).

Held-out synthetic rallies (Federer v Nadal, hard, a generator seed the training never used) are
branched at 1, 2, 3 and 4 s after their start; `n` rollouts of each run for `horizon_s`
(no rally-end rules: a fixed horizon). At each time after the branch: RMSE of the ball's 3-D
position and of the players' 2-D positions against the recorded track, over every rollout whose
rally still lasts that long, beside linear extrapolation of the last recorded velocity (the
paper's reference).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from sportsngen.sim import Simulator
from sportsngen.sim.rollout import rollout
from sportsngen.sim.whatif import _plan, _rally
from sportsngen.studies.tables import md_table, write_markdown
from sportsngen.synth.generate import generate_matches
from sportsngen.viz.study_figures import plot_horizon

PLAYERS = ("Roger Federer", "Rafael Nadal")
BRANCH_S = (1.0, 2.0, 3.0, 4.0)


def horizon_errors(sim: Simulator, tracks: dict, n: int, h: int, rng: np.random.Generator,
                   seed: int) -> pd.DataFrame:
    """Per frame after the branch (1..h): rollouts counted, and the model's and linear
    extrapolation's RMSE (m) of the ball and the players, over `n` rollouts of every track
    (rally id -> (rally, positions, ...)) long enough to branch at each of `BRANCH_S`; `rng`
    draws the rollouts' inputs, generators seeded `seed + branch index` their samples."""
    fps = sim.fps
    sq_model = {k: np.zeros(h) for k in ("ball", "players")}
    sq_lin = {k: np.zeros(h) for k in ("ball", "players")}
    count = np.zeros(h)
    for g, b in enumerate(BRANCH_S):
        k = int(round(b * fps))
        use = [i for i, (_, pos, _) in tracks.items() if len(pos) > k + 2]
        if not use:
            continue
        plan = pd.concat([_plan(tracks[i][0], n) for i in use], ignore_index=True)
        init = np.concatenate([np.repeat(tracks[i][1][None, :k + 1], n, axis=0)
                               for i in use])
        inputs = sim._inputs(plan, rng, init)
        gen = torch.Generator().manual_seed(seed + g)
        roll = rollout(sim.model, inputs, k + 1 + h, None, sim.top_p_player, sim.top_p_ball,
                       generator=gen)
        for j, i in enumerate(np.repeat(use, n)):
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
    t = np.arange(1, h + 1) / fps
    return pd.DataFrame({"t_s": t, "n": count.astype(int),
                         **{f"{k}_rmse_model_m": np.sqrt(sq_model[k] / np.maximum(count, 1))
                            for k in sq_model},
                         **{f"{k}_rmse_linear_m": np.sqrt(sq_lin[k] / np.maximum(count, 1))
                            for k in sq_lin}})


def horizon_study(model: str | None, rallies: int, n: int, horizon_s: float, seed: int,
                  threads: int | None, out: Path) -> pd.DataFrame:
    """Branch `rallies` held-out rallies, roll out, write horizon.png, horizon.md and
    horizon.csv into `out`; -> the per-frame table."""
    if threads:
        torch.set_num_threads(threads)
    sim = Simulator.from_pretrained(model)
    fps = sim.fps
    h = int(round(horizon_s * fps))
    held = generate_matches([PLAYERS], "hard", 3 * rallies, seed=30_000 + seed, workers=1)
    rng = np.random.default_rng(seed)
    ids = held.rallies["rally_id"].to_numpy()[rng.permutation(len(held.rallies))[:rallies]]
    tracks = {int(i): _rally(held, int(i)) for i in ids}
    t0 = time.perf_counter()
    df = horizon_errors(sim, tracks, n, h, rng, seed)     # rng goes on after the sample
    wall = time.perf_counter() - t0
    out.mkdir(parents=True, exist_ok=True)
    df.to_csv(out / "horizon.csv", index=False)
    plot_horizon(df, out / "horizon.png")
    marks = [x for x in (0.2, 0.5, 1.0, horizon_s) if x <= horizon_s]
    rows = []
    for x in marks:
        r = df.iloc[int(round(x * fps)) - 1]
        rows.append([f"{x:g}", str(int(r["n"])), f"{r['ball_rmse_model_m']:.2f}",
                     f"{r['ball_rmse_linear_m']:.2f}", f"{r['players_rmse_model_m']:.2f}",
                     f"{r['players_rmse_linear_m']:.2f}"])
    lines = ["# Horizon study", "",
             f"`python scripts/horizon_study.py --rallies {rallies} --n {n} --seed "
             f"{seed}`: branches at {', '.join(f'{b:g}' for b in BRANCH_S)} s of "
             f"{len(ids)} held-out rallies, {n} rollouts each, {wall:.0f} s.", "",
             *md_table(["t after branch (s)", "rollouts", "ball RMSE model (m)",
                        "ball RMSE linear (m)", "players RMSE model (m)",
                        "players RMSE linear (m)"], rows, left=0),
             "", "![horizon](horizon.png)"]
    write_markdown(out / "horizon.md", lines)
    print("\n".join(lines))
    return df
