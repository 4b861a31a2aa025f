"""Compare the decoder's output heads, bin spacings and bin centres by held-out likelihood
(`scripts/compare_heads.py`).

Every variant is trained with `train_from_config` on the same data (`synthetic_tiny`, frozen
first into `<out>/data/<name>-<fingerprint>`), the same `tiny` model, seed, steps and `n_bins`
(21, so that the joint ball head's 21^3 classes fit), then scored on its held-out rallies (the
validation split the training recorded in `model.pt`) by `evaluate_held_out(...,
continuous=True)`: discrete NLL over bins is not comparable across binnings (a wider bin holds
more mass), so the headline figure is the continuous NLL of the density the sampler draws from
(`sportsngen.train.evaluate`).
"""

from __future__ import annotations

import json
import math
import shlex
from dataclasses import dataclass
from pathlib import Path

import torch

from sportsngen.data.tracking import RallyData
from sportsngen.model.export import load_model, read_extra
from sportsngen.studies.tables import kept_tail, md_table, write_markdown
from sportsngen.studies.variants import freeze_data, run_variant
from sportsngen.synth.dataset import cache_root
from sportsngen.train.datamodule import data_fingerprint, load_rally_data
from sportsngen.train.evaluate import data_config, evaluate_held_out
from sportsngen.train.evaluate import format_or_na as _f

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


def training_data_config(split: dict, search: list[Path]) -> dict:
    """The data config of the rallies a model was trained on: its recorded one if that still
    gives the recorded fingerprint, else the folder among `search` (frozen copies, synthetic
    caches) that does; anything else would score a model on rallies it may have trained on."""
    fp = split["fingerprint"]
    try:
        if data_fingerprint(load_rally_data(split["data"])) == fp:
            return split["data"]
    except FileNotFoundError:
        pass
    for folder in search:
        if (folder / "meta.json").is_file() and data_fingerprint(RallyData.load(folder)) == fp:
            return {"source": "folder", "path": str(folder)}
    raise RuntimeError(f"no data with the training fingerprint {fp} (looked in "
                       f"{[str(f) for f in search]})")


def evaluate(model_path: Path, batch_size: int, search: list[Path]) -> dict:
    """Held-out continuous and discrete NLL, top-1, out-of-range shares of one model file."""
    split = read_extra(model_path)["split"]
    res = evaluate_held_out(model_path, training_data_config(split, search),
                            batch_size=batch_size, continuous=True)
    return {**res, "data_fingerprint": split["fingerprint"]}


def run_dir(out: Path, name: str, steps: int, seed: int) -> Path:
    return out / f"{name}_steps{steps}_seed{seed}"


def run_one(v: Variant, steps: int, seed: int, n_bins: int, batch_size: int, out: Path,
            data: str, data_dir: Path, force: bool, reevaluate: bool) -> dict:
    out_dir = run_dir(out, v.name, steps, seed)
    search = [data_dir, *sorted((out / "data").glob("*")),
              *sorted((cache_root() / "synthetic").glob(f"{data}-*"))]
    result_path = out_dir / "result.json"
    if result_path.is_file() and not force and reevaluate:
        res = json.loads(result_path.read_text())
        keep = ("variant", "note", "seed", "steps", "train_wall_s", "n_params", "overrides")
        res = {**{k: res[k] for k in keep},
               **evaluate(out_dir / "model.pt", batch_size, search)}
        result_path.write_text(json.dumps(res, indent=2))
        return res
    return run_variant(out_dir, overrides(v, steps, seed, n_bins, data_dir),
                       {"variant": v.name, "note": v.note, "seed": seed, "steps": steps},
                       lambda path: evaluate(path, batch_size, search), force,
                       tag="compare_heads")


def table(results: list[dict]) -> list[str]:
    header = ["variant", "seed", "ball cont. NLL", "flight", "contact", "player cont. NLL",
              "ball floor", "player floor", "ball disc. NLL", "player disc. NLL", "ball top-1",
              "flight top-1", "contact top-1", "player top-1", "ball out-of-range",
              "player out-of-range", "train s", "params"]
    rows = []
    for r in results:
        name = r["variant"] + (f" ({r['note']})" if r.get("note") else "")
        rows.append([
            name, str(r["seed"]), _f(r["cont_nll_ball"]), _f(r["cont_nll_ball_flight"]),
            _f(r["cont_nll_ball_contact"]), _f(r["cont_nll_player"]),
            _f(r["cont_nll_ball"] - r["nll_ball"]), _f(r["cont_nll_player"] - r["nll_player"]),
            _f(r["nll_ball"]), _f(r["nll_player"]), _f(r["acc_ball"]),
            _f(r["acc_ball_flight"]), _f(r["acc_ball_contact"]), _f(r["acc_player"]),
            f"{_f(100 * r['oor_ball'], '.2f')}%", f"{_f(100 * r['oor_player'], '.2f')}%",
            f"{r['train_wall_s']:.0f}", f"{r['n_params']:,}"])
    return md_table(header, rows)


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


def heads_markdown(results: list[dict], steps: list[int], n_bins: int, out: Path,
                   argv: list[str]) -> list[str]:
    """The markdown lines of `docs/figures/compare_heads.md` (without the kept notes)."""
    main_steps = steps[0]
    main = [r for r in results if r["steps"] == main_steps]
    r0 = main[0]
    model_file = run_dir(out, r0["variant"], r0["steps"], r0["seed"]) / "model.pt"
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
        f"`model.ball_centre` and `model.n_bins={n_bins}` (a variant is named "
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
          ((n, uniform_floor(model_file, n)) for n in (n_bins, 61))],
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
    for n in steps[1:]:
        other = [r for r in results if r["steps"] == n]
        text += ["", f"### {n} steps (does the ranking hold with less training?)", "",
                 data_line(other), "", *table(other), "", *summary_lines(other)]
    return text


def compare_heads(steps: list[int], seeds: list[int], seed_variants: int | None, n_bins: int,
                  only: list[str] | None, batch_size: int, out: Path, md: Path, data: str,
                  data_path: Path | None, force: bool, reevaluate: bool,
                  argv: list[str]) -> list[dict]:
    """Freeze the data, train and score every variant (the first `seed_variants` ones also on
    the seeds after the first), write `out/results.json` and (unless `only`) `md`, whose
    hand-written notes below `NOTES_MARKER` are kept; print the table; -> the results."""
    torch.set_num_threads(1)
    if data_path:
        rallies, name = RallyData.load(data_path), Path(data_path).name.split("-")[0]
    else:
        rallies, name = load_rally_data(data_config(data)), data
    data_dir = freeze_data(out / "data" / f"{name}-{data_fingerprint(rallies)}",
                           lambda: rallies)
    variants = [v for v in VARIANTS if only is None or v.name in only]
    runs = []
    for n in steps:
        runs += [(v, n, seeds[0]) for v in variants]
        runs += [(v, n, s) for s in seeds[1:] for v in variants[:seed_variants]]
    results = [run_one(v, n, s, n_bins, batch_size, out, data, data_dir, force, reevaluate)
               for v, n, s in runs]
    (out / "results.json").write_text(json.dumps(results, indent=2))
    if only is None:
        notes = kept_tail(md, NOTES_MARKER) or NOTES_MARKER + "\n"
        write_markdown(md, heads_markdown(results, steps, n_bins, out, argv), "\n" + notes)
    print("\n".join(table(results)))
    return results
