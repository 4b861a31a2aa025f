"""The figures `simulate.py` writes beside a match: the Markov engine's win-probability path, the
learned engine's longest rallies and an animation of the longest."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def agg_pyplot():
    """pyplot on the Agg backend (files, no display)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_win_probability(probs: np.ndarray, names: tuple[str, str], title: str,
                         path: Path) -> None:
    """Player 1's win probability before each point, as a line against 0.5, saved to `path`."""
    plt = agg_pyplot()
    fig, ax = plt.subplots(figsize=(9, 3.5))
    ax.plot(np.arange(len(probs)), probs, color="tab:blue", lw=1.5)
    ax.axhline(0.5, color="grey", lw=0.8, ls="--")
    ax.set_ylim(0, 1)
    ax.set_xlabel("point")
    ax.set_ylabel(f"P({names[0]} wins)")
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def rally_figures(res, out_dir: Path, n_plots: int = 3, max_gif_frames: int = 150) -> None:
    """Plots of the longest rallies of a simulated match (`MatchResult`) and an animation of the
    longest one, of at most `max_gif_frames` frames (so that a long rally does not take minutes
    to render; 0: no animation)."""
    plt = agg_pyplot()
    from sportsngen.viz.court_plot import animate_rally, plot_rally

    r = res.rallies.rallies.sort_values("rally_length", ascending=False, kind="stable")
    for k, rid in enumerate(r["rally_id"].head(n_plots)):
        fig = plot_rally(res.rallies, int(rid), out_dir / f"rally_{k + 1}.png")
        plt.close(fig)
    if len(r) and max_gif_frames > 0:
        rid = int(r["rally_id"].iat[0])
        n = int((res.rallies.frames["rally_id"] == rid).sum() // 3)
        every = max(2, -(-n // max_gif_frames))
        animate_rally(res.rallies, rid, out_dir / "point.gif", every=every)
