"""Add and fit a model file's per-server shifts of the receiver's odds of starting his run at
the serve (`model.receiver_start`; `sportsngen.train.receiver_start`).

    .venv/bin/python scripts/fit_receiver_start.py --model FILE --out FILE [--more-data NAME]
        [--prior-frames 200] [--threads 2]

The recorded serves are the file's own training split (`extra.split`, windows also turned as
training turns them) and with `--more-data NAME` every rally of the data config
conf/data/NAME.yaml (synthetic_named: the named players' round robins). Everything else in the
file is copied unchanged.
"""

from __future__ import annotations

import argparse
import time

import torch

from sportsngen.data.tokens import N_SPECIAL_IDS
from sportsngen.model.export import load_model, read_extra, save_model
from sportsngen.sim.simulator import model_path
from sportsngen.train.evaluate import training_arrays
from sportsngen.train.receiver_start import (
    WaitStates,
    collect_wait_states,
    fit_receiver_start,
    with_receiver_start,
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None, help="model file (default: the bundled one)")
    ap.add_argument("--out", required=True, help="where to write the model file")
    ap.add_argument("--more-data", default=None,
                    help="also read every rally of this data config (conf/data/NAME.yaml)")
    ap.add_argument("--prior-frames", type=float, default=200.0,
                    help="pseudo-frames at the head's own odds added to each server's record")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    path = model_path(args.model)
    model, ec, vocab, _ = load_model(path)
    if model.cfg.head != "factorised":
        raise SystemExit(f"{path}: the receiver's shift needs the factorised head")
    extra = read_extra(path)
    t0 = time.time()
    try:
        arrays = training_arrays(path, vocab, args.more_data)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    parts = [collect_wait_states(model, a, flip=True) for a in arrays]
    states = WaitStates.concat(parts)
    print(f"{len(states)} recorded waiting frames read ({time.time() - t0:.0f} s)")
    model = with_receiver_start(model)
    table = fit_receiver_start(model, states, prior_frames=args.prior_frames)
    names = {N_SPECIAL_IDS + i: p for i, p in enumerate(vocab.players)}
    table.insert(0, "server", table["server_id"].map(names))
    for col in ("record", "head", "shift"):
        wide = table.pivot_table(index=["server", "serve"], columns="wait", values=col)
        print(f"\n{col} by frames waited:\n{wide.round(2).to_string()}")
    save_model(args.out, model, vocab, ec, extra=extra)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
