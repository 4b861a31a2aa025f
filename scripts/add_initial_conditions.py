"""Store the simulator's initial conditions (first frames of real serves) in a model file.

    python scripts/add_initial_conditions.py --model sportsngen/model/bundled/sportsngen-small.pt \
        --data synthetic_small [--frames 10] [--per-key 100]

`train.py` already stores them in every model it exports; this is for model files exported
before that, to rebuild the pool from other data (`--data` is a conf/data/*.yaml name or a
RallyData folder), or to rebuild a pool stored before pools recorded their receivers (a
simulated point then starts with its own receiver's stance, `sportsngen.sim.initial`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from omegaconf import OmegaConf

from sportsngen.data.tracking import RallyData
from sportsngen.model.export import update_extra
from sportsngen.sim.initial import MAX_PER_KEY_DEFAULT, N_FRAMES_DEFAULT, InitialConditions
from sportsngen.train.datamodule import load_rally_data

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", required=True)
    ap.add_argument("--data", required=True, help="conf/data config name or RallyData folder")
    ap.add_argument("--frames", type=int, default=N_FRAMES_DEFAULT)
    ap.add_argument("--per-key", type=int, default=MAX_PER_KEY_DEFAULT)
    args = ap.parse_args()
    if Path(args.data).is_dir():
        data = RallyData.load(args.data)
    else:
        cfg = OmegaConf.load(REPO / "conf" / "data" / f"{args.data}.yaml")
        data = load_rally_data(OmegaConf.to_container(cfg, resolve=True))
    ic = InitialConditions.from_rally_data(data, args.frames, args.per_key)
    update_extra(args.model, initial_conditions=ic.to_dict())
    print(f"{args.model}: {len(ic)} initial conditions of {len(ic.servers)} servers, "
          f"{ic.n_frames} frames each")


if __name__ == "__main__":
    main()
