"""Export a decoder checkpoint as a model file, with another model file's event classifier and
extras (serve starts, simulation defaults, split; `sportsngen.train.finetune.export_checkpoint`).

    python scripts/export_checkpoint.py CHECKPOINT OUT [--from MODEL_FILE]
        [--events-from MODEL_FILE] [--strike-head-from MODEL_FILE] [--average-generic-identity]

CHECKPOINT: `outputs/.../checkpoints_decoder/*.ckpt` (the decoder only) or a model file;
everything else from --from (default: the bundled model).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.sim.simulator import model_path
from sportsngen.train.finetune import export_checkpoint


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkpoint", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--from", dest="source", type=Path, default=model_path())
    ap.add_argument("--events-from", type=Path, default=None,
                    help="the event classifier of this file (one whose g was retrained)")
    ap.add_argument("--strike-head-from", type=Path, default=None,
                    help="the strike head of this file, fine-tuned from the same base")
    ap.add_argument("--average-generic-identity", action="store_true",
                    help="generic row := the players' mean (not for a player fine-tuned onto "
                         "a generic model)")
    args = ap.parse_args()
    export_checkpoint(args.checkpoint, args.out, args.source, args.events_from,
                      args.strike_head_from, average_identity=args.average_generic_identity)


if __name__ == "__main__":
    main()
