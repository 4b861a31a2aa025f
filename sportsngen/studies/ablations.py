"""Every ablation of conf/experiment/ablation_*.yaml trained at tiny scale and compared by
held-out NLL (`scripts/run_ablations.py`).

Each ablation is its own experiment config (`python train.py experiment=ablation_no_velocity`);
here every one, and the full model ("default"), is trained by `train_from_config` with the same
tiny-scale overrides (those of `experiment=tiny`: the tiny model on synthetic_tiny, batch 8, one
thread), the same seed and steps, then scored by `sportsngen.train.evaluate.evaluate_held_out`
on the held-out rallies of its own training split (the split seed is the training seed, so every
ablation of one seed is scored on the same rallies). All variants share the bins (tiny: 21,
nonuniform, centred on the constant-velocity extrapolation), so their discrete NLLs compare.

synthetic_tiny is generated once and frozen in `<out>/data` (a `RallyData` folder, reused by
later runs): the generator's cache is keyed by the calibrated profiles, so a profile change
in the middle of the sequence would otherwise give later ablations other rallies.
"""

from __future__ import annotations

import json
import shlex
from pathlib import Path

import torch

from sportsngen.studies.tables import md_table, write_markdown
from sportsngen.studies.variants import freeze_data, run_variant
from sportsngen.train.datamodule import data_fingerprint, load_rally_data
from sportsngen.train.evaluate import data_config, evaluate_held_out
from sportsngen.train.evaluate import format_or_na as _f

DEFAULT = "default"
# name -> what it switches off (the experiment config is conf/experiment/ablation_<name>.yaml).
ABLATIONS = {
    DEFAULT: "nothing: the full tiny model",
    "baseline": "velocity, distance, time, context: the paper's baseline",
    "no_velocity": "velocity features",
    "no_distance": "distance-to-ball feature",
    "no_time": "elapsed-time feature",
    "no_context": "context tokens",
    "ball_noise": "nothing; adds the paper's ball-noise augmentation (off by default)",
    "id0": "identity embedding; tiny has size 8",
    "id4": "identity size 4",
    "id20": "identity size 20",
    "id64": "identity size 64",
}
# (column header, result key): held-out NLL in nats per object token, then top-1.
COLUMNS = (("ball NLL", "nll_ball"), ("ball flight", "nll_ball_flight"),
           ("ball contact", "nll_ball_contact"), ("player NLL", "nll_player"),
           ("ball top-1", "acc_ball"), ("player top-1", "acc_player"))


def overrides(name: str, steps: int, seed: int, data_path: Path | None = None) -> list[str]:
    """Hydra overrides of one run: the ablation's experiment, then `experiment=tiny`'s scale;
    with `data_path`, synthetic_tiny read from that frozen folder. One validation pass at the
    end only (the exported model is the last weights anyway)."""
    exp = [] if name == DEFAULT else [f"experiment=ablation_{name}"]
    data = [] if data_path is None else ["data.source=folder", f"+data.path={data_path}"]
    return exp + ["model=tiny", "data=synthetic_tiny", *data, "trainer=cpu",
                  "windows.batch_size=8", "threads=1", f"seed={seed}",
                  f"trainer.max_steps={steps}", f"trainer.val_check_interval={steps}",
                  "trainer.limit_val_batches=2", "trainer.enable_progress_bar=false",
                  "events.enabled=false"]


def mean_over_seeds(results: list[dict]) -> dict[str, dict[str, float]]:
    """name -> {result key: mean over the seeds that name was run with}."""
    out: dict[str, dict[str, float]] = {}
    for name in dict.fromkeys(r["name"] for r in results):
        rs = [r for r in results if r["name"] == name]
        out[name] = {k: sum(r[k] for r in rs) / len(rs) for _, k in COLUMNS}
        out[name].update(train_wall_s=sum(r["train_wall_s"] for r in rs) / len(rs),
                         n_params=rs[0]["n_params"], n_seeds=len(rs))
    return out


def table(results: list[dict]) -> list[str]:
    """One row an ablation: means over seeds, and the paired difference to the default."""
    means = mean_over_seeds(results)
    base = means.get(DEFAULT)
    rows = []
    for name, m in means.items():
        d = ["", ""] if base is None or name == DEFAULT else [
            f"{m['nll_ball'] - base['nll_ball']:+.3f}",
            f"{m['nll_player'] - base['nll_player']:+.3f}"]
        rows.append([f"{name} ({ABLATIONS[name]})", *(_f(m[k]) for _, k in COLUMNS), *d,
                     f"{m['n_params']:,}", f"{m['train_wall_s']:.0f}"])
    return md_table(["ablation (off)", *(h for h, _ in COLUMNS), "ball vs default",
                     "player vs default", "params", "train s"], rows)


