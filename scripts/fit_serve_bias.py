"""Add and fit a model file's per-server shifts of the serve head's odds of a long and a wide
serve and of its speed (`model.serve_bias`; `sportsngen.train.serve_bias`).

    .venv/bin/python scripts/fit_serve_bias.py --model FILE --out FILE [--more-data NAME]
        [--prior-serves 100] [--threads 2] [--short]

With `--short`, on a file that has the table: the short serves' shift added and fitted
(`model.serve_short`, `fit_serve_short`) and each long shift refitted beside it; the other
shifts are left as they are. With `--lateral`, likewise: the lateral bands' shifts added and
fitted (`model.serve_lateral`, `fit_serve_lateral`), each wide shift refitted beside them.

The recorded serves are the file's own training split (`extra.split`, windows also turned as
training turns them) and with `--more-data NAME` every serve of the data config
conf/data/NAME.yaml (synthetic_named: the named players' round robins). Everything else in the
file is copied unchanged.
"""

from __future__ import annotations

import time

from sportsngen.data.tokens import N_SPECIAL_IDS
from sportsngen.train.head_fit import HeadStates, collect_head_states
from sportsngen.train.serve_bias import (
    fit_serve_bias,
    fit_serve_lateral,
    fit_serve_short,
    with_serve_bias,
    with_serve_lateral,
    with_serve_short,
)
from sportsngen.train.table_cli import open_table_run, table_parser


def _on_top(run, flag: str, add, fit, states, prior_serves: float, names: dict):
    """A table fitted on top of the file's serve table (`--short`, `--lateral`) -> the model
    with it and the fit's cells named by server."""
    if run.model.serve_bias is None:
        raise SystemExit(f"{run.path}: {flag} needs the serve table: fit it first")
    model = add(run.model)
    table = fit(model, states, prior_serves=prior_serves)
    table.insert(0, "server", table["server_id"].map(names))
    return model, table


def main() -> None:
    ap = table_parser(__doc__, "--prior-serves", 100.0,
                      "pseudo-serves at the head's own odds added to each server's record",
                      "also read every serve of this data config (conf/data/NAME.yaml)")
    ap.add_argument("--short", action="store_true",
                    help="fit the short serves' shift on a file that has the table")
    ap.add_argument("--lateral", action="store_true",
                    help="fit the lateral bands' shifts on a file that has the table")
    args = ap.parse_args()
    run = open_table_run(args, lambda m: None if m.serve_head is not None
                         else "no serve head (model.serve_head)")
    model, vocab = run.model, run.vocab
    t0 = time.time()
    parts = [collect_head_states(model, a, "serve", flip=True) for a in run.arrays]
    states = HeadStates.concat(parts)
    print(f"{len(states)} recorded serves read ({time.time() - t0:.0f} s)")
    names = {N_SPECIAL_IDS + i: p for i, p in enumerate(vocab.players)}
    if args.lateral:
        model, table = _on_top(run, "--lateral", with_serve_lateral, fit_serve_lateral, states,
                               args.prior_serves, names)
        wide = table.groupby(["server", "serve"]).first()[["n", "wide_odds", "wide_after"]]
        for kind in ("record", "head", "after", "shift"):
            wide[kind] = table.groupby(["server", "serve"])[kind].apply(
                lambda v: " ".join(f"{x:5.2f}" for x in v))
        print(wide.to_string())
        run.save(model, args.out)
        return
    if args.short:
        model, table = _on_top(run, "--short", with_serve_short, fit_serve_short, states,
                               args.prior_serves, names)
        print(table.drop(columns=["server_id"]).round(3).to_string(index=False))
        run.save(model, args.out)
        return
    model = with_serve_bias(model)
    table = fit_serve_bias(model, states, prior_serves=args.prior_serves)
    table.insert(0, "server", table["server_id"].map(names))
    for kind in ("speed_record", "speed_head"):
        table[kind] *= 3.6                                     # km/h
    cols = ["server", "serve", "n", "long_record", "long_head", "long_shift", "wide_record",
            "wide_head", "wide_shift", "speed_record", "speed_head", "speed_shift"]
    print(table[cols].round(3).to_string(index=False))
    run.save(model, args.out)


if __name__ == "__main__":
    main()
