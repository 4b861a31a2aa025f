"""Rally outcome prediction (the paper's Fig. 14 and 15): calibration of the simulator's
P(server wins the point) from random frames of held-out rallies
(`scripts/rally_outcome_study.py`, whose flags are `OutcomeStudy`'s fields).

Held-out rallies: freshly generated synthetic points (a generator seed the training data never
used) of Roger Federer v Rafael Nadal on hard. For each sampled rally, branch points at a few
fixed times after the start (1, 2, 3, 4 and 6 s, those inside the rally; one before the
serve's contact moves to `AFTER_SERVE_FRAMES` after it), `--n` rollouts each
(`sportsngen.sim.whatif.rally_win_probabilities`; with `--chunk-items K` in fixed chunks of K
branch points, which `--workers` processes share: `sportsngen.sim.outcome_pool`, whose results
do not depend on the number of workers); the outcome is the recorded winner. Beside
two baselines: the base rate (the server's share of points won in the generator's ground truth
for this matchup) and the Markov model with per-player serve probabilities (the bundled 2011
serve models, opponent-adjusted: P(server wins | first serve in play) or on a second serve).

Recalibration, judged out of fold: the rallies are split in two halves (alternately, in
sampling order; a rally's branch points share its outcome, so they stay together) and each
half's rollout probabilities are mapped by a calibrator fitted on the other half
(`sportsngen.eval.calibration.cross_fitted`), for both kinds: logistic on the log-odds (two
numbers) and isotonic. Every row of the table is over all branch points. Writes
reliability.png (diagram + histogram), outcome.md, outcome.json and branch_points.csv (every
branch point's rollout share `p`, its count `n` and the outcome) into --out. Beside them the
generator's players' share from each branch point (`--kernel-n` plays, `p_kernel`:
`sportsngen.eval.expert_outcomes`), what the data's players win from there: the rollouts'
gap to it is the model's own error, without the outcomes' luck.
`--save-calibrator` also stores a `--calibrator` map fitted on all branch points in the model
file, where `Simulator.rally_win_probability(..., calibrated=True)` uses it. `--from-points`
reads the branch points an earlier run of the same model wrote instead of rolling out again
(the table and the map only); given several runs' files (other seeds), it pools them, each
file's rallies kept apart, with `--kernel-n 0`. One 200-rally seed's map learns that sample's
luck: fitted on seed 0 it took seed 1's raw ECE 0.043 to 0.088, fitted on seed 1 seed 0's 0.075
to 0.099, so the bundled file's map is fitted on seeds 0 and 1 pooled (docs/evaluation.md,
seventy-fourth part).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from sportsngen.baselines.serve_model import serve_model
from sportsngen.eval.branch_points import (
    pool_branch_points,
    study_branch_points,
    truth_rates,
    with_truth_rates,
)
from sportsngen.eval.calibration import (
    brier_score,
    cross_fitted,
    ece_if_calibrated,
    expected_calibration_error,
    fit_calibrator,
)
from sportsngen.eval.expert_outcomes import kernel_win_shares, paired_reference_gaps
from sportsngen.sim import Simulator
from sportsngen.sim.outcome_pool import pooled_rally_win_probabilities
from sportsngen.sim.simulator import model_path
from sportsngen.studies.tables import write_markdown
from sportsngen.synth.generate import generate_matches
from sportsngen.viz.calibration_plot import plot_reliability

PLAYERS = ("Roger Federer", "Rafael Nadal")


@dataclass
class OutcomeStudy:
    """The study's options (those of `scripts/rally_outcome_study.py`)."""

    model: str | None = None
    rallies: int = 60
    n: int = 32
    seed: int = 0
    threads: int | None = None
    workers: int = 1
    chunk_items: int = 0
    out: Path = Path("docs/figures/outcome")
    calibrator: str = "logistic"
    save_calibrator: bool = False
    kernel_n: int = 64
    from_points: list[Path] | None = None

    def __post_init__(self) -> None:
        if self.workers < 1 or self.chunk_items < 0:
            raise ValueError("--workers must be at least 1 and --chunk-items at least 0")
        if self.from_points is not None and len(self.from_points) > 1 and self.kernel_n > 0:
            raise ValueError("pooled --from-points files come from different held-out rallies: "
                             "give --kernel-n 0")


