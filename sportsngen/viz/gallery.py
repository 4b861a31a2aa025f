"""The gallery of `docs/synthetic-data.md`: four generated rallies drawn with
`sportsngen.viz.court_plot.plot_rally` (an ace, a long rally, a net approach, a forced error);
`scripts/render_gallery.py` is the command line."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from sportsngen.data.tracking import RallyData
from sportsngen.errors import ArgumentError
from sportsngen.synth import generate_matches
from sportsngen.viz.court_plot import plot_rally


def gallery_rallies(data: RallyData) -> dict[str, pd.Series]:
    """The rally ids of each kind, first choice first (the longest for the long rally)."""
    r, s = data.rallies, data.shots
    return {
        "ace": r.loc[r["end_reason"] == "ace", "rally_id"],
        "long_rally": r.loc[[r["rally_length"].idxmax()], "rally_id"],
        "net_play": s.loc[s["stroke"].str.contains("volley"), "rally_id"],
        "forced_error": r.loc[(r["end_reason"] == "forced_error") & (r["rally_length"] >= 4),
                              "rally_id"],
    }


def render_gallery(out: Path, n_points: int = 300, seed: int = 4) -> None:
    """Draw the first rally of each kind in `n_points` generated points of Federer v Nadal on
    grass into ``<out>/<kind>.png``; `ArgumentError` where a kind is missing."""
    data = generate_matches([("Roger Federer", "Rafael Nadal")], "grass", n_points, seed=seed)
    kinds = gallery_rallies(data)
    missing = [name for name, ids in kinds.items() if ids.empty]
    if missing:
        raise ArgumentError(f"no {', '.join(missing)} rally in {n_points} points (seed "
                            f"{seed}): try more --points")
    picks = {name: ids.iloc[0] for name, ids in kinds.items()}
    out.mkdir(parents=True, exist_ok=True)
    rallies = data.rallies.set_index("rally_id")
    for name, rid in picks.items():
        row = rallies.loc[rid]
        plot_rally(data, int(rid), out / f"{name}.png")
        print(f"{name}: rally {rid}, {row['rally_length']} shots, {row['end_reason']}")
