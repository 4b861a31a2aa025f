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

import time

from sportsngen.data.tokens import N_SPECIAL_IDS
from sportsngen.train.receiver_start import (
    WaitStates,
    collect_wait_states,
    fit_receiver_start,
    with_receiver_start,
)
from sportsngen.train.table_cli import open_table_run, table_parser


def main() -> None:
    args = table_parser(__doc__, "--prior-frames", 200.0,
                        "pseudo-frames at the head's own odds added to each server's record",
                        "also read every rally of this data config (conf/data/NAME.yaml)"
                        ).parse_args()
    run = open_table_run(args, lambda m: None if m.cfg.head == "factorised"
                         else "the receiver's shift needs the factorised head")
    model, vocab = run.model, run.vocab
    t0 = time.time()
    parts = [collect_wait_states(model, a, flip=True) for a in run.arrays]
    states = WaitStates.concat(parts)
    print(f"{len(states)} recorded waiting frames read ({time.time() - t0:.0f} s)")
    model = with_receiver_start(model)
    table = fit_receiver_start(model, states, prior_frames=args.prior_frames)
    names = {N_SPECIAL_IDS + i: p for i, p in enumerate(vocab.players)}
    table.insert(0, "server", table["server_id"].map(names))
    for col in ("record", "head", "shift"):
        wide = table.pivot_table(index=["server", "serve"], columns="wait", values=col)
        print(f"\n{col} by frames waited:\n{wide.round(2).to_string()}")
    run.save(model, args.out)


if __name__ == "__main__":
    main()
