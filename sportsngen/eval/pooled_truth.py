"""Simulated runs pooled against one large generated truth: the biases one check cannot show
(`scripts/bias_to_truth.py`).

A check's own truth is 3,000 points (about 1,500 a server) and as much a draw as its
simulation: the generator itself, run as a simulator, misses about one statistic in sixty
(`eval.check_noise`). Here the runs (`check_simulation.py --save-sim` folders) are grouped by
matchup and surface, their realistic points pooled into one sample (`check_noise.concat_runs`),
and each group compared with one truth of `truth_points` points of the same matchup
(`generate_matches`, `truth_seed`; cached by players, surface, size, seed and generator
version; 12,000 clay points took 7 minutes on 2 shared cores), with both sides' standard errors
(`gap_noise`). Statistics and tolerances are the checks'; `*` marks a pooled gap outside its
tolerance, `!` one outside it with |z| over 3. The last line sums z squared over the statistics
other than the serve speed (a right simulator: about their number).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from sportsngen.data.tracking import RallyData
from sportsngen.eval.check_noise import (
    CHECK_COLUMNS,
    CHECK_SCALE,
    CHECK_TOLERANCE,
    concat_runs,
    first_serve_speeds,
    format_pooled,
    gap_noise,
)
from sportsngen.sim.assemble import realistic_points
from sportsngen.synth.dataset import GENERATOR_VERSION
from sportsngen.synth.generate import generate_matches

SPEED = "first_serve_kmh_median"
MIN_TRUTH_POINTS = 1000     # the truth is meant to be the larger sample


def matchup(sim: RallyData, where: Path) -> tuple[tuple[str, str], str]:
    """The run's two players (in the order of its first server) and its surface."""
    r = sim.rallies
    surfaces = r["surface"].astype(str).unique()
    if len(surfaces) != 1:
        raise SystemExit(f"{where}: {len(surfaces)} surfaces in one run ({list(surfaces)})")
    first = r.iloc[0]
    players = (str(first["server"]), str(first["receiver"]))
    if set(r["server"].astype(str)) | set(r["receiver"].astype(str)) != set(players):
        raise SystemExit(f"{where}: more than one matchup in one run")
    return players, str(surfaces[0])


def truth_for(players: tuple[str, str], surface: str, n_points: int, seed: int,
              cache: Path) -> RallyData:
    """The large truth of one matchup, generated once and kept in `cache`."""
    key = "_".join(p.replace(" ", "-") for p in sorted(players))
    folder = cache / f"{key}_{surface}_{n_points}_seed{seed}_v{GENERATOR_VERSION}"
    if (folder / "meta.json").is_file():
        return RallyData.load(folder)
    print(f"generating the truth of {' v '.join(players)} on {surface}: {n_points} points",
          flush=True)
    truth = generate_matches([players], surface, n_points, seed=seed, workers=2, progress=True)
    truth.save(folder)
    return truth


def bias_to_truth(sims: list[Path], truth_points: int, truth_seed: int, cache: Path,
                  json_out: Path | None = None) -> dict:
    """The module's comparison of the runs in the folders `sims`, printed (and written to
    `json_out` where given) -> {"rows", "within", "cells", "sum_z2", "n_z"}."""
    if truth_points < MIN_TRUTH_POINTS:
        raise SystemExit(f"--truth-points: at least {MIN_TRUTH_POINTS} (the truth is meant to "
                         "be the larger sample)")
    groups: dict[tuple[tuple[str, str], str], list[RallyData]] = {}
    for folder in sims:
        sim = realistic_points(RallyData.load(folder, validate=False))
        groups.setdefault(matchup(sim, folder), []).append(sim)
    columns = [c for c, _, _ in CHECK_COLUMNS]
    rows, sum_z2, n_z, within, n_cells = [], 0.0, 0, 0, 0
    for (players, surface), runs in groups.items():
        truth = truth_for(players, surface, truth_points, truth_seed, cache)
        pts, values = concat_runs([s.points() for s in runs],
                                  [first_serve_speeds(s, "sim", list(players)) for s in runs])
        values.update(first_serve_speeds(truth, "truth", list(players)))
        noise = gap_noise(pts, truth.points(), list(players), columns, values=values,
                          seed=truth_seed).assign(runs=len(runs), surface=surface)
        print(f"\n{' v '.join(players)} on {surface}: {len(runs)} runs, "
              f"{len(pts)} simulated points against {truth_points} (seed "
              f"{truth_seed}); pooled gap (sim - truth) ± its standard error, z")
        print(format_pooled(noise))
        for r in noise.itertuples():
            n_cells += 1
            within += bool(abs(r.gap) * CHECK_SCALE[r.statistic] <= CHECK_TOLERANCE[r.statistic])
            if r.statistic != SPEED and np.isfinite(r.z):
                sum_z2, n_z = sum_z2 + r.z ** 2, n_z + 1
        rows += noise.to_dict("records")
    print(f"\nwithin tolerance pooled: {within} of {n_cells}; sum of z² over the {n_z} "
          f"statistics other than the serve speed: {sum_z2:.1f}")
    result = {"rows": rows, "within": within, "cells": n_cells, "sum_z2": sum_z2, "n_z": n_z}
    if json_out is not None:
        Path(json_out).write_text(json.dumps(result, indent=1))
    return result
