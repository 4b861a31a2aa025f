"""docs/evaluation.md: SportsNGEN against the shot-cycle baseline and the ground truth
(`scripts/evaluation_report.py`).

For four matchups on hard (Federer v Nadal, Djokovic v Federer, Nadal v Djokovic, S. Williams v
Sharapova): the generator's ground truth (`--truth-points` points per matchup), the SportsNGEN
simulator (`--points` service points of each player against the other) and the Vid2Player-style
shot-cycle model fitted on that ground truth (`sportsngen.baselines.shot_cycle`, the same number
of points, scored as matches). Every engine is compared with the ground truth by the same code
(`sportsngen.eval.physical.compare_data`): realism, serving statistics, speeds from the ball
tracks, bounce speed ratio, rally lengths. Also writes the full report of SportsNGEN against the
ground truth for Federer v Nadal (with the real 2011 figures where the shared data is present)
into docs/figures/evaluation/, and the SportsNGEN rallies of all four matchups into
outputs/eval/sportsngen_sim (a RallyData folder for scripts/render_style_graphs.py --simulated).
"""


from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from sportsngen.baselines.shot_cycle import fit_shot_cycle
from sportsngen.baselines.shot_cycle_sim import simulate_points as shot_cycle_points
from sportsngen.data.tracking import RallyData
from sportsngen.eval.physical import compare_data
from sportsngen.eval.report import load_real_points, write_report
from sportsngen.sim import Simulator
from sportsngen.studies.tables import kept_tail, write_markdown
from sportsngen.synth.generate import generate_matches

PROSE_MARKER = "## What this says about the bundled model"
MATCHUPS = [("Roger Federer", "Rafael Nadal"), ("Novak Djokovic", "Roger Federer"),
            ("Rafael Nadal", "Novak Djokovic"), ("Serena Williams", "Maria Sharapova")]
ROWS = [  # (section, metric, statistic, label, scale)
    ("realism", "non_realistic_share", "value", "non-realistic rallies %", 100),
    ("serve", "first_serve_in", "value", "1st serve in %", 100),
    ("serve", "ace", "value", "aces %", 100),
    ("serve", "double_fault", "value", "double faults %", 100),
    ("serve", "serve_points_won", "value", "serve points won %", 100),
    ("serve", "rally_mean", "value", "mean rally length (shots)", 1),
    ("physical", "toss_contact_height_m", "median", "serve contact height m (median)", 1),
    ("physical", "first_serve_kmh", "median", "1st serve km/h (median)", 1),
    ("physical", "first_serve_kmh", "wasserstein", "1st serve km/h (W1 to truth)", 1),
    ("physical", "second_serve_kmh", "median", "2nd serve km/h (median)", 1),
    ("physical", "return_kmh", "median", "return km/h (median)", 1),
    ("physical", "groundstroke_kmh", "median", "groundstroke km/h (median)", 1),
    ("physical", "groundstroke_kmh", "wasserstein", "groundstroke km/h (W1 to truth)", 1),
    ("bounce", "bounce_speed_ratio", "median", "bounce speed ratio (median)", 1),
]


def _value(cmp: pd.DataFrame, section, metric, statistic, col) -> float:
    group = "hard" if section == "bounce" else "all"     # bounce ratios are by surface
    c = cmp[(cmp["group"] == group) & (cmp["section"] == section) & (cmp["metric"] == metric)
            & (cmp["statistic"] == statistic)]
    if not len(c):
        return float("nan")
    v = c[col].iat[0]
    if statistic == "wasserstein":      # the distance sits in whichever column is filled
        v = np.nanmax(c[["sim", "ref"]].to_numpy(float))
    return float(v)


