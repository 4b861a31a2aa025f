"""Add and fit a model file's per-hitter shifts of the strike head's odds of a rally ball long,
wide or into the net (`model.strike_bias`; `sportsngen.train.strike_bias`).

    .venv/bin/python scripts/fit_strike_bias.py --model FILE --out FILE [--more-data NAME]
        [--prior-strikes 200] [--width] [--threads 2]

The recorded rally strikes are the file's own training split (`extra.split`) and with
`--more-data NAME` every rally strike of the data config conf/data/NAME.yaml (synthetic_named:
the named players' round robins). With `--width` the per-hitter width of the balls in play
(`model.strike_width`, `fit_strike_width`) is fitted after the errors, and each wide error's
shift again with it. Everything else in the file is copied unchanged.
"""

from __future__ import annotations

import time

from sportsngen.data.tokens import N_SPECIAL_IDS
from sportsngen.train.head_fit import HeadStates, collect_head_states
from sportsngen.train.strike_bias import (
    error_shares,
    fit_strike_bias,
    fit_strike_width,
    with_strike_bias,
    with_strike_width,
)
from sportsngen.train.table_cli import open_table_run, table_parser


def main() -> None:
    ap = table_parser(__doc__, "--prior-strikes", 200.0,
                      "pseudo-strikes at the head's own odds added to each hitter's record",
                      "also read every rally strike of this data config (conf/data/NAME.yaml)")
    ap.add_argument("--width", action="store_true",
                    help="also fit each hitter's width of the balls in play (model.strike_width)")
    args = ap.parse_args()
    run = open_table_run(args, lambda m: None if m.strike_head is not None
                         else "no strike head (model.strike_head)")
    model, vocab = run.model, run.vocab
    t0 = time.time()
    states = HeadStates.concat([collect_head_states(model, a, "strike") for a in run.arrays])
    print(f"{len(states)} recorded rally strikes read ({time.time() - t0:.0f} s)")
    model = with_strike_bias(model)
    table = fit_strike_bias(model, states, prior_strikes=args.prior_strikes)
    names = {N_SPECIAL_IDS + i: p for i, p in enumerate(vocab.players)}
    shares = error_shares(table)
    table.insert(0, "hitter", table["hitter_id"].map(names))
    for col in ("error_record", "error_head", "error_after"):
        table[col] = shares[col]
    cols = ["hitter", "receiver", "n", "error_record", "error_head", "error_after",
            "long_shift", "wide_shift", "net_shift"]
    print(table[cols].round(3).to_string(index=False))
    if args.width:
        model = with_strike_width(model)
        width = fit_strike_width(model, states, prior_strikes=args.prior_strikes)
        width.insert(0, "hitter", width["hitter_id"].map(names))
        print(width.drop(columns="hitter_id").round(3).to_string(index=False))
    run.save(model, args.out)


if __name__ == "__main__":
    main()
