"""The generator against the real Hawk-Eye figures: the matchups of the Hawk-Eye README,
generated, measured with `sportsngen.eval.hawkeye` and compared group by group.

Kept apart from `sportsngen.eval.hawkeye` because it generates (imports the synthetic
generator); `scripts/hawkeye_report.py` is its command line.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd

from sportsngen.data.paths import HAWKEYE_TARGETS_MISSING, hawkeye_targets_path
from sportsngen.eval.hawkeye import (
    compare,
    comparison_markdown,
    hawkeye_stats,
    keypoint_strikes,
    load_targets,
    strike_keypoints,
)

# (players, surface) generated, and the (player or tour, surface) groups compared: those of
# the README with enough real data (Murray and Sharapova have one real match each).
README_MATCHUPS: tuple[tuple[tuple[str, str], str], ...] = (
    (("Roger Federer", "Rafael Nadal"), "hard"),
    (("Roger Federer", "Rafael Nadal"), "clay"),
    (("Novak Djokovic", "Andy Murray"), "hard"),
    (("Novak Djokovic", "Andy Murray"), "clay"),
    (("Serena Williams", "Maria Sharapova"), "hard"),
)
README_GROUPS: tuple[tuple[str, str], ...] = (
    ("Roger Federer", "hard"), ("Roger Federer", "clay"), ("Rafael Nadal", "hard"),
    ("Rafael Nadal", "clay"), ("Novak Djokovic", "hard"), ("Novak Djokovic", "clay"),
    ("Serena Williams", "hard"), ("ATP", "hard"), ("ATP", "clay"), ("WTA", "hard"),
)

# The keypoint files' names of the README's players -> the names of the figures and profiles.
FILE_NAMES = {"R.FEDERER": "Roger Federer", "R.NADAL": "Rafael Nadal",
              "N.DJOKOVIC": "Novak Djokovic", "A.MURRAY": "Andy Murray",
              "S.WILLIAMS": "Serena Williams", "M.SHARAPOVA": "Maria Sharapova"}


def _matchup_strikes(job: tuple) -> pd.DataFrame:
    """Strikes of one generated matchup, ids made unique by the matchup's index k."""
    from sportsngen.synth import generate_matches

    k, pair, surface, n_points, seed, progress = job
    data = generate_matches([pair], surface, n_points=n_points, seed=seed, progress=progress)
    s = strike_keypoints(data)
    s["match_id"] = f"{k}-" + s["match_id"].astype(str)
    s["rally_id"] += k * 10_000_000
    return s


def generated_strikes(n_points: int, seed: int,
                      matchups: Sequence[tuple[tuple[str, str], str]] = README_MATCHUPS,
                      profiles: Mapping[str, object] | None = None, workers: int = 1,
                      progress: bool = False) -> pd.DataFrame:
    """The strikes table of `n_points` generated points of each matchup (matchup k from seed
    `seed` + k): one matchup a process at a time, so only its tracking is in memory. Players
    by name; `profiles` (name -> `PlayerProfile`) plays other profiles under those names (a
    calibration's candidates). Match ids are prefixed "<k>-" and rally ids offset by k * 1e7
    so they stay unique."""
    jobs = []
    for k, ((a, b), surface) in enumerate(matchups):
        pair = (a, b) if profiles is None else (profiles.get(a, a), profiles.get(b, b))
        if progress:
            print(f"[{k + 1}/{len(matchups)}] {a} v {b} on {surface}: {n_points} points",
                  flush=True)
        jobs.append((k, pair, surface, n_points, seed + k, progress and workers == 1))
    if workers > 1:
        from sportsngen.workers import pool_context

        with pool_context(__name__).Pool(min(workers, len(jobs))) as pool:
            parts = pool.map(_matchup_strikes, jobs)
    else:
        parts = [_matchup_strikes(j) for j in jobs]
    return pd.concat(parts, ignore_index=True)


def hawkeye_report(strikes: pd.DataFrame, targets: pd.DataFrame | None = None,
                   groups: Sequence[tuple[str, str]] = README_GROUPS
                   ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(statistics of every player and tour in `strikes`, their comparison with `targets`
    (default: the real figures) for `groups`)."""
    stats = hawkeye_stats(strikes)
    targets = load_targets() if targets is None else targets
    return stats, compare(stats, targets, groups)


def outside_tolerance(cmp: pd.DataFrame) -> pd.DataFrame:
    """The rows of a comparison outside their tolerance, with the excess over it."""
    out = cmp[cmp["within"].eq(False)].copy()
    out["excess"] = out["difference"].abs() - out["tolerance"]
    return out


def write_hawkeye_report(out: Path, n_points: int = 2000, seed: int = 0,
                         keypoints: Path | None = None, title: str | None = None,
                         before: Path | None = None) -> int:
    """Measure `n_points` generated points a README matchup (matchup k from seed + k), or the
    real keypoint files under `keypoints`, against the real figures: write ``<out>.md`` (the
    table, "generated / real", bold outside tolerance; `before`, an earlier run's csv, adds its
    figures in brackets) and ``<out>.csv`` (`compare`'s columns), print the statistics outside
    tolerance. -> 0, or 2 (said on stderr) without the real figures."""
    if hawkeye_targets_path() is None:
        print(HAWKEYE_TARGETS_MISSING, file=sys.stderr)
        return 2
    if keypoints is not None:
        from sportsngen.data.keypoints import read_keypoints

        strikes = keypoint_strikes(read_keypoints(keypoints, player_names=FILE_NAMES,
                                                  progress=True))
        source = f"real keypoint files under {keypoints}"
    else:
        strikes = generated_strikes(n_points, seed, progress=True)
        source = f"{n_points} generated points per matchup, seed {seed}"
    stats, cmp = hawkeye_report(strikes, groups=README_GROUPS)
    title = title or f"Hawk-Eye statistics: {source} / real"
    out.parent.mkdir(parents=True, exist_ok=True)
    cmp.to_csv(out.with_suffix(".csv"), index=False)
    earlier = pd.read_csv(before) if before is not None else None
    out.with_suffix(".md").write_text(comparison_markdown(cmp, title, before=earlier))
    off = outside_tolerance(cmp)
    print(f"{len(off)} of {int(cmp['within'].notna().sum())} comparisons outside tolerance:")
    for _, r in off.iterrows():
        print(f"  {r['player']:>15} {r['surface']:<5} {r['statistic']:<32} "
              f"gen {r['generated']:8.3f}  real {r['real']:8.3f}  diff {r['difference']:+.3f} "
              f"(tol {r['tolerance']:g}, excess {r['excess']:.3f})")
    print(f"wrote {out.with_suffix('.md')} and {out.with_suffix('.csv')}")
    return 0
