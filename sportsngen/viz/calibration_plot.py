"""Reliability diagrams of win probabilities (`eval.calibration`'s tables drawn)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sportsngen.eval.calibration import (
    brier_score,
    expected_calibration_error,
    reliability_table,
)
from sportsngen.viz.match_figures import agg_pyplot


def plot_reliability(preds: dict[str, np.ndarray], outcome, path: str | Path,
                     n_bins: int = 10, title: str = "") -> Path:
    """Reliability diagram (observed frequency against mean prediction per bin, one line per
    predictor) above the histogram of each predictor's predictions."""
    plt = agg_pyplot()

    fig, (ax, hx) = plt.subplots(2, 1, figsize=(5.5, 7), height_ratios=(3, 1.4))
    ax.plot([0, 1], [0, 1], color="grey", ls="--", lw=1, label="perfect")
    for name, p in preds.items():
        t = reliability_table(p, outcome, n_bins)
        ok = t["count"] > 0
        ece = expected_calibration_error(p, outcome, n_bins)
        ax.plot(t.loc[ok, "mean_pred"], t.loc[ok, "observed"], marker="o",
                label=f"{name} (ECE {ece:.3f}, Brier {brier_score(p, outcome):.3f})")
        hx.hist(p, bins=np.linspace(0, 1, n_bins + 1), alpha=0.5, label=name)
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_xlabel("predicted P(server wins the point)")
    ax.set_ylabel("observed frequency")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="upper left")
    hx.set_xlabel("predicted probability")
    hx.set_ylabel("count")
    hx.legend(fontsize=7)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
