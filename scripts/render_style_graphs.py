"""Render style graphs (SkillVis style) and placement / recovery heatmaps (Vid2Player style).

Ground truth: four named players generated; simulated: the shot-cycle model fitted on it, or a
`RallyData` folder given with ``--simulated`` (`sportsngen.viz.style_figures`). Writes
``style_graphs.png``, ``heatmaps_<who>_<player>.png`` and ``summary.json`` into ``--out``:

    .venv/bin/python scripts/render_style_graphs.py [--points 400] [--sim-points N]
        [--seed 0] [--surface hard] [--threshold 1.5] [--simulated FOLDER] [--out DIR]

(points are per matchup; about 3 minutes on one CPU core with the defaults)
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.viz.style_figures import render_style_graphs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--points", type=int, default=400, help="ground-truth points a matchup")
    ap.add_argument("--sim-points", type=int, default=None,
                    help="simulated points a matchup (default: --points, so that skill indices "
                         "compare like with like)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--surface", default="hard")
    ap.add_argument("--threshold", type=float, default=1.5, help="node distance threshold, m")
    ap.add_argument("--simulated", type=Path, default=None, help="RallyData folder to compare")
    ap.add_argument("--out", type=Path, default=Path("docs/figures/style"))
    args = ap.parse_args()
    render_style_graphs(args.out, args.points, args.sim_points, args.seed, args.surface,
                        args.threshold, args.simulated)


if __name__ == "__main__":
    main()