def rally_outcome_study(opts: OutcomeStudy) -> pd.DataFrame:
    """Branch points (rolled out, or read `from_points`), their references, the table, the
    figure, the files and (with `save_calibrator`) the stored map; -> the branch points."""
    if opts.threads:
        torch.set_num_threads(opts.threads)
    model_file = str(model_path(opts.model))
    Simulator.from_pretrained(model_file)          # fails early on a file it cannot simulate
    truth = generate_matches([PLAYERS], "hard", 3000, seed=10_000 + opts.seed, workers=2)
    held = None                   # the held-out rallies: for new rollouts or the kernel only
    if opts.from_points is None or opts.kernel_n > 0:
        held = generate_matches([PLAYERS], "hard", 4 * opts.rallies, seed=20_000 + opts.seed,
                                workers=1)
    if opts.from_points is not None:
        points = pool_branch_points([pd.read_csv(f) for f in opts.from_points])
        wall = float("nan")
        n_rallies = points["rally_id"].nunique()
    else:
        points, wall, n_rallies = _branch_points(model_file, held, opts)
    if opts.kernel_n > 0:
        points = kernel_win_shares(held, points, n=opts.kernel_n, seed=opts.seed, progress=True)
    base = float((truth.points()["winner"] == truth.points()["server"]).mean())
    points = with_truth_rates(points, truth_rates(truth))
    _report(points, base, model_file, wall, n_rallies, opts)
    return points


def _branch_points(model_file: str, held,
                   opts: OutcomeStudy) -> tuple[pd.DataFrame, float, int]:
    """Branch points of held-out rallies and their rollouts' share of server wins."""
    points = study_branch_points(held, opts.rallies, opts.seed)
    t0 = time.perf_counter()
    res = pooled_rally_win_probabilities(
        model_file, held, list(zip(points["rally_id"], points["frame"])), n=opts.n,
        seed=opts.seed, workers=opts.workers, threads=opts.threads or 1,
        chunk_items=opts.chunk_items)
    points = points.assign(p=res["p"].to_numpy(), n=res["n"].to_numpy())
    return points, time.perf_counter() - t0, opts.rallies


