"""How returned serves end, simulated against the ground truth: by rally length and end reason,
and how often the server wins once the serve is returned.

    .venv/bin/python scripts/diagnose_rally_ends.py [--model PATH] [--server "Rafael Nadal"]
        [--receiver "Roger Federer"] [--points 300] [--seed 4]

First serves of the server on hard (`sportsngen.eval.serve_returns.diagnose_rally_ends`).
"""

from __future__ import annotations

import argparse

from sportsngen.eval.command_line import add_points_seed, add_simulator_options, simulator_from_args
from sportsngen.eval.serve_returns import diagnose_rally_ends


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_simulator_options(ap)
    ap.add_argument("--server", default="Rafael Nadal")
    ap.add_argument("--receiver", default="Roger Federer")
    add_points_seed(ap, points=300, seed=4)
    args = ap.parse_args()
    diagnose_rally_ends(simulator_from_args(ap, args), args.server, args.receiver, args.points,
                        args.seed)


if __name__ == "__main__":
    main()