def evaluation_report(model: str | None, points: int, truth_points: int, seed: int,
                      threads: int | None, out: Path) -> list[str]:
    """Simulate, fit and compare the four matchups; write `out/evaluation.md` (its
    hand-written reading from `PROSE_MARKER` on kept), the comparison tables, the full
    Federer v Nadal report and the SportsNGEN rallies; -> the markdown table's lines."""
    if threads:
        torch.set_num_threads(threads)
    sim = Simulator.from_pretrained(model)
    truths, ours, baseline, timing = [], [], [], {"sportsngen": 0.0, "shot_cycle": 0.0}
    for m, (a, b) in enumerate(MATCHUPS):
        truth = generate_matches([(a, b)], "hard", truth_points, seed=50_000 + m,
                                 workers=2)
        truths.append(truth)
        t0 = time.perf_counter()
        ours.append(sim.simulate_both_serving(a, b, "hard", points, seed=seed + 2 * m))
        timing["sportsngen"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        cycle = fit_shot_cycle(truth)
        baseline.append(shot_cycle_points(cycle, a, b, "hard", 2 * points,
                                          seed=seed + m))
        timing["shot_cycle"] += time.perf_counter() - t0
        print(f"{a} v {b}: done", flush=True)
    truth_all, ours_all, base_all = (RallyData.concat(parts, renumber=True)
                                     for parts in (truths, ours, baseline))
    cmp_ours = compare_data(ours_all, truth_all)
    cmp_base = compare_data(base_all, truth_all)
    lines = ["# Evaluation: SportsNGEN, the shot-cycle baseline and the ground truth", "",
             f"Written by `python scripts/evaluation_report.py --points {points} "
             f"--truth-points {truth_points} --seed {seed}`. Matchups (hard): "
             + "; ".join(f"{a} v {b}" for a, b in MATCHUPS) + ". Ground truth: the synthetic "
             f"generator, {truth_points} points a matchup. SportsNGEN: the bundled model, "
             f"{points} service points of each player a matchup (first serves, second "
             "serves after faults; non-realistic rallies excluded from the statistics). "
             "Shot-cycle: fitted on each matchup's ground truth, "
             f"{2 * points} points a matchup. All figures pooled over the four matchups, "
             "all from `sportsngen.eval.physical.compare_data`; speeds from the ball tracks "
             "(one to two frame times after the contact) for every engine.", "",
             "| metric | ground truth | SportsNGEN | shot-cycle |", "|---|---:|---:|---:|"]
    for section, metric, stat, label, scale in ROWS:
        digits = 1 if (scale != 1 or "km/h" in label) else 2
        cells = []
        for cmp, col in ((cmp_ours, "ref"), (cmp_ours, "sim"), (cmp_base, "sim")):
            if stat == "wasserstein" and col == "ref":
                cells.append("-")           # a distance to the truth itself
                continue
            cells.append(f"{_value(cmp, section, metric, stat, col) * scale:.{digits}f}")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    lines += ["", f"Simulation time (this machine): SportsNGEN {timing['sportsngen']:.0f} s, "
              f"shot-cycle {timing['shot_cycle']:.0f} s (fitting included).", "",
              "Full SportsNGEN report for Federer v Nadal (figures, every statistic, the real "
              "2011 column): [figures/evaluation/report.md](figures/evaluation/report.md)."]
    doc = out / "evaluation.md"
    # The hand-written reading of the figures (from PROSE_MARKER on) survives a re-run.
    prose = kept_tail(doc, PROSE_MARKER)
    write_markdown(doc, lines, "\n" + prose if prose else "")
    cmp_ours.to_csv(out / "figures" / "evaluation_sportsngen.csv", index=False)
    cmp_base.to_csv(out / "figures" / "evaluation_shot_cycle.csv", index=False)
    try:
        real = load_real_points(list(MATCHUPS[0]))
    except Exception as exc:   # no shared data on this machine: the report goes without it
        print(f"no real 2011 figures: {exc}")
        real = None
    write_report(ours[0], truths[0], out / "figures" / "evaluation", real_points=real)
    ours_all.save(Path("outputs/eval/sportsngen_sim"))
    print("\n".join(lines))
    return lines
