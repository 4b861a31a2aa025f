"""Compare the decoder's output heads, bin spacings and bin centres by held-out likelihood.

    nice -n 10 .venv/bin/python scripts/compare_heads.py --steps 2000 1000 --seeds 0 1 \\
        --seed-variants 2

Every variant is trained with `train_from_config` on the same data (`synthetic_tiny`, frozen
first into `outputs/compare_heads/data/<name>-<fingerprint>` because the generator's cache is
regenerated whenever its profiles or version change), the same `tiny` model, seed, steps and
`n_bins` (21, so that the joint ball head's 21^3 classes fit), then scored on its held-out
rallies (the validation split the training recorded in `model.pt`).

Discrete NLL over bins is not comparable across binnings (a wider bin holds more mass), so the
headline figure is the continuous NLL of the density the sampler draws from: a bin chosen with
probability p, then a point uniform inside it, has density p / prod(widths), so per object token

    continuous NLL = discrete NLL + sum over dimensions of log(width of the target bin in m).

A target beyond the bin range falls in an edge bin (`Bins.index` clamps) where the sampler puts
no mass at all; it is scored with the edge bin's width and counted (`out-of-range share`). The
constant-velocity Gaussian (per-dimension sigma fitted on the same tokens, as in
`sportsngen.train.metrics`) is scored as a true continuous density: it does not depend on the
binning, so equal values across variants show that every variant is scored on the same tokens.

Results go to `outputs/compare_heads/<variant>_steps<n>_seed<k>/` (model, logs, `result.json`; an
existing `result.json` is reused unless --force; --reevaluate scores it again) and the tables
to `docs/figures/compare_heads.md`.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import torch
from hydra import compose, initialize_config_dir
from torch.utils.data import DataLoader

from sportsngen.data.tokens import BALL, WindowDataset, object_features, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.model.export import load_model, read_extra
from sportsngen.synth.dataset import cache_root
from sportsngen.train.datamodule import data_fingerprint, load_rally_data, split_rallies
from sportsngen.train.evaluate import data_config
from sportsngen.train.metrics import CV_SIGMAS_M, NextFrameMetrics
from sportsngen.train.run import train_from_config

REPO = Path(__file__).resolve().parents[1]
LOG_2PI = math.log(2.0 * math.pi)
NOTES_MARKER = "<!-- hand-written notes below: kept when the script rewrites this file -->"


@dataclass(frozen=True)
class Variant:
    head: str
    spacing: str
    centre: str  # the players' bins (`model.bin_centre`)
    ball: str  # the ball's (`model.ball_centre`)
    note: str = ""

    @property
    def name(self) -> str:
        return f"{self.head}-{self.spacing}-{self.centre}-{self.ball}"


# The physics centre's sampler puts a draw in the centre bin on the centre itself (its step is
# exact in free flight), so the uniform-in-bin density scored here understates what it draws.
VARIANTS = (
    Variant("factorised", "nonuniform", "cv", "velocity", "current default"),
    Variant("joint", "nonuniform", "cv", "velocity"),
    Variant("factorised", "uniform", "cv", "velocity"),
    Variant("factorised", "nonuniform", "cv", "physics", "the ball on one physics step"),
    Variant("factorised", "nonuniform", "current", "current"),
    Variant("joint", "uniform", "current", "current", "the paper's"),
    Variant("factorised", "uniform", "current", "current"),
)


def freeze_data(args) -> Path:
    """A copy of the data under out/data/<name>-<fingerprint> that every variant trains on:
    a cached synthetic set is regenerated whenever the generator's profiles or version change,
    which must not happen between two variants of one comparison."""
    if args.data_path:
        data, name = RallyData.load(args.data_path), Path(args.data_path).name.split("-")[0]
    else:
        data, name = load_rally_data(data_config(args.data)), args.data
    dest = args.out / "data" / f"{name}-{data_fingerprint(data)}"
    if not (dest / "meta.json").is_file():
        data.save(dest)
    return dest


def overrides(v: Variant, steps: int, seed: int, n_bins: int, data_dir: Path) -> list[str]:
    # One validation pass at the end only: intermediate ones would cost CPU time and change
    # nothing in the exported model (train_from_config exports the last weights).
    return ["experiment=tiny", "data=synthetic_tiny", "data.source=folder",
            f"+data.path={data_dir}", "threads=1", f"seed={seed}",
            f"trainer.max_steps={steps}", f"trainer.val_check_interval={steps}",
            "trainer.limit_val_batches=2", "trainer.enable_progress_bar=false",
            "events.enabled=false", f"model.head={v.head}", f"model.bin_spacing={v.spacing}",
            f"model.bin_centre={v.centre}", f"model.ball_centre={v.ball}",
            f"model.n_bins={n_bins}"]


def train_variant(v: Variant, steps: int, seed: int, n_bins: int, data_dir: Path,
                  out_dir: Path) -> dict:
    """Train one variant into out_dir; -> wall time (s), parameter count, overrides."""
    ov = overrides(v, steps, seed, n_bins, data_dir)
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base=None):
        cfg = compose(config_name="train", overrides=ov)
    t0 = time.perf_counter()
    summary = train_from_config(cfg, out_dir)
    return {"train_wall_s": time.perf_counter() - t0, "n_params": summary["n_params"],
            "overrides": ov}


def training_data(split: dict, search: list[Path], cache: dict) -> RallyData:
    """The rallies a model was trained on: its recorded data config if that still gives the
    recorded fingerprint, else the folder among `search` (frozen copies, synthetic caches)
    that does; anything else would score a model on rallies it may have trained on."""
    fp = split["fingerprint"]
    if fp in cache:
        return cache[fp]
    try:
        data = load_rally_data(split["data"])
    except FileNotFoundError:
        data = None
    if data is None or data_fingerprint(data) != fp:
        data = None
        for folder in search:
            if (folder / "meta.json").is_file():
                candidate = RallyData.load(folder)
                if data_fingerprint(candidate) == fp:
                    data = candidate
                    break
    if data is None:
        raise RuntimeError(f"no data with the training fingerprint {fp} (looked in "
                           f"{[str(f) for f in search]})")
    cache[fp] = data
    return data


def held_out_loader(model_path: Path, batch_size: int, search: list[Path],
                    cache: dict) -> DataLoader:
    """Windows of the rallies the training put in validation (as `train.evaluate` does)."""
    _, _, vocab, cfg = load_model(model_path)
    split = read_extra(model_path)["split"]
    arrays = rally_arrays(training_data(split, search, cache), vocab, cfg.unknown)
    held = split_rallies(arrays, float(split["val_fraction"]), int(split["seed"]))[1]
    return DataLoader(WindowDataset(held, cfg.window_frames, None), batch_size=batch_size)


def gaussian_nll_grid(err_m: torch.Tensor) -> torch.Tensor:
    """(N, dims) errors -> (sigmas, dims) summed Gaussian NLL (nats) for each sigma in
    CV_SIGMAS_M: the continuous constant-velocity reference, sigma picked afterwards."""
    s = CV_SIGMAS_M[:, None, None]
    e = err_m.double()[None]
    return (0.5 * (e / s) ** 2 + torch.log(s) + 0.5 * LOG_2PI).sum(dim=1)


@torch.no_grad()
def evaluate(model_path: Path, batch_size: int, search: list[Path], cache: dict) -> dict:
    """Held-out continuous and discrete NLL, top-1, out-of-range shares of one model file."""
    model, _, _, cfg = load_model(model_path)
    loader = held_out_loader(model_path, batch_size, search, cache)
    disc = NextFrameMetrics()
    parts = ("player", "flight", "contact")
    dims = {"player": 2, "flight": 3, "contact": 3}
    sums = {p: {"n": 0, "cont": 0.0, "disc": 0.0, "oor": 0,
                "cv": torch.zeros(len(CV_SIGMAS_M), dims[p], dtype=torch.float64)}
            for p in parts}
    for batch in loader:
        feats = object_features(batch["pos_m"], batch["vel_mps"], batch["t_s"])
        ctx = model.context_tokens(batch["surface"], batch["tournament"], batch["serve"],
                                   batch["score"])
        h = model(feats, batch["ident"], ctx)
        disc.update(model, batch, h)
        pos, vel, nxt = batch["pos_m"], batch["vel_mps"], batch["next_pos_m"]
        p_idx, b_idx = model.target_bins(pos, vel, nxt, batch.get("prev_vel_mps"))
        p_nll, b_nll = model.nll(h, p_idx, b_idx)
        off = nxt - model.centres(pos, vel, batch.get("prev_vel_mps"))
        cv_err = nxt - (pos + vel / cfg.fps)
        m = batch["has_next"].bool()
        near = batch["near_contact"].bool()
        selections = {
            "player": (model.player_bins, p_idx[m], p_nll[m], off[..., :BALL, :2][m],
                       cv_err[..., :BALL, :2][m]),
        }
        for part, sel in (("flight", m & ~near), ("contact", m & near)):
            selections[part] = (model.ball_bins, b_idx[sel], b_nll[sel],
                                off[..., BALL, :][sel], cv_err[..., BALL, :][sel])
        for part, (bins, idx, nll, o, e) in selections.items():
            idx, nll = idx.reshape(-1, dims[part]), nll.reshape(-1)
            o, e = o.reshape(-1, dims[part]), e.reshape(-1, dims[part])
            log_w = torch.log(bins.width(idx).double()).sum(-1)
            out = ((o < bins.edges[:, 0]) | (o > bins.edges[:, -1])).any(-1)
            s = sums[part]
            s["n"] += nll.numel()
            s["disc"] += float(nll.double().sum())
            s["cont"] += float((nll.double() + log_w).sum())
            s["oor"] += int(out.sum())
            s["cv"] += gaussian_nll_grid(e)
    res = {k: v for k, v in disc.compute().items() if not k.startswith("cv_")}
    res["data_fingerprint"] = read_extra(model_path)["split"]["fingerprint"]
    n_ball = sums["flight"]["n"] + sums["contact"]["n"]
    cv_ball = sums["flight"]["cv"] + sums["contact"]["cv"]
    best_b = cv_ball.argmin(dim=0)[None]
    best_p = sums["player"]["cv"].argmin(dim=0)[None]
    res["cont_nll_player"] = sums["player"]["cont"] / sums["player"]["n"]
    res["cont_nll_ball"] = (sums["flight"]["cont"] + sums["contact"]["cont"]) / n_ball
    res["oor_player"] = sums["player"]["oor"] / sums["player"]["n"]
    res["oor_ball"] = (sums["flight"]["oor"] + sums["contact"]["oor"]) / n_ball
    res["cv_cont_nll_player"] = float(sums["player"]["cv"].gather(0, best_p).sum()) / \
        sums["player"]["n"]
    res["cv_cont_nll_ball"] = float(cv_ball.gather(0, best_b).sum()) / n_ball
    for part in ("flight", "contact"):
        s = sums[part]
        res[f"cont_nll_ball_{part}"] = s["cont"] / s["n"] if s["n"] else math.nan
        res[f"oor_ball_{part}"] = s["oor"] / s["n"] if s["n"] else math.nan
        res[f"cv_cont_nll_ball_{part}"] = float(s["cv"].gather(0, best_b).sum()) / s["n"] \
            if s["n"] else math.nan
    # The discrete NLL summed here must be the project's metric on the same tokens.
    for mine, theirs in (("player", "nll_player"), ("flight", "nll_ball_flight")):
        if abs(sums[mine]["disc"] / sums[mine]["n"] - res[theirs]) > 1e-5:
            raise RuntimeError(f"discrete NLL mismatch for {mine}: token selection differs")
    return res


def run_dir(out: Path, name: str, steps: int, seed: int) -> Path:
    return out / f"{name}_steps{steps}_seed{seed}"


def run_one(v: Variant, steps: int, seed: int, args) -> dict:
    out_dir = run_dir(args.out, v.name, steps, seed)
    result_path = out_dir / "result.json"
    search = [args.data_dir, *sorted((args.out / "data").glob("*")),
              *sorted((cache_root() / "synthetic").glob(f"{args.data}-*"))]
    if result_path.is_file() and not args.force:
        res = json.loads(result_path.read_text())
        if not args.reevaluate:
            return res
        keep = ("variant", "note", "seed", "steps", "train_wall_s", "n_params", "overrides")
        res = {**{k: res[k] for k in keep},
               **evaluate(out_dir / "model.pt", args.batch_size, search, args.cache)}
        result_path.write_text(json.dumps(res, indent=2))
        return res
    print(f"[compare_heads] training {v.name} steps {steps} seed {seed}", flush=True)
    info = train_variant(v, steps, seed, args.n_bins, args.data_dir, out_dir)
    res = {"variant": v.name, "note": v.note, "seed": seed, "steps": steps, **info,
           **evaluate(out_dir / "model.pt", args.batch_size, search, args.cache)}
    result_path.write_text(json.dumps(res, indent=2))
    print(f"[compare_heads] {v.name} steps {steps} seed {seed}: ball "
          f"{res['cont_nll_ball']:.3f} player {res['cont_nll_player']:.3f} "
          f"({res['train_wall_s']:.0f} s)", flush=True)
    return res


def _f(x: float, fmt: str = ".3f") -> str:
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, fmt)


def table(results: list[dict]) -> list[str]:
    lines = [
        "| variant | seed | ball cont. NLL | flight | contact | player cont. NLL | "
        "ball floor | player floor | ball disc. NLL | player disc. NLL | ball top-1 | "
        "flight top-1 | contact top-1 | player top-1 | ball out-of-range | "
        "player out-of-range | train s | params |",
        "|---|---:|" + "---:|" * 16,
    ]
    for r in results:
        name = r["variant"] + (f" ({r['note']})" if r.get("note") else "")
        lines.append(
            f"| {name} | {r['seed']} | {_f(r['cont_nll_ball'])} | "
            f"{_f(r['cont_nll_ball_flight'])} | {_f(r['cont_nll_ball_contact'])} | "
            f"{_f(r['cont_nll_player'])} | {_f(r['cont_nll_ball'] - r['nll_ball'])} | "
            f"{_f(r['cont_nll_player'] - r['nll_player'])} | {_f(r['nll_ball'])} | "
            f"{_f(r['nll_player'])} | "
            f"{_f(r['acc_ball'])} | {_f(r['acc_ball_flight'])} | {_f(r['acc_ball_contact'])} | "
            f"{_f(r['acc_player'])} | {_f(100 * r['oor_ball'], '.2f')}% | "
            f"{_f(100 * r['oor_player'], '.2f')}% | {r['train_wall_s']:.0f} | "
            f"{r['n_params']:,} |")
    return lines


def summary_lines(results: list[dict]) -> list[str]:
    """Ranking on the first seed, and each variant's paired difference to the winner on every
    seed that has both (their spread over seeds is the noise estimate)."""
    seeds = sorted({r["seed"] for r in results})
    by = {(r["variant"], r["seed"]): r for r in results}
    names = [r["variant"] for r in results if r["seed"] == seeds[0]]
    out = [f"Ranked on seed {seeds[0]}; paired differences to the winner per seed "
           f"(seeds {seeds}; a seed sets the initialisation, the data order and the held-out "
           "split). Continuous NLL, nats per object token, lower is better.", ""]
    for key, label in (("cont_nll_ball", "ball"), ("cont_nll_ball_flight", "ball in flight"),
                       ("cont_nll_ball_contact", "ball at contact"),
                       ("cont_nll_player", "players")):
        ranked = sorted(names, key=lambda n: by[(n, seeds[0])][key])
        best = ranked[0]
        out.append(f"- **{label}**: " + ", ".join(f"{n} {by[(n, seeds[0])][key]:.3f}"
                                                  for n in ranked) + ".")
        for n in ranked[1:]:
            d = ", ".join(f"seed {s} {by[(n, s)][key] - by[(best, s)][key]:+.3f}"
                          for s in seeds if (n, s) in by and (best, s) in by)
            out.append(f"  - {n} minus {best}: {d}")
    return out


def uniform_floor(model_path: Path, n_bins: int) -> tuple[float, float]:
    """(ball, player) continuous NLL of a perfect bin picker on uniform bins: with equal
    widths the log bin volume is the same for every token, sum over dims of log(2 R / n)."""
    cfg = load_model(model_path)[3]
    ball = sum(math.log(2 * s / cfg.fps / n_bins) for s in cfg.ball_max_speed_mps)
    return ball, 2 * math.log(2 * cfg.player_max_speed_mps / cfg.fps / n_bins)


def data_line(results: list[dict]) -> str:
    """Which data (fingerprint, `data_fingerprint`) the runs of a table were trained and
    scored on: comparisons inside a table are only fair on one data set."""
    fps = sorted({r["data_fingerprint"] for r in results})
    if len(fps) == 1:
        return f"Every run of this table trained and scored on data `{fps[0]}`."
    return ("**Mixed data** (compare only rows of the same fingerprint): " + "; ".join(
        f"`{fp}`: " + ", ".join(f"{r['variant']} seed {r['seed']}" for r in results
                               if r["data_fingerprint"] == fp) for fp in fps) + ".")


def write_markdown(results: list[dict], args, argv: list[str]) -> None:
    main_steps = args.steps[0]
    main = [r for r in results if r["steps"] == main_steps]
    r0 = main[0]
    model_file = run_dir(args.out, r0["variant"], r0["steps"], r0["seed"]) / "model.pt"
    cmd = "nice -n 10 .venv/bin/python scripts/compare_heads.py " + shlex.join(argv)
    text = [
        "# Output heads, bin spacing and bin centre: held-out likelihood",
        "",
        f"Reproduce (from the repository root; {len(results)} CPU trainings in sequence, "
        "threads=1; without --data-path the current `synthetic_tiny` is frozen first into "
        "`outputs/compare_heads/data/<name>-<fingerprint>`; runs whose `result.json` exists "
        "are reused):",
        "",
        "```bash",
        "nice -n 10 .venv/bin/python scripts/compare_heads.py --steps 2000 1000 --seeds 0 1 "
        "--seed-variants 2",
        "```",
        "",
        f"This file was written by `{cmd.strip()}`.",
        "",
        f"Each variant: `train_from_config` with overrides `{' '.join(r0['overrides'][:-5])}` "
        "plus its `model.head`, `model.bin_spacing`, `model.bin_centre` (the players'), "
        f"`model.ball_centre` and `model.n_bins={args.n_bins}` (a variant is named "
        "head-spacing-players' centre-ball's centre): the `tiny` model on `synthetic_tiny`, "
        f"the same seed, data and steps (batch 8). Scored on the held-out rallies of the "
        "training's own validation split (the split seed is the training seed).",
        "",
        "NLL in nats per object token. **Continuous NLL** = discrete NLL + sum over "
        "dimensions of log(target bin width in m): minus the log density of the "
        "piecewise-uniform distribution the sampler draws from, comparable across binnings "
        "(lower is better). Discrete NLL and top-1 are over each variant's own bins and are "
        "not comparable across binnings. Out-of-range: share of tokens whose target lies "
        "beyond the bin range in some dimension (scored in the edge bin, where the sampler "
        "puts no mass). Floor = continuous minus discrete NLL = mean log volume (m^d) of the "
        "target bins: what a model that always picked the right bin would score, so the gap "
        "to it is the model's own error and the floor itself is the binning's resolution "
        "cost. Ball contact = within one frame of a shot (`near_contact`). The physics "
        "centre's sampler takes the centre itself for a draw in the centre bin (its step is "
        "exact in free flight), so its continuous NLL here, of the uniform-in-bin density, "
        "understates what it draws.",
        "",
        f"### {main_steps} steps",
        "",
        data_line(main),
        "",
        *table(main),
        "",
        "Reference: constant-velocity Gaussian (continuous, sigma per dimension fitted on the "
        f"same tokens): ball {r0['cv_cont_nll_ball']:.3f} (flight "
        f"{r0['cv_cont_nll_ball_flight']:.3f}, contact {r0['cv_cont_nll_ball_contact']:.3f}), "
        f"players {r0['cv_cont_nll_player']:.3f} (seed {r0['seed']}'s split; the same for "
        "every variant of that seed).",
        "",
        *[f"Uniform-bin floor with {n} bins (a model that always picks the right bin): "
          f"ball {b:.3f}, players {pl:.3f}." for n, (b, pl) in
          ((n, uniform_floor(model_file, n)) for n in (args.n_bins, 61))],
        "",
        "## Result",
        "",
        f"### Result at {main_steps} steps",
        "",
        *summary_lines(main),
    ]
    if len({r["data_fingerprint"] for r in results}) > 1:
        text += ["", "The tables below used other data (another generator version or other "
                 "profiles, by fingerprint): compare rows within a table, not across tables."]
    for steps in args.steps[1:]:
        other = [r for r in results if r["steps"] == steps]
        text += ["", f"### {steps} steps (does the ranking hold with less training?)", "",
                 data_line(other), "", *table(other), "", *summary_lines(other)]
    # Hand-written notes below the marker survive a rewrite of the generated part.
    notes = NOTES_MARKER + "\n"
    if args.md.is_file() and NOTES_MARKER in args.md.read_text():
        notes = args.md.read_text().split(NOTES_MARKER, 1)
        notes = NOTES_MARKER + notes[1]
    args.md.parent.mkdir(parents=True, exist_ok=True)
    args.md.write_text("\n".join(text) + "\n\n" + notes)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, nargs="+", default=[600],
                   help="training steps of every variant; the first is the main comparison")
    p.add_argument("--seeds", type=int, nargs="+", default=[0],
                   help="seeds of the main comparison (two or more: a noise estimate)")
    p.add_argument("--seed-variants", type=int, default=None,
                   help="run the seeds after the first only for the first N variants")
    p.add_argument("--n-bins", type=int, default=21)
    p.add_argument("--only", nargs="*", default=None, help="variant names to run")
    p.add_argument("--batch-size", type=int, default=32, help="evaluation batch size")
    p.add_argument("--out", type=Path, default=REPO / "outputs" / "compare_heads")
    p.add_argument("--md", type=Path, default=REPO / "docs" / "figures" / "compare_heads.md")
    p.add_argument("--data", default="synthetic_tiny", help="a conf/data config to freeze")
    p.add_argument("--data-path", type=Path, default=None,
                   help="a RallyData folder to freeze and train on instead of --data")
    p.add_argument("--force", action="store_true", help="retrain even if a result exists")
    p.add_argument("--reevaluate", action="store_true",
                   help="score existing runs again (on the data matching their fingerprint)")
    argv = sys.argv[1:]
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    args.cache = {}
    args.data_dir = freeze_data(args)
    variants = [v for v in VARIANTS if args.only is None or v.name in args.only]
    runs = []
    for n in args.steps:
        runs += [(v, n, args.seeds[0]) for v in variants]
        runs += [(v, n, s) for s in args.seeds[1:] for v in variants[:args.seed_variants]]
    results = [run_one(v, n, s, args) for v, n, s in runs]
    (args.out / "results.json").write_text(json.dumps(results, indent=2))
    if args.only is None:
        write_markdown(results, args, argv)
    print("\n".join(table(results)))


if __name__ == "__main__":
    main()
