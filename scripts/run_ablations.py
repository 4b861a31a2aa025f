"""Train every ablation of conf/experiment/ablation_*.yaml at tiny scale and compare held-out NLL.

    nice -n 10 .venv/bin/python scripts/run_ablations.py --steps 1000 --seeds 0 1

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

Results go to `outputs/ablations/<name>_steps<N>_seed<k>/` (model, logs, `result.json`; an
existing `result.json` is reused unless --force) and the table to `docs/figures/ablations.md`.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
import time
from pathlib import Path

import torch
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from sportsngen.train.datamodule import data_fingerprint, load_rally_data
from sportsngen.train.evaluate import evaluate_held_out
from sportsngen.train.run import train_from_config

REPO = Path(__file__).resolve().parents[1]
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


def compose_config(ov: list[str]):
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base=None):
        return compose(config_name="train", overrides=ov)


def frozen_data(out: Path) -> tuple[Path, str]:
    """synthetic_tiny as a RallyData folder under `out` (made once) -> (folder, fingerprint)."""
    folder = out / "data"
    if not (folder / "meta.json").is_file():
        cfg = compose_config(["data=synthetic_tiny"])
        load_rally_data(OmegaConf.to_container(cfg.data, resolve=True)).save(folder)
    return folder, data_fingerprint(load_rally_data({"source": "folder", "path": str(folder)}))


def run_one(name: str, steps: int, seed: int, out: Path, data_path: Path, force: bool) -> dict:
    """Train (unless a result exists) and evaluate one ablation; -> its result dict."""
    out_dir = out / f"{name}_steps{steps}_seed{seed}"
    result_path = out_dir / "result.json"
    if result_path.is_file() and not force:
        return json.loads(result_path.read_text())
    print(f"[ablations] training {name} steps {steps} seed {seed}", flush=True)
    ov = overrides(name, steps, seed, data_path)
    t0 = time.perf_counter()
    summary = train_from_config(compose_config(ov), out_dir)
    train_s = time.perf_counter() - t0
    stats = evaluate_held_out(out_dir / "model.pt")
    res = {"name": name, "seed": seed, "steps": steps, "overrides": ov, "train_wall_s": train_s,
           "n_params": summary["n_params"], **stats}
    result_path.write_text(json.dumps(res, indent=2))
    print(f"[ablations] {name} seed {seed}: ball {res['nll_ball']:.3f} player "
          f"{res['nll_player']:.3f} ({train_s:.0f} s)", flush=True)
    return res


def _f(x: float | None, fmt: str = ".3f") -> str:
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, fmt)


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
    lines = ["| ablation (off) | " + " | ".join(h for h, _ in COLUMNS)
             + " | ball vs default | player vs default | params | train s |",
             "|---|" + "---:|" * (len(COLUMNS) + 4)]
    for name, m in means.items():
        d = ["", ""] if base is None or name == DEFAULT else [
            f"{m['nll_ball'] - base['nll_ball']:+.3f}",
            f"{m['nll_player'] - base['nll_player']:+.3f}"]
        lines.append(f"| {name} ({ABLATIONS[name]}) | "
                     + " | ".join(_f(m[k]) for _, k in COLUMNS)
                     + f" | {d[0]} | {d[1]} | {m['n_params']:,} | {m['train_wall_s']:.0f} |")
    return lines


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


def write_markdown(results: list[dict], args, argv: list[str], fingerprint: str) -> None:
    r0 = results[0]
    seeds = sorted({r["seed"] for r in results})
    shared = " ".join(o for o in r0["overrides"]
                      if not o.startswith(("experiment=", "+data.path=", "seed=")))
    text = [
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
    args.md.parent.mkdir(parents=True, exist_ok=True)
    args.md.write_text("\n".join(text) + "\n")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=1000, help="training steps of every run")
    p.add_argument("--seeds", type=int, nargs="+", default=[0])
    p.add_argument("--only", nargs="*", default=None,
                   help=f"ablation names to run (of {list(ABLATIONS)})")
    p.add_argument("--out", type=Path, default=REPO / "outputs" / "ablations")
    p.add_argument("--md", type=Path, default=REPO / "docs" / "figures" / "ablations.md")
    p.add_argument("--force", action="store_true", help="retrain even if a result exists")
    argv = sys.argv[1:]
    args = p.parse_args(argv)
    names = list(ABLATIONS) if args.only is None else args.only
    unknown = sorted(set(names) - set(ABLATIONS))
    if unknown:
        p.error(f"unknown ablations {unknown}; known: {list(ABLATIONS)}")
    torch.set_num_threads(1)
    data_path, fingerprint = frozen_data(args.out)
    results = [run_one(n, args.steps, s, args.out, data_path, args.force)
               for s in args.seeds for n in names]
    (args.out / "results.json").write_text(json.dumps(results, indent=2))
    if args.only is None:
        write_markdown(results, args, argv, fingerprint)
    print("\n".join(table(results)))


if __name__ == "__main__":
    main()
