"""Fine-tuning study (the paper's Fig. 13): a generic model adapted to a player it never saw
(`scripts/finetune_study.py`).

1. Base: a generic `small` decoder (`model.generic_identity=true`: one identity for every
   player) trained on `synthetic_small` generated without the player (`base_steps` steps).
   Or `base` (a model file, or `bundled`): a trained model used as it is, which plays an
   unknown player as the mean of its players' identities; the player must then be one it
   never saw: a population player named "Unseen M 000", ... (`players.population_prefix`),
   drawn with `population_seed`, whom the study's data pits against the other two.
2. For each k > 0: `train.py experiment=finetune_player` from the base, learning only the new
   identity row from the player's first k rallies (serving or receiving) of a separate
   generated set (the player and two population players, round robin).
3. Each model (k = 0 is the base, where the player is the generic identity) simulates
   `points` service points of the player against one population opponent on hard, from the
   same serve starts (the player's own, drawn from the fine-tuning data), beside the
   generator's ground truth for the same matchup: serve contact height, first-serve speed,
   first serve in %, aces %, double faults %, serve points won %, and the non-realistic share.
   600 points a model by default: at 150 the same base model read 76.4 % first serves in on
   one run and 71.1 % on 600 points, a draw as large as the gaps the study reads
   (docs/evaluation.md, forty-seventh part).

Every training runs `train.py` in a subprocess, so the commands in the printed log reproduce
each model.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from sportsngen.studies.tables import md_table, write_markdown
from sportsngen.train.evaluate import CONF_DATA
from sportsngen.viz.study_figures import plot_finetune_study

NAMED = ("Roger Federer", "Rafael Nadal", "Novak Djokovic", "Andy Murray", "John Isner",
         "Serena Williams", "Maria Sharapova")
METRICS = (("toss_contact_height_m", "serve contact height m", 1.0),
           ("first_serve_kmh", "1st serve km/h", 1.0),
           ("first_serve_in", "1st in %", 100.0), ("ace", "ace %", 100.0),
           ("double_fault", "DF %", 100.0), ("serve_points_won", "srv won %", 100.0))
UNSEEN = "Unseen"


def _hydra(value) -> str:
    """A value as Hydra override syntax (lists of strings quoted, dicts as {k: v})."""
    if isinstance(value, list):
        return "[" + ",".join(f'"{v}"' for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ",".join(f"{k}:{v}" for k, v in value.items()) + "}"
    return str(value)


def train(args: list[str], run_dir: Path, reuse: bool, root: Path) -> Path:
    """`train.py <args>` (run from `root`) into run_dir, its log beside it -> the model file."""
    model = run_dir / "model.pt"
    if reuse and model.is_file():
        print(f"reusing {model}")
        return model
    cmd = [sys.executable, "train.py", *args, f"hydra.run.dir={run_dir}"]
    print("$ " + " ".join(cmd), flush=True)
    t0 = time.perf_counter()
    with open(run_dir.parent / f"{run_dir.name}.log", "w") as log:
        subprocess.run(cmd, cwd=root, check=True, stdout=log, stderr=subprocess.STDOUT)
    print(f"  {time.perf_counter() - t0:.0f} s", flush=True)
    return model


def player_data(player: str, n_points: int, population_seed: int) -> dict[str, object]:
    """Overrides of conf/data/synthetic_small.yaml: the player against the population, a
    generator seed the base never saw. An unseen player is one of 3 renamed population players
    (the other two are his opponents)."""
    name = f"finetune_{player.replace(' ', '_')}"
    if player.startswith(UNSEEN + " "):
        return {"name": f"{name}_{population_seed}", "players.named": [],
                "players.population": {"men": 3, "women": 0},
                "players.population_seed": population_seed,
                "players.population_prefix": UNSEEN, "n_points": n_points, "seed": 11}
    return {"name": name, "players.named": [player],
            "players.population": {"men": 2, "women": 0}, "n_points": n_points, "seed": 11}


def data_args(overrides: dict[str, object]) -> list[str]:
    return ["data=synthetic_small"] + [
        f"++data.{k}={_hydra(v)}" for k, v in overrides.items()]


def evaluate(model_path: Path, player: str, opponent: str, truth, initial, n_points: int,
             seed: int, defaults: dict) -> dict:
    from sportsngen.eval.physical import shot_quantities
    from sportsngen.eval.stats import serve_stats
    from sportsngen.model.export import load_model
    from sportsngen.sim import Simulator
    from sportsngen.sim.assemble import realistic_points

    model, ec, vocab, _ = load_model(model_path)
    sim = Simulator(model, ec, vocab, initial, **defaults)
    d = sim.simulate_points(player, opponent, "hard", n_points, seed=seed)
    out = {"non_realistic": float((~d.rallies["realistic"]).mean())}
    for name, data in (("sim", realistic_points(d)), ("truth", truth)):
        st = serve_stats(data.points()).reindex([player]).iloc[0]
        q = shot_quantities(data)
        q = q[q["hitter"] == player].groupby("quantity")["value"].median()
        for key, _, _ in METRICS:
            physical = key.endswith(("_m", "_kmh"))
            out[f"{key}_{name}"] = float(q.get(key, np.nan) if physical else st[key])
    return out


def train_models(player: str, ks: list[int], base_steps: int, ft_steps: int, base_points: int,
                 pdata_overrides: dict, seed: int, threads: int, work: Path, reuse: bool,
                 base: str | None, root: Path) -> dict[int, Path]:
    """k -> model file: 0 the base (trained without the player, or the given file), each
    k > 0 fine-tuned from it on k of the player's sequences."""
    if base is not None:
        from sportsngen.sim.simulator import model_path

        base_file = model_path(None if base == "bundled" else base)
    else:
        others = [p for p in NAMED if p != player]
        without = {"name": f"synthetic_small_without_{player.replace(' ', '_')}",
                   "players.named": others, "n_points": base_points}
        base_file = train([*data_args(without), "model=small", "model.generic_identity=true",
                           "events.enabled=true",
                           f"trainer.max_steps={base_steps}", "trainer.val_check_interval=500",
                           f"threads={threads}", f"seed={seed}"], work / "base", reuse, root)
    models = {0: base_file}
    for k in ks:
        if k > 0:
            models[k] = train(["experiment=finetune_player", f"player={player}",
                               f"init={base_file}", f"finetune.n_sequences={k}",
                               f"trainer.max_steps={ft_steps}", f"threads={threads}",
                               *data_args(pdata_overrides)], work / f"k{k}", reuse, root)
    return models