def per_seed_lines(results: list[dict]) -> list[str]:
    """Each seed's difference to that seed's default (the spread is the noise estimate)."""
    seeds = sorted({r["seed"] for r in results})
    by = {(r["name"], r["seed"]): r for r in results}
    out = []
    for name in dict.fromkeys(r["name"] for r in results):
        if name == DEFAULT:
            continue
        parts = []
        for key, label in (("nll_ball", "ball"), ("nll_player", "player")):
            d = [by[(name, s)][key] - by[(DEFAULT, s)][key] for s in seeds
                 if (name, s) in by and (DEFAULT, s) in by]
            parts.append(f"{label} " + ", ".join(f"{x:+.3f}" for x in d) + f" ({_verdict(d)})")
        out.append(f"- {name}: " + "; ".join(parts))
    return out


def _verdict(diffs: list[float]) -> str:
    if len(diffs) > 1 and all(x > 0 for x in diffs):
        return "worse on every seed"
    if len(diffs) > 1 and all(x < 0 for x in diffs):
        return "better on every seed"
    return "mixed" if len(diffs) > 1 else "one seed"


def ablations_markdown(results: list[dict], argv: list[str], fingerprint: str) -> list[str]:
    """The lines of `docs/figures/ablations.md`."""
    r0 = results[0]
    seeds = sorted({r["seed"] for r in results})
    shared = " ".join(o for o in r0["overrides"]
                      if not o.startswith(("experiment=", "+data.path=", "seed=")))
    return [
        "# Ablations: held-out next-frame NLL at tiny scale",
        "",
        f"Reproduce (from the repository root; {len(results)} CPU trainings in sequence, "
        f"threads=1; {sum(r['train_wall_s'] for r in results) / 60:.0f} min of training "
        "under `nice -n 10` on a shared 2-core machine, evaluation not counted):",
        "",
        "```bash",
        ("nice -n 10 .venv/bin/python scripts/run_ablations.py " + shlex.join(argv)).rstrip(),
        "```",
        "",
        "Each row: `train_from_config` with `experiment=ablation_<name>` (none for `default`) "
        f"and `{shared}` (and the seed): the `tiny` model on `synthetic_tiny`, frozen in "
        f"`<out>/data` (fingerprint `{fingerprint}`), {r0['steps']} steps of batch 8, no "
        "event classifier. Scored by `evaluate_held_out` (what `scripts/evaluate_model.py` "
        "prints) on the held-out rallies of the run's own split (seed "
        f"{r0['seed']}: {r0['n_rallies']} rallies); every run of one seed has the same"
        f" split. Seeds {seeds}: figures are means over them.",
        "",
        "NLL in nats per object token (lower is better), summed over the dimensions of the "
        "target bin; the bins are the same for every row (21 a dimension, nonuniform, centred "
        "on the constant-velocity extrapolation), so the NLLs compare across rows. Ball "
        "contact = within one frame of a shot. `vs default` = mean paired difference to the "
        "full model (positive: the ablation is worse).",
        "",
        *table(results),
        "",
        "Per seed, difference to that seed's default (the spread across seeds is the noise; "
        "positive: worse than the full model):",
        "",
        *per_seed_lines(results),
        "",
        "Caveats:",
        "",
        "- Tiny scale (33k parameters, synthetic_tiny's 4 players on one surface, short "
        "training): differences of a few hundredths are within seed noise, and inputs that "
        "carry little information here (context, identity) can cost more in overfitting than "
        "they give.",
        "- The bins are centred on the constant-velocity extrapolation computed from the "
        "observed positions, so `no_velocity` and `baseline` still get the velocity through "
        "the output's centre; with `model.bin_centre=current` (the paper's) velocity would "
        "matter more.",
        "- Ball noise: the held-out windows are noise-free synthetic tracks (no augmentation "
        "at evaluation), while training noise moves the ball's input position and velocity and "
        "so also the bin centre its target is measured from; a noised model learns a wider "
        "ball distribution, which teacher-forced NLL on clean data can only penalise. What the "
        "noise is for (robustness to tracking noise, stable rollouts) is not measured here.",
    ]


def run_ablations(steps: int, seeds: list[int], only: list[str] | None, out: Path, md: Path,
                  force: bool, argv: list[str]) -> list[dict]:
    """Freeze synthetic_tiny in `out/data`, train and score each ablation (all by default) on
    every seed, write `out/results.json` and (unless `only`) `md`; print the table."""
    names = list(ABLATIONS) if only is None else only
    unknown = sorted(set(names) - set(ABLATIONS))
    if unknown:
        raise ValueError(f"unknown ablations {unknown}; known: {list(ABLATIONS)}")
    torch.set_num_threads(1)
    data_path = freeze_data(out / "data", lambda: load_rally_data(data_config("synthetic_tiny")))
    fingerprint = data_fingerprint(load_rally_data({"source": "folder", "path": str(data_path)}))
    results = [run_variant(out / f"{n}_steps{steps}_seed{s}", overrides(n, steps, s, data_path),
                           {"name": n, "seed": s, "steps": steps},
                           lambda path: evaluate_held_out(path), force, tag="ablations")
               for s in seeds for n in names]
    (out / "results.json").write_text(json.dumps(results, indent=2))
    if only is None:
        write_markdown(md, ablations_markdown(results, argv, fingerprint))
    print("\n".join(table(results)))
    return results
