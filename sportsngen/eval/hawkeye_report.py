"""The generator against the real Hawk-Eye figures: the matchups of the Hawk-Eye README,
generated, measured with `sportsngen.eval.hawkeye` and compared group by group.

Kept apart from `sportsngen.eval.hawkeye` because it generates (imports the synthetic
generator); `scripts/hawkeye_report.py` is its command line.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import pandas as pd

from sportsngen.eval.hawkeye import compare, hawkeye_stats, load_targets, strike_keypoints

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