def finetune_study(player: str, ks: list[int], base_steps: int, ft_steps: int,
                   base_points: int, player_points: int, points: int, seed: int, threads: int,
                   work: str, out: str, reuse: bool, base: str | None, population_seed: int,
                   root: Path) -> pd.DataFrame:
    """Train (or reuse) the models, simulate each, write finetune.md, finetune.csv and
    finetune.png into root/out (trainings in root/work); -> the table."""
    unseen = [f"{UNSEEN} M {i:03d}" for i in range(3)]
    if base is None and player not in NAMED:
        raise ValueError(f"--player must be one of the generator's named players {NAMED}")
    if base is not None and player not in unseen:
        raise ValueError(f"with --base, --player must be one the base never saw: {unseen}")
    torch.set_num_threads(threads)
    work_dir, out_dir = root / work, root / out
    work_dir.mkdir(parents=True, exist_ok=True)
    out_dir.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    pdata_overrides = player_data(player, player_points, population_seed)
    models = train_models(player, ks, base_steps, ft_steps, base_points, pdata_overrides, seed,
                          threads, work_dir, reuse, base, root)

    from omegaconf import OmegaConf

    from sportsngen.data.serve_starts import InitialConditions
    from sportsngen.model.export import read_extra
    from sportsngen.synth.dataset import load_synthetic, matchups
    from sportsngen.synth.generate import generate_matches

    cfg = OmegaConf.load(CONF_DATA / "synthetic_small.yaml")
    for key, value in pdata_overrides.items():
        OmegaConf.update(cfg, key, value)
    pdata = load_synthetic(OmegaConf.to_container(cfg, resolve=True))
    initial = InitialConditions.from_rally_data(pdata)
    r = pdata.rallies
    opponent = str(r.loc[r["server"] == player, "receiver"].value_counts().index[0])
    profiles = {p.name: p for pair in matchups(OmegaConf.to_container(cfg)) for p in pair}
    truth = generate_matches([(profiles[player], profiles[opponent])], "hard", 3000,
                             seed=seed + 100, workers=2)
    truth = truth.subset(truth.rallies.loc[truth.rallies["server"] == player, "rally_id"])
    # Every k samples as the base does, so the rows differ only in the player's identity.
    defaults = read_extra(models[0]).get("sim_defaults") or {}
    rows = []
    for k in sorted(models):
        t0 = time.perf_counter()
        res = evaluate(models[k], player, opponent, truth, initial, points, seed, defaults)
        rows.append({"k": k, **res})
        print(f"k={k}: " + ", ".join(f"{key} {res[key + '_sim']:.3f} (truth "
                                     f"{res[key + '_truth']:.3f})" for key, _, _ in METRICS)
              + f", non-realistic {res['non_realistic']:.3f} ({time.perf_counter() - t0:.0f} s)",
              flush=True)
    table = pd.DataFrame(rows)
    table.to_csv(out_dir / "finetune.csv", index=False)
    plot_finetune_study(table, out_dir / "finetune.png", METRICS)
    if base is None:
        how = (f"--base-steps {base_steps}", f"A generic `small` model trained "
               f"{base_steps} steps without {player}")
    else:
        how = (f"--base {base} --population-seed {population_seed}",
               f"The trained model `{models[0].name}`, which never saw {player} (a population "
               "player; at k = 0 he plays as the mean of its players' identities)")
    cells = [[str(row["k"]), *(f"{row[key + '_sim'] * f:.2f} "
                               f"({abs(row[key + '_sim'] - row[key + '_truth']) * f:.2f})"
                               for key, _, f in METRICS), f"{100 * row['non_realistic']:.1f}"]
             for row in rows]
    cells.append(["truth", *(f"{rows[0][key + '_truth'] * f:.2f}" for key, _, f in METRICS),
                  "0.0"])
    lines = ["# Fine-tuning study", "",
             f"`python scripts/finetune_study.py --player \"{player}\" --ks "
             f"{' '.join(map(str, ks))} {how[0]} --ft-steps "
             f"{ft_steps} --points {points} --seed {seed}` "
             f"({time.perf_counter() - t_start:.0f} s). {how[1]}; k of his sequences teach it "
             f"one new identity row ({ft_steps} steps, the rest frozen). {points} "
             f"simulated service points of {player} v {opponent} (hard) per model against "
             "the generator's ground truth of the same matchup (|sim - truth| in brackets).", "",
             *md_table(["k", *(label for _, label, _ in METRICS), "non-realistic %"], cells,
                       left=0),
             "", "![fine-tuning](finetune.png)"]
    write_markdown(out_dir / "finetune.md", lines)
    print("\n".join(lines))
    return table
