"""The leak check of issue 16 on generated play: Federer v Nadal on hard and Djokovic v Murray on
clay, `--points` each (`sportsngen.eval.leak_report`).

    python scripts/leak_report.py [--points 800] [--seed 1] [--boot 1000] [--out /tmp/leaks]
        [--before /tmp/leaks_v5] [--data /tmp/v5data/p800 | --save-data /tmp/v5data/p800]

Writes ``<out>_<matchup>.csv``, ``<out>_<matchup>_paths.csv`` and ``<out>.md`` and prints how
many AUCs lie outside [0.4, 0.6]; ``--before`` (another run's ``--out``) adds
``<out>_compare.md``, before -> now. ``--save-data PREFIX``, run from a replaced generator's
tree (PYTHONPATH), only saves its points in ``<PREFIX>_<matchup>`` folders for ``--data PREFIX``
here to check them with today's check.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.eval.leak_report import leak_report, save_matchups


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=800)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--boot", type=int, default=1000)
    ap.add_argument("--out", type=Path, default=Path("/tmp/leaks"))
    ap.add_argument("--before", type=Path, default=None,
                    help="--out of a run on another revision: also write a comparison table")
    ap.add_argument("--data", type=Path, default=None,
                    help="read the points from <DATA>_<matchup> folders (module doc)")
    ap.add_argument("--save-data", type=Path, default=None,
                    help="only generate the points and save them in <SAVE_DATA>_<matchup>")
    args = ap.parse_args()
    if args.save_data is not None:
        save_matchups(args.save_data, args.points, args.seed, data=args.data)
        return
    leak_report(args.out, args.points, args.seed, args.boot, data=args.data, before=args.before)


if __name__ == "__main__":
    main()
