"""Fit each receiver's reach for the return on a model file's recorded serves, and write it
into a copy of the file (`extra.return_reach`, `sportsngen.sim.return_reach`) with the
sampling default that draws from it (`return_reach_draw=true`).

    .venv/bin/python scripts/fit_return_reach.py --model MODEL --more-data synthetic_named \\
        --out OUT.pt

The serves read are the file's training split and, with --more-data, every rally of that data
config; a receiver with fewer than --min-serves good serves plays the pooled row.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from sportsngen.model.export import update_extra
from sportsngen.sim.return_reach import MIN_SERVES, return_reach_from_data
from sportsngen.sim.simulator import Simulator, model_path
from sportsngen.train.evaluate import training_rally_data


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None, help="model file (default: the bundled one)")
    ap.add_argument("--out", required=True, help="where to write the model file")
    ap.add_argument("--more-data", default=None,
                    help="also read every rally of this data config (conf/data/NAME.yaml)")
    ap.add_argument("--min-serves", type=int, default=MIN_SERVES)
    args = ap.parse_args()
    src = model_path(args.model)
    try:
        parts = training_rally_data(src, args.more_data)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    table, serves = return_reach_from_data(parts, args.min_serves)
    print(f"{len(serves)} good serves, {serves['answered'].mean():.3f} returned")
    print(f"pooled: half returned at {table.pooled[0]:.3f} m, scale {table.pooled[1]:.3f} m")
    for name, (c, s) in sorted(table.players.items()):
        n = int((serves["receiver"] == name).sum())
        print(f"{name:<20} {n:6d} serves: half returned at {c:.3f} m, scale {s:.3f} m")
    out = Path(args.out)
    if out.resolve() != src.resolve():
        shutil.copyfile(src, out)
    update_extra(out, return_reach=table.to_dict())
    Simulator.set_defaults(out, return_reach_draw=True)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
