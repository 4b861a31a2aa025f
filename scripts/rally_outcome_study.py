"""Rally outcome prediction (the paper's Fig. 14 and 15): calibration of the simulator's
P(server wins the point) from random frames of held-out rallies.

    .venv/bin/python scripts/rally_outcome_study.py [--model PATH] [--rallies 60] [--n 32]
        [--seed 0] [--workers 1 --threads 2] [--out docs/figures/outcome]
        [--calibrator logistic|isotonic] [--save-calibrator] [--from-points CSV [CSV ...]]
        [--kernel-n 64]

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

import argparse
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from sportsngen.eval.branch_points import (
    pool_branch_points,
    study_branch_points,
    truth_rates,
    with_truth_rates,
)
from sportsngen.eval.calibration import (
    CALIBRATORS,
    brier_score,
    cross_fitted,
    ece_if_calibrated,
    expected_calibration_error,
    fit_calibrator,
    plot_reliability,
)
from sportsngen.eval.expert_outcomes import kernel_win_shares, paired_reference_gaps
from sportsngen.sim import Simulator
from sportsngen.sim.cli import serve_model
from sportsngen.sim.outcome_pool import pooled_rally_win_probabilities
from sportsngen.sim.simulator import model_path
from sportsngen.synth.generate import generate_matches

PLAYERS = ("Roger Federer", "Rafael Nadal")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--rallies", type=int, default=60)
    ap.add_argument("--n", type=int, default=32)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=None, help="threads a process")
    ap.add_argument("--workers", type=int, default=1,
                    help="processes rolling the branch points out (each loads the model)")
    ap.add_argument("--chunk-items", type=int, default=0,
                    help="branch points a chunk (one seed each; the results depend on it); "
                         "0: all in one call, as before there were workers")
    ap.add_argument("--out", type=Path, default=Path("docs/figures/outcome"))
    ap.add_argument("--calibrator", choices=sorted(CALIBRATORS), default="logistic",
                    help="the map --save-calibrator stores (fitted on all branch points)")
    ap.add_argument("--save-calibrator", action="store_true",
                    help="store the --calibrator map in the model file (outcome_calibrator)")
    ap.add_argument("--kernel-n", type=int, default=64,
                    help="plays of the generator's players from each branch point's hand-over "
                         "(sportsngen.eval.expert_outcomes), the reference without the "
                         "outcomes' luck; 0: none")
    ap.add_argument("--from-points", type=Path, nargs="+", default=None,
                    help="branch_points.csv of earlier runs of this model (several: pooled, "
                         "with --kernel-n 0): no rollouts")
    args = ap.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    if args.workers < 1 or args.chunk_items < 0:
        ap.error("--workers must be at least 1 and --chunk-items at least 0")
    if args.from_points is not None and len(args.from_points) > 1 and args.kernel_n > 0:
        ap.error("pooled --from-points files come from different held-out rallies: give "
                 "--kernel-n 0")
    model_file = str(model_path(args.model))
    Simulator.from_pretrained(model_file)          # fails early on a file it cannot simulate
    truth = generate_matches([PLAYERS], "hard", 3000, seed=10_000 + args.seed, workers=2)
    held = None                   # the held-out rallies: for new rollouts or the kernel only
    if args.from_points is None or args.kernel_n > 0:
        held = generate_matches([PLAYERS], "hard", 4 * args.rallies, seed=20_000 + args.seed,
                                workers=1)
    if args.from_points is not None:
        points = pool_branch_points([pd.read_csv(f) for f in args.from_points])
        wall = float("nan")
        n_rallies = points["rally_id"].nunique()
    else:
        points, wall, n_rallies = _branch_points(model_file, held, args)
    if args.kernel_n > 0:
        points = kernel_win_shares(held, points, n=args.kernel_n, seed=args.seed, progress=True)
    base = float((truth.points()["winner"] == truth.points()["server"]).mean())
    points = with_truth_rates(points, truth_rates(truth))
    _report(points, base, model_file, wall, n_rallies, args)


def _branch_points(model_file: str, held, args) -> tuple[pd.DataFrame, float, int]:
    """Branch points of held-out rallies and their rollouts' share of server wins."""
    points = study_branch_points(held, args.rallies, args.seed)
    t0 = time.perf_counter()
    res = pooled_rally_win_probabilities(
        model_file, held, list(zip(points["rally_id"], points["frame"])), n=args.n,
        seed=args.seed, workers=args.workers, threads=args.threads or 1,
        chunk_items=args.chunk_items)
    points = points.assign(p=res["p"].to_numpy(), n=res["n"].to_numpy())
    return points, time.perf_counter() - t0, args.rallies


def _report(points: pd.DataFrame, base: float, model_file: str, wall: float, n_rallies: int,
            args) -> None:
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
    floor = ece_if_calibrated(p_model, ok["n"].to_numpy(), seed=args.seed)
    shared = ece_if_calibrated(p_model, ok["n"].to_numpy(), seed=args.seed,
                               groups=ok["rally_id"].to_numpy())
    raw = rows["SportsNGEN rollouts"]["ece"]
    if args.from_points is not None:
        source = f"branch points read from {', '.join(map(str, args.from_points))}"
        command = (f"`python scripts/rally_outcome_study.py --from-points "
                   f"{' '.join(map(str, args.from_points))} --kernel-n {args.kernel_n}`")
    else:
        source = f"{args.n} rollouts each, {wall:.0f} s"
        command = (f"`python scripts/rally_outcome_study.py --rallies {args.rallies} --n "
                   f"{args.n} --seed {args.seed} --chunk-items {args.chunk_items}` "
                   f"({args.workers} process(es))")
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
    cal = fit_calibrator(args.calibrator, p_model, y)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "outcome.md").write_text("\n".join(lines) + "\n")
    (args.out / "outcome.json").write_text(json.dumps(
        {"metrics": rows, "n_items": len(points), "n_ok": len(ok), "wall_s": wall,
         "calibrator": cal.to_dict(), "mean_ok_rollouts": float(points["n"].mean()),
         "base_rate": base, "ece_if_calibrated": {"mean": float(floor.mean()),
                                                  "p90": float(np.percentile(floor, 90))},
         "ece_if_calibrated_shared": {"mean": float(shared.mean()),
                                      "p90": float(np.percentile(shared, 90)),
                                      "share_at_or_above_raw": float((shared >= raw).mean())}},
        indent=2))
    if args.from_points is None or (args.out / "branch_points.csv").resolve() not in \
            [f.resolve() for f in args.from_points]:
        points.to_csv(args.out / "branch_points.csv", index=False)
    print("\n".join(lines))
    plot_reliability(preds, y, args.out / "reliability.png",
                     title=f"{len(ok)} branch points of {n_rallies} held-out rallies, "
                           f"up to {points['n'].max():.0f} rollouts each")
    if args.save_calibrator:
        from sportsngen.model.export import update_extra

        path = update_extra(model_file, outcome_calibrator=cal.to_dict())
        print(f"stored the {args.calibrator} calibrator in {path}")


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


if __name__ == "__main__":
    main()
