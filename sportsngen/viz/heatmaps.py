"""Shot placement and recovery heatmaps per player (Vid2Player's Fig. 10 and 11).

Everything is shown in the player's frame (`shot_cycle_table`): he plays from the left baseline
(x = -11.885 m) toward the right, so his right-hand side is the bottom of the picture (-y).
Placements are first bounces of his forehands or backhands (volleys included, by side);
recoveries are where he stood when the opponent next hit. Densities are Gaussian KDEs with
leave-one-out bandwidths (`shot_cycle_kde`) on a 0.25 m grid, drawn over `draw_court`, blank
below 5 % of the peak; the points themselves are dots.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from sportsngen.baselines.shot_cycle_kde import fit_kde
from sportsngen.baselines.shot_cycle_table import shot_table
from sportsngen.data.tracking import RallyData
from sportsngen.tennis.court import BASELINE_X_M, DOUBLES_HALF_WIDTH_M
from sportsngen.viz.court_plot import draw_court

GRID_STEP_M = 0.25
SHOW_ABOVE = 0.05
SIDES = {"forehand": ("forehand", "forehand_volley", "overhead"),
         "backhand": ("backhand", "backhand_volley")}


def _table(data: RallyData | pd.DataFrame) -> pd.DataFrame:
    return data if isinstance(data, pd.DataFrame) else shot_table(data)


def _mine(table: pd.DataFrame, player: str, opponent: str | None) -> pd.DataFrame:
    t = table[table["hitter"] == player]
    if opponent is not None:
        t = t[t["opponent"] == opponent]
    if t.empty:
        raise ValueError(f"no shots of {player!r}" + (f" against {opponent!r}" if opponent
                                                       else ""))
    return t


def placements(data: RallyData | pd.DataFrame, player: str, side: str = "forehand",
               opponent: str | None = None) -> np.ndarray:
    """(n, 2) first bounces of the player's rally shots on one side, in his frame."""
    if side not in SIDES:
        raise ValueError(f"side must be one of {list(SIDES)}, got {side!r}")
    t = _mine(_table(data), player, opponent)
    t = t[t["stroke"].isin(SIDES[side])]
    p = t[["place_x", "place_y"]].to_numpy(float)
    return p[np.isfinite(p).all(axis=1)]


def recoveries(data: RallyData | pd.DataFrame, player: str,
               opponent: str | None = None) -> np.ndarray:
    """(n, 2) recovery positions of the player (after rally shots and serves), in his frame."""
    t = _mine(_table(data), player, opponent)
    p = t[["recovery_x", "recovery_y"]].to_numpy(float)
    return p[np.isfinite(p).all(axis=1)]


def density_grid(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x grid, y grid, density (ny, nx)) of a KDE of `points` over the court area."""
    gx = np.arange(-BASELINE_X_M - 4.0, BASELINE_X_M + 4.0 + 1e-9, GRID_STEP_M)
    gy = np.arange(-DOUBLES_HALF_WIDTH_M - 2.5, DOUBLES_HALF_WIDTH_M + 2.5 + 1e-9, GRID_STEP_M)
    xx, yy = np.meshgrid(gx, gy)
    if len(points) == 0:
        return gx, gy, np.zeros_like(xx)
    kde = fit_kde(points, min_std=0.1)
    return gx, gy, kde.pdf(np.column_stack([xx.ravel(), yy.ravel()])).reshape(xx.shape)


def draw_heatmap(ax, points: np.ndarray, title: str, surface: str = "hard",
                 cmap: str = "magma") -> None:
    """Court, KDE heatmap and dots of `points` on `ax`."""
    draw_court(ax, "top", surface)
    gx, gy, dens = density_grid(points)
    if dens.max() > 0:
        shown = np.ma.masked_less(dens, SHOW_ABOVE * dens.max())
        ax.imshow(shown, extent=(gx[0], gx[-1], gy[0], gy[-1]), origin="lower", cmap=cmap,
                  alpha=0.8, zorder=0.5, aspect="auto")  # under the court lines
    if len(points):
        ax.scatter(points[:, 0], points[:, 1], s=3, c="white", alpha=0.5, zorder=4, lw=0)
    ax.set_aspect("equal")
    ax.set_title(f"{title} (n={len(points)})", fontsize=9)


def plot_player_heatmaps(data: RallyData | pd.DataFrame, player: str,
                         opponent: str | None = None, path: str | Path | None = None,
                         surface: str = "hard", dpi: int = 80) -> Figure:
    """Forehand placement, backhand placement and recovery heatmaps of one player (against one
    opponent if given) side by side; saved to `path` if given."""
    table = _table(data)
    fig = Figure(figsize=(13.5, 2.9), layout="constrained")
    axes = fig.subplots(1, 3)
    vs = f" vs {opponent}" if opponent else ""
    for ax, side in zip(axes[:2], SIDES):
        draw_heatmap(ax, placements(table, player, side, opponent),
                     f"{player}{vs}: {side} placement", surface)
    draw_heatmap(axes[2], recoveries(table, player, opponent), f"{player}{vs}: recovery",
                 surface, cmap="viridis")
    if path is not None:
        fig.savefig(path, dpi=dpi)
    return fig
