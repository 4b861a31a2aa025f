"""The counterfactual figure (the paper's Fig. 16 and 17): the real rally's ball track and the
simulated branches of each option after the chosen shot, on a top view of the court."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from sportsngen.data.tracking import RallyData
from sportsngen.viz.court_plot import draw_court

OPTION_COLOURS = ("tab:orange", "tab:cyan", "tab:pink", "tab:olive", "tab:purple")


def _ball_xy(data: RallyData, rally_id: int) -> np.ndarray:
    f = data.frames[(data.frames["rally_id"] == rally_id) & (data.frames["object"] == "ball")]
    return f.sort_values("frame")[["x", "y"]].to_numpy(float)


def plot_counterfactual(data: RallyData, rally_id: int, table: pd.DataFrame,
                        branches: dict[str, RallyData], branch_frame: int,
                        path: str | Path | None = None, max_branches: int = 12) -> Figure:
    """`table` and `branches` as `sportsngen.sim.whatif.counterfactual(...,
    return_branches=True)` gives them; `branch_frame` the frame (index from the rally start)
    where the branches leave the real rally. Draws up to `max_branches` branch tracks an option
    from the branch point on, the real track in black, and each option's win probability."""
    fig = Figure(figsize=(8.5, 4.8), layout="constrained")
    ax = fig.subplots()
    row = data.rallies[data.rallies["rally_id"] == rally_id].iloc[0]
    draw_court(ax, "top", str(row["surface"]))
    real = _ball_xy(data, rally_id)
    ax.plot(real[:, 0], real[:, 1], color="black", lw=2, label="real rally", zorder=6)
    ax.scatter(*real[min(branch_frame, len(real) - 1)], s=60, color="yellow",
               edgecolors="black", zorder=7, label="branch point")
    for k, (opt, out) in enumerate(branches.items()):
        colour = OPTION_COLOURS[k % len(OPTION_COLOURS)]
        r = table[table["option"] == opt].iloc[0]
        label = (f"{opt}: P(hitter wins) {r['win_probability']:.2f} "
                 f"[{r['ci_low']:.2f}, {r['ci_high']:.2f}], n={int(r['n'])}")
        for j, rid in enumerate(out.rallies["rally_id"].head(max_branches)):
            xy = _ball_xy(out, int(rid))[branch_frame:]
            ax.plot(xy[:, 0], xy[:, 1], color=colour, lw=0.8, alpha=0.7, zorder=5,
                    label=label if j == 0 else None)
    ax.set_title(f"rally {rally_id}: {row['server']} v {row['receiver']} - what if",
                 fontsize=9)
    ax.legend(loc="upper left", fontsize=7)
    if path is not None:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
    return fig
