"""The generator against the real Hawk-Eye figures: the matchups of the Hawk-Eye README,
generated, measured with `sportsngen.eval.hawkeye` and compared group by group.

Kept apart from `sportsngen.eval.hawkeye` because it generates (imports the synthetic
generator); `scripts/hawkeye_report.py` is its command line.
"""

from __future__ import annotations

from collections.abc import Sequence

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


def generated_strikes(n_points: int, seed: int,
                      matchups: Sequence[tuple[tuple[str, str], str]] = README_MATCHUPS,
                      progress: bool = False) -> pd.DataFrame:
    """The strikes table of `n_points` generated points of each matchup (matchup k from seed
    `seed` + k), one matchup at a time in this process so only one's tracking is in memory.
    Match ids are prefixed with "<k>-" and rally ids shifted so they stay unique."""
    from sportsngen.synth import generate_matches

    parts, offset = [], 0
    for k, (pair, surface) in enumerate(matchups):
        if progress:
            print(f"[{k + 1}/{len(matchups)}] {pair[0]} v {pair[1]} on {surface}: "
                  f"{n_points} points", flush=True)
        data = generate_matches([tuple(pair)], surface, n_points=n_points, seed=seed + k,
                                progress=progress)
        s = strike_keypoints(data)
        del data
        s["match_id"] = f"{k}-" + s["match_id"]
        s["rally_id"] += offset
        offset = int(s["rally_id"].max()) + 1
        parts.append(s)
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