def _report(points: pd.DataFrame, base: float, model_file: str, wall: float, n_rallies: int,
            opts: OutcomeStudy) -> None:
    """The table, the figure, the files and (with --save-calibrator) the stored map."""
    if "receiver" not in points:     # files written before the column: the other player
        points = points.assign(receiver=[PLAYERS[1] if s == PLAYERS[0] else PLAYERS[0]
                                         for s in points["server"]])
    ok = points[points["p"].notna()]
    y, p_model, half = (ok[c].to_numpy() for c in ("server_won", "p", "half"))
    p_markov = np.array([_markov(s, rcv, serve) for s, rcv, serve in
                         zip(ok["server"], ok["receiver"], ok["serve_number"])])
    preds = {"SportsNGEN rollouts": p_model}
    for kind in ("logistic", "isotonic"):
        preds[f"SportsNGEN recalibrated ({kind}, out of fold)"] = cross_fitted(
            kind, p_model, y, half)
    preds |= {"base rate": np.full(len(y), base), "Markov (serve model)": p_markov}
    rows = {name: {"ece": expected_calibration_error(p, y), "brier": brier_score(p, y)}
            for name, p in preds.items()}
    floor = ece_if_calibrated(p_model, ok["n"].to_numpy(), seed=opts.seed)
    shared = ece_if_calibrated(p_model, ok["n"].to_numpy(), seed=opts.seed,
                               groups=ok["rally_id"].to_numpy())
    raw = rows["SportsNGEN rollouts"]["ece"]
    if opts.from_points is not None:
        source = f"branch points read from {', '.join(map(str, opts.from_points))}"
        command = (f"`python scripts/rally_outcome_study.py --from-points "
                   f"{' '.join(map(str, opts.from_points))} --kernel-n {opts.kernel_n}`")
    else:
        source = f"{opts.n} rollouts each, {wall:.0f} s"
        command = (f"`python scripts/rally_outcome_study.py --rallies {opts.rallies} --n "
                   f"{opts.n} --seed {opts.seed} --chunk-items {opts.chunk_items}` "
                   f"({opts.workers} process(es))")
    lines = ["# Rally outcome prediction", "",
             f"{command}: {len(points)} branch points ({len(ok)} with at least one "
             f"realistic decided rollout) of {n_rallies} held-out synthetic rallies "
             f"(Federer v Nadal, hard), {source}. Every row is over all {len(ok)}; a "
             f"recalibrated row maps each half of the rallies by a map fitted on the other.",
             "", "| predictor | ECE | Brier |", "|---|---:|---:|"]
    for name, v in rows.items():
        lines.append(f"| {name} | {v['ece']:.3f} | {v['brier']:.3f} |")
    lines += ["", f"Mean realistic decided rollouts per branch point: "
              f"{points['n'].mean():.1f} of {points['n'].max():.0f}; mean prediction "
              f"{p_model.mean():.3f}, server's share won {y.mean():.3f}. The ECE a perfectly "
              f"calibrated simulator would score with this design (`ece_if_calibrated`: the "
              f"rollouts' shares taken as the truth, each point's rollouts redrawn), mean (90th "
              f"percentile): outcomes drawn apart {floor.mean():.3f} "
              f"({np.percentile(floor, 90):.3f}); a rally's branch points drawing from one "
              f"shared number, as they share its outcome, {shared.mean():.3f} "
              f"({np.percentile(shared, 90):.3f}). Such a simulator scores the raw "
              f"{raw:.3f} or more in {(shared >= raw).mean():.0%} of samples like this one "
              f"(drawn apart: {(floor >= raw).mean():.0%}).",
              *_reference_lines(points), "", "![reliability](reliability.png)"]
    cal = fit_calibrator(opts.calibrator, p_model, y)
    opts.out.mkdir(parents=True, exist_ok=True)
    write_markdown(opts.out / "outcome.md", lines)
    (opts.out / "outcome.json").write_text(json.dumps(
        {"metrics": rows, "n_items": len(points), "n_ok": len(ok), "wall_s": wall,
         "calibrator": cal.to_dict(), "mean_ok_rollouts": float(points["n"].mean()),
         "base_rate": base, "ece_if_calibrated": {"mean": float(floor.mean()),
                                                  "p90": float(np.percentile(floor, 90))},
         "ece_if_calibrated_shared": {"mean": float(shared.mean()),
                                      "p90": float(np.percentile(shared, 90)),
                                      "share_at_or_above_raw": float((shared >= raw).mean())}},
        indent=2))
    if opts.from_points is None or (opts.out / "branch_points.csv").resolve() not in \
            [f.resolve() for f in opts.from_points]:
        points.to_csv(opts.out / "branch_points.csv", index=False)
    print("\n".join(lines))
    plot_reliability(preds, y, opts.out / "reliability.png",
                     title=f"{len(ok)} branch points of {n_rallies} held-out rallies, "
                           f"up to {points['n'].max():.0f} rollouts each")
    if opts.save_calibrator:
        from sportsngen.model.export import update_extra

        path = update_extra(model_file, outcome_calibrator=cal.to_dict())
        print(f"stored the {opts.calibrator} calibrator in {path}")


