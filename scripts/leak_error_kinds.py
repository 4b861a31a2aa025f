"""What drives the leak check's error-against-in separation for the opponent: his speed k frames
after rally contacts that will be errors, by where the error goes (net, long, wide), beside
contacts that land in, all before the outcome is visible.

    python scripts/leak_error_kinds.py [--points 1500] [--seed 1] [--k 12]

Federer v Nadal on hard (`sportsngen.eval.leak_causes`).
"""

from __future__ import annotations

import argparse

from sportsngen.eval.leak_causes import leak_error_kinds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1500)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--k", type=int, default=12)
    args = ap.parse_args()
    leak_error_kinds(args.points, args.seed, args.k)


if __name__ == "__main__":
    main()
