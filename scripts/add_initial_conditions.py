"""Store the simulator's initial conditions (first frames of real serves) in a model file
(`sportsngen.train.rule_tables.add_initial_conditions`).

    python scripts/add_initial_conditions.py --model sportsngen/model/bundled/sportsngen-small.pt \\
        --data synthetic_small [--frames 10] [--per-key 100]

For files exported before `train.py` stored them, or a pool from other data (a RallyData folder).
"""

from __future__ import annotations

import argparse

from sportsngen.data.serve_starts import MAX_PER_KEY_DEFAULT, N_FRAMES_DEFAULT
from sportsngen.train.rule_tables import add_initial_conditions


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", required=True)
    ap.add_argument("--data", required=True, help="conf/data config name or RallyData folder")
    ap.add_argument("--frames", type=int, default=N_FRAMES_DEFAULT)
    ap.add_argument("--per-key", type=int, default=MAX_PER_KEY_DEFAULT)
    add_initial_conditions(**vars(ap.parse_args()))


if __name__ == "__main__":
    main()