def _reference_lines(points: pd.DataFrame) -> list[str]:
    """The rollouts beside the truth's rates of the same kinds of branch points and beside the
    generator's players from the same branch points (--kernel-n)."""
    lines = []
    if "decided" in points:
        live = points[points["p"].notna() & ~points["decided"].astype(bool)]
        y = live["server_won"].to_numpy()
        lines += ["", f"{int(points['decided'].astype(bool).sum())} branch points lie at or "
                  f"after the point's end (the tracks run a second past it; their outcome is "
                  f"known at the branch). Without them the rollouts' raw ECE is "
                  f"{expected_calibration_error(live['p'].to_numpy(), y):.3f}, Brier "
                  f"{brier_score(live['p'].to_numpy(), y):.3f} ({len(live)} points)."]
    if "p_truth" in points:
        lines += ["", "**Beside the truth's own rates** (`eval.branch_points.truth_rates`: the "
                  "server's share won from the branch points of the 3,000 base-rate points, by "
                  "server, serve and branch time; a calibrated predictor's mean over a group "
                  "comes to its rate). Over the undecided branch points, weighted as they "
                  "fall (standard errors clustered by rally):", "",
                  "| mean over the branch points | less the truth's rate | se |",
                  "|---|---:|---:|"]
        for name, col in (("rollouts", "p"), ("recorded outcomes", "server_won"),
                          ("generator's players", "p_kernel")):
            if col in points:
                g = paired_reference_gaps(points, pred=col, reference="p_truth").loc["all"]
                lines.append(f"| {name} | {g['gap']:+.3f} | {g['se']:.3f} |")
        rated = points[points["p"].notna() & points["p_truth"].notna()]
        ours, theirs = _eces_beside(rated, "p_truth")
        lines += ["", f"The truth's rates as a predictor, right on average by construction "
                  f"but blind to the rally's state, score ECE {theirs:.3f} on these "
                  f"{len(rated)} points (the rollouts {ours:.3f}): how far this sample's "
                  f"outcomes stray from their rates, whatever the model."]
    if "p_kernel" not in points:
        return lines
    both = points[points["p"].notna() & points["p_kernel"].notna()]
    live = both[~both["decided"].astype(bool)]
    y = both["server_won"].to_numpy()
    ours, theirs = _eces_beside(both, "p_kernel")
    lines += ["", f"**Beside the generator's players** (`sportsngen.eval.expert_outcomes`: "
             f"the kernel played on from each branch point's hand-over state, its plays still "
             f"going at the branch frame; a branch frame after the point's end is decided). "
             f"On the {len(both)} branch points it answers ({int(both['decided'].sum())} "
             f"decided): ECE / Brier of the rollouts {ours:.3f} / "
             f"{brier_score(both['p'].to_numpy(), y):.3f}, of the generator's players "
             f"{theirs:.3f} / "
             f"{brier_score(both['p_kernel'].to_numpy(), y):.3f} (a calibrated predictor on "
             f"this sample, less sharp). Rollouts less the generator's players on the "
             f"{len(live)} undecided points (standard error clustered by rally):", "",
             "| branch points | n | rollouts | generator's players | outcomes | gap | se |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    tables = [paired_reference_gaps(live)]
    for by in ("branch_s", ["server", "serve_number"]):
        tables.append(paired_reference_gaps(live, by=by))
    for t in tables:
        for key, r in t.iterrows():
            name = ", ".join(map(str, key)) if isinstance(key, tuple) else str(key)
            lines.append(f"| {name} | {int(r['n'])} | {r['pred']:.3f} | {r['reference']:.3f} "
                         f"| {r['outcome']:.3f} | {r['gap']:+.3f} | {r['se']:.3f} |")
    return lines


def _eces_beside(rows: pd.DataFrame, reference: str) -> tuple[float, float]:
    """ECE of the rollouts and of a reference predictor column on the same rows."""
    y = rows["server_won"].to_numpy()
    return (expected_calibration_error(rows["p"].to_numpy(), y),
            expected_calibration_error(rows[reference].to_numpy(), y))


def _markov(server: str, receiver: str, serve_number: int) -> float:
    """P(server wins | his serve in play) of the opponent-adjusted 2011 serve models."""
    m = serve_model(server).adjusted_against(serve_model(receiver))
    return m.first_serve_won if serve_number == 1 else m.second_serve_won


