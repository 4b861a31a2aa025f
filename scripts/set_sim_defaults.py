"""Store sampling defaults in a model file (its `sim_defaults`, used by every rollout that
does not name them), keeping the others (`sportsngen.train.table_cli.set_sim_defaults`).
Values: true / false, or a number.

    python scripts/set_sim_defaults.py MODEL KEY=VALUE [KEY=VALUE ...]
    e.g. scripts/set_sim_defaults.py sportsngen/model/bundled/sportsngen-small.pt \\
        strike_in_reach_force=true strike_in_reach_m=1.5
"""

from __future__ import annotations

import argparse

from sportsngen.errors import ArgumentError
from sportsngen.train.table_cli import set_sim_defaults


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("values", nargs="+", metavar="KEY=VALUE")
    args = ap.parse_args()
    try:
        print(f"{args.model}: sim_defaults {set_sim_defaults(args.model, args.values)}")
    except ArgumentError as exc:
        ap.error(str(exc))


if __name__ == "__main__":
    main()
