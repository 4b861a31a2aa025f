"""Store sampling defaults in a model file (its `sim_defaults`, used by every rollout that
does not name them), keeping the others.

    .venv/bin/python scripts/set_sim_defaults.py MODEL KEY=VALUE [KEY=VALUE ...]
    e.g. scripts/set_sim_defaults.py sportsngen/model/bundled/sportsngen-small.pt \\
        strike_in_reach_force=true strike_in_reach_m=1.5

Values: true / false, or a number.
"""

from __future__ import annotations

import argparse

from sportsngen.errors import ArgumentError
from sportsngen.sim.simulator import Simulator


def parse_value(text: str) -> bool | float:
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    try:
        return float(text)
    except ValueError:
        raise ArgumentError(f"a value is true, false or a number, got {text!r}") from None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("values", nargs="+", metavar="KEY=VALUE")
    args = ap.parse_args()
    try:
        pairs = dict(v.split("=", 1) if "=" in v else (v, "") for v in args.values)
        values = {k: parse_value(v) for k, v in pairs.items()}
        print(f"{args.model}: sim_defaults {Simulator.set_defaults(args.model, **values)}")
    except ArgumentError as exc:
        ap.error(str(exc))


if __name__ == "__main__":
    main()
