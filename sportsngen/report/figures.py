"""The serving and rally statistics of a match's two players, beside their real 2011 figures.

This match's figures come from its points table through `sportsngen.eval.stats` (the same code
for real, synthetic and simulated points). The 2011 figures are the committed derived tables:
`synth/data/slam2011_targets.csv` (the generator's calibration targets, every statistic) where
the player is there, else the rates of his bundled serve model
(`baselines/data/serve_models_2011.json`). Both come from Jeff Sackmann / Tennis Abstract's
slam point-by-point data (CC BY-NC-SA 4.0): `SOURCE_2011` is shown wherever they are.
"""

from __future__ import annotations

import math
from functools import lru_cache

import pandas as pd

from sportsngen.baselines.serve_model import bundled_serve_models
from sportsngen.eval.stats import return_stats, serve_stats
from sportsngen.synth.targets import TARGETS_CSV

ATTRIBUTION = "Jeff Sackmann / Tennis Abstract, CC BY-NC-SA 4.0"
SOURCE_2011 = f"2011 US Open + Wimbledon point-by-point data ({ATTRIBUTION})"
# (key, label, unit): "pct" a share shown as a percentage, "kmh" a speed, "n" a count or mean.
STAT_ROWS: tuple[tuple[str, str, str], ...] = (
    ("points_won", "points won", "n"),
    ("first_serve_in", "1st serve in", "pct"),
    ("ace", "aces (of service points)", "pct"),
    ("double_fault", "double faults", "pct"),
    ("first_serve_won", "1st-serve points won", "pct"),
    ("second_serve_won", "2nd-serve points won", "pct"),
    ("serve_points_won", "service points won", "pct"),
    ("return_points_won", "return points won", "pct"),
    ("first_serve_kmh_median", "1st serve, median km/h", "kmh"),
    ("second_serve_kmh_median", "2nd serve, median km/h", "kmh"),
    ("rally_mean", "mean rally length (shots)", "n"),
)


def _clean(v) -> float | None:
    """JSON-friendly: None for NaN / NA."""
    if v is None or v is pd.NA:
        return None
    v = float(v)
    return None if math.isnan(v) else v


def match_figures(points: pd.DataFrame, players: tuple[str, str]) -> dict[str, dict]:
    """Per player: every `STAT_ROWS` statistic of this match (None where unknown)."""
    srv, ret = serve_stats(points), return_stats(points)
    won = points["winner"].value_counts()
    out = {}
    for p in players:
        row = {k: _clean(srv.at[p, k]) if p in srv.index and k in srv.columns else None
               for k, _, _ in STAT_ROWS}
        row["return_points_won"] = _clean(ret.at[p, "return_points_won"]) \
            if p in ret.index else None
        row["points_won"] = float(won.get(p, 0))
        out[p] = row
    return out


@lru_cache(maxsize=1)
def _targets() -> pd.DataFrame:
    return pd.read_csv(TARGETS_CSV, comment="#").set_index("player")


def real_2011_figures(player: str) -> dict | None:
    """`player`'s 2011 slam figures (see the module), or None where neither table knows him."""
    t = _targets()
    if player in t.index:
        row = t.loc[player]
        out = {k: _clean(row[k]) if k in row.index else None for k, _, _ in STAT_ROWS}
        out["points_won"] = None
        return out
    m = bundled_serve_models().get(player)
    if m is None:
        return None
    second = 1.0 - m.first_serve_in
    ace = m.first_serve_in * m.ace_first + second * (1.0 - m.double_fault) * m.ace_second
    return {"first_serve_in": m.first_serve_in, "ace": ace,
            "double_fault": second * m.double_fault, "first_serve_won": m.first_serve_won,
            "second_serve_won": m.second_serve_won, "serve_points_won": m.serve_points_won,
            "return_points_won": _clean(m.return_won),
            "first_serve_kmh_median": _clean(m.first_serve_kmh_median),
            "second_serve_kmh_median": _clean(m.second_serve_kmh_median),
            "rally_mean": None, "points_won": None}
