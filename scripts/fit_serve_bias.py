"""Add and fit a model file's per-server shifts of the serve head's odds of a long and a wide
serve and of its speed (`model.serve_bias`; `sportsngen.train.serve_bias`).

    .venv/bin/python scripts/fit_serve_bias.py --model FILE --out FILE [--more-data NAME]
        [--prior-serves 100] [--threads 2]

The recorded serves are the file's own training split (`extra.split`, windows also turned as
training turns them) and with `--more-data NAME` every serve of the data config
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
from sportsngen.train.head_fit import HeadStates, collect_head_states
from sportsngen.train.serve_bias import fit_serve_bias, with_serve_bias


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None, help="model file (default: the bundled one)")
    ap.add_argument("--out", required=True, help="where to write the model file")
    ap.add_argument("--more-data", default=None,
                    help="also read every serve of this data config (conf/data/NAME.yaml)")
    ap.add_argument("--prior-serves", type=float, default=100.0,
                    help="pseudo-serves at the head's own odds added to each server's record")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    path = model_path(args.model)
    model, ec, vocab, _ = load_model(path)
    if model.serve_head is None:
        raise SystemExit(f"{path} has no serve head (model.serve_head)")
    extra = read_extra(path)
    t0 = time.time()
    try:
        arrays = training_arrays(path, vocab, args.more_data)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    parts = [collect_head_states(model, a, "serve", flip=True) for a in arrays]
    states = HeadStates.concat(parts)
    print(f"{len(states)} recorded serves read ({time.time() - t0:.0f} s)")
    model = with_serve_bias(model)
    table = fit_serve_bias(model, states, prior_serves=args.prior_serves)
    names = {N_SPECIAL_IDS + i: p for i, p in enumerate(vocab.players)}
    table.insert(0, "server", table["server_id"].map(names))
    for kind in ("speed_record", "speed_head"):
        table[kind] *= 3.6                                     # km/h
    cols = ["server", "serve", "n", "long_record", "long_head", "long_shift", "wide_record",
            "wide_head", "wide_shift", "speed_record", "speed_head", "speed_shift"]
    print(table[cols].round(3).to_string(index=False))
    save_model(args.out, model, vocab, ec, extra=extra)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
