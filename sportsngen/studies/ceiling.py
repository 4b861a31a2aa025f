"""The checks' ceiling: the generator itself, run as the simulator, against each check's truth
(`scripts/check_ceiling.py`).

For the eight checks of docs/evaluation.md (Federer v Nadal on hard seeds 0, 1, 2, 5; Djokovic
v Murray on clay 0, 2; Williams v Sharapova on hard 0, 2): each truth as `check_simulation.py`
generates it, against `samples` other generator samples of `points` points a server (seeds
10007 + 101 x seed + k), the same statistics and tolerances. Prints, per pair, how many of the
twelve fall within tolerance, how many `eval.check_noise` expected, and the mean square of the
pairs' z-scores (1 where the standard errors are right).
"""

from __future__ import annotations

import numpy as np

from sportsngen.eval import check_noise as cn
from sportsngen.synth.generate import generate_matches

CHECKS = ([("Roger Federer", "Rafael Nadal", "hard", s) for s in (0, 1, 2, 5)]
          + [("Novak Djokovic", "Andy Murray", "clay", s) for s in (0, 2)]
          + [("Serena Williams", "Maria Sharapova", "hard", s) for s in (0, 2)])


def check_ceiling(samples: int, points: int, truth_points: int) -> tuple[np.ndarray, np.ndarray]:
    """Run every check against `samples` generator samples; print each pair and the summary
    -> (checks within tolerance per sample, every pair's z-score)."""
    stats = [c for c, _, _ in cn.CHECK_COLUMNS]
    within, z = np.zeros(samples, dtype=int), []
    for a, b, surface, seed in CHECKS:
        players = [a, b]
        truth = generate_matches([(a, b)], surface, truth_points, seed=seed, workers=2)
        for k in range(samples):
            sample = generate_matches([(a, b)], surface, 2 * points,
                                      seed=10007 + 101 * seed + k, workers=2)
            speeds = {**cn.first_serve_speeds(truth, "truth", players),
                      **cn.first_serve_speeds(sample, "sim", players)}
            noise = cn.gap_noise(sample.points(), truth.points(), players, stats,
                                 values=speeds, seed=k)
            inside = int(sum(abs(r.gap * cn.CHECK_SCALE[r.statistic])
                             <= cn.CHECK_TOLERANCE[r.statistic] for r in noise.itertuples()))
            within[k] += inside
            z += noise["z"].tolist()
            print(f"{a} v {b}, {surface}, seed {seed}, sample {k}: {inside} of {len(noise)} "
                  f"within tolerance (expected "
                  f"{cn.expected_within(noise, cn.CHECK_TOLERANCE, cn.CHECK_SCALE):.2f})",
                  flush=True)
    z = np.asarray(z)
    print(f"\nwithin tolerance over the {len(CHECKS)} checks, each sample: "
          f"{', '.join(str(w) for w in within)} of {12 * len(CHECKS)}; z mean square "
          f"{np.mean(z ** 2):.2f}, |z| > 2: {np.mean(np.abs(z) > 2):.3f}")
    return within, z
