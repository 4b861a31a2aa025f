"""The gallery of `docs/synthetic-data.md`: four generated rallies drawn with
`sportsngen.viz.court_plot.plot_rally` (an ace, a long rally, a net approach, a forced error).

    python scripts/render_gallery.py [--points 300] [--seed 4] [--out docs/figures/synthetic]

Federer v Nadal on grass; each picture the first rally of its kind (`sportsngen.viz.gallery`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.errors import ArgumentError
from sportsngen.viz.gallery import render_gallery


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=300)
    ap.add_argument("--seed", type=int, default=4)
    ap.add_argument("--out", type=Path, default=Path("docs/figures/synthetic"))
    args = ap.parse_args()
    try:
        render_gallery(args.out, args.points, args.seed)
    except ArgumentError as exc:
        raise SystemExit(str(exc)) from None


if __name__ == "__main__":
    main()
