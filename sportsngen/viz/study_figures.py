"""The studies' figures: the top-p sweep's statistics by nucleus, the horizon study's error by
time ahead, the fine-tuning study's statistics by the player's rallies learned from."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from sportsngen.viz.match_figures import agg_pyplot


def plot_top_p_sweep(df: pd.DataFrame, best: float, path: Path) -> None:
    """Each statistic of the sweep by nucleus, the chosen one marked."""
    plt = agg_pyplot()
    cols = [c for c in df.columns if c.startswith(("w_", "d_"))] + ["non_realistic", "score"]
    n = len(cols)
    fig, axes = plt.subplots((n + 3) // 4, 4, figsize=(13, 2.6 * ((n + 3) // 4)))
    for ax, c in zip(np.ravel(axes), cols):
        ax.plot(df["top_p"], df[c], marker="o")
        ax.axvline(best, color="grey", ls="--", lw=0.8)
        ax.set_title(c.replace("w_", "W/IQR ").replace("d_", "|sim-truth| "), fontsize=8)
        ax.set_xlabel("top-p", fontsize=8)
    for ax in np.ravel(axes)[n:]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_horizon(df: pd.DataFrame, path: Path) -> None:
    """The ball's and the players' error by time after the branch, model and linear."""
    plt = agg_pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
    for ax, k in zip(axes, ("ball", "players")):
        ax.plot(df["t_s"], df[f"{k}_rmse_model_m"], label="SportsNGEN rollout")
        ax.plot(df["t_s"], df[f"{k}_rmse_linear_m"], label="linear extrapolation", ls="--")
        ax.set_xlabel("time after branch (s)")
        ax.set_ylabel("RMSE (m)")
        ax.set_title(k)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_finetune_study(table: pd.DataFrame, path: Path,
                        metrics: tuple[tuple[str, str, float], ...]) -> None:
    """Each of `metrics` (column key, label, scale) simulated against its truth, by the
    player's rallies learned from."""
    plt = agg_pyplot()
    fig, axes = plt.subplots(2, 3, figsize=(12, 6.5))
    x = np.arange(len(table))
    for ax, (key, label, f) in zip(axes.ravel(), metrics):
        ax.plot(x, table[f"{key}_sim"] * f, "o-", label="fine-tuned model")
        ax.axhline(table[f"{key}_truth"].iloc[0] * f, color="k", ls="--", label="ground truth")
        ax.set_xticks(x, [str(k) for k in table["k"]])
        ax.set_xlabel("k (player sequences)")
        ax.set_title(label)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("Generic model fine-tuned on k sequences of an unseen player")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
