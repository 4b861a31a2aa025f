"""Style graph drawings (matplotlib `Figure`, no pyplot, safe on the Agg backend).

Nodes sit at the 2-D PCA layout of their centroids, sized by the number of shot cycles starting
there; an arrow joins two nodes with a width by the number of cycles making that transition
with a repeated action (edges taken once are left out, as in the skill index); a transition
back to the same node is a ring around it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import FancyArrowPatch

from sportsngen.eval.style_graph import StyleGraph

NODE_AREA_PT2 = 900.0     # area of the biggest node
EDGE_WIDTH_PT = 8.0       # width of the most frequent transition


def transitions(graph: StyleGraph) -> dict[tuple[int, int], int]:
    """Cycles per (src, dst) over the edges taken at least twice."""
    e = graph.edges[graph.edges["count"] >= 2]
    return {(int(s), int(d)): int(c) for (s, d), c in e.groupby(["src", "dst"])["count"].sum()
            .items()}


def plot_style_graph(ax, graph: StyleGraph, title: str | None = None,
                     layout: np.ndarray | None = None, colour: str = "tab:blue") -> None:
    """Draw `graph` on `ax` (at `layout` if given, e.g. a reference graph's, else its own)."""
    xy = graph.layout() if layout is None else np.asarray(layout, dtype=float)
    trans = transitions(graph)
    top = max(trans.values(), default=1)
    span = float(np.ptp(xy, axis=0).max()) if len(xy) > 1 else 1.0
    span = span if span > 0 else 1.0
    for (s, d), n in sorted(trans.items()):
        w = 0.5 + EDGE_WIDTH_PT * n / top
        if s == d:
            ax.scatter(*xy[s], s=NODE_AREA_PT2 * 1.8, facecolors="none", edgecolors=colour,
                       linewidths=w * 0.5, alpha=0.5, zorder=1)
            continue
        ax.add_patch(FancyArrowPatch(xy[s], xy[d], arrowstyle="-|>", mutation_scale=8 + w,
                                     lw=w, color=colour, alpha=0.45, zorder=1,
                                     connectionstyle="arc3,rad=0.15", shrinkA=12, shrinkB=12))
    size = NODE_AREA_PT2 * graph.node_counts / max(graph.node_counts.max(), 1)
    ax.scatter(xy[:, 0], xy[:, 1], s=np.maximum(size, 20.0), c="white", edgecolors="0.2",
               zorder=2)
    for k, (x, y) in enumerate(xy):
        ax.annotate(str(k), (x, y), ha="center", va="center", fontsize=7, zorder=3)
    pad = 0.15 * span
    ax.set_xlim(xy[:, 0].min() - pad, xy[:, 0].max() + pad)
    ax.set_ylim(xy[:, 1].min() - pad, xy[:, 1].max() + pad)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title if title is not None else
                 f"{graph.player}\nskill index {graph.skill_index:.2f} "
                 f"({graph.n_nodes} nodes)", fontsize=9)


def plot_style_graphs(rows: list[list[StyleGraph]], titles: list[list[str]] | None = None,
                      layouts: list[list[np.ndarray | None]] | None = None,
                      row_labels: list[str] | None = None,
                      path: str | Path | None = None, dpi: int = 90) -> Figure:
    """Graphs side by side, one list per row (e.g. ground truth above simulated); saved to
    `path` if given."""
    n_rows, n_cols = len(rows), max(len(r) for r in rows)
    fig = Figure(figsize=(3.2 * n_cols, 3.2 * n_rows), layout="constrained")
    axes = np.atleast_2d(fig.subplots(n_rows, n_cols, squeeze=False))
    colours = ("tab:blue", "tab:red", "tab:green", "tab:purple")
    for i, row in enumerate(rows):
        for j in range(n_cols):
            ax = axes[i, j]
            if j >= len(row):
                ax.set_axis_off()
                continue
            plot_style_graph(ax, row[j], None if titles is None else titles[i][j],
                             None if layouts is None else layouts[i][j], colours[i % 4])
            if j == 0 and row_labels is not None:
                ax.set_ylabel(row_labels[i])
    if path is not None:
        fig.savefig(path, dpi=dpi)
    return fig
