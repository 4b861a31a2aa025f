"""Shot by shot, how often a named player's service points end: the real 2011 slams (US Open and
Wimbledon) beside the generator (the calibration's service points against population players).

    python scripts/rally_hazards.py [--players "Rafael Nadal" "Novak Djokovic"] [--points 3000]
        [--seed 5] [--max-length 10]

Hazard at rally length L: the share of points reaching L shots that end there
(`sportsngen.eval.slam_hazards`, which names the source of the real points; needs
../shared/data/slam_pointbypoint).
"""

from __future__ import annotations

import argparse
import sys

from sportsngen.eval.slam_hazards import slam_hazards


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--players", nargs="+", default=["Rafael Nadal", "Novak Djokovic"])
    ap.add_argument("--points", type=int, default=3000, help="generated service points a player")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--max-length", type=int, default=10)
    args = ap.parse_args(argv)
    return slam_hazards(args.players, args.points, args.seed, args.max_length)


if __name__ == "__main__":
    sys.exit(main())
