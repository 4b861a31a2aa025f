"""Add and fit a model file's shifts of the ball's odds of a racket contact by where the ball
is from its hitter (`model.contact_reach`; `sportsngen.train.contact_reach`).

    .venv/bin/python scripts/fit_contact_reach.py --model FILE --out FILE [--more-data NAME]
        [--prior-frames 20] [--threads 2]

Fitted on the file's own training split (and with `--more-data NAME` every rally of
conf/data/NAME.yaml); the record's share of contacts, the head's odds and the fitted odds are
printed per cell on the file's held-out split. Everything else in the file is copied unchanged.
"""

from __future__ import annotations

import time

import pandas as pd

from sportsngen.model import contact_reach
from sportsngen.train.contact_reach import (
    ContactStates,
    cell_table,
    collect_contact_states,
    fit_contact_reach,
    with_contact_reach,
)
from sportsngen.train.evaluate import split_arrays
from sportsngen.train.table_cli import open_table_run, table_parser


def grid(table: pd.DataFrame, col: str) -> str:
    """A cell table's column as frames-until-his-line rows by metres-aside columns."""
    def edges(e: tuple) -> list[str]:
        return [f"<{e[0]:g}"] + [f"{a:g}-{b:g}" for a, b in zip(e, e[1:])] + [f">{e[-1]:g}"]
    wide = table.pivot_table(index="frames_cell", columns="aside_cell", values=col)
    wide.index = [edges(contact_reach.FRAMES_EDGES)[i] for i in wide.index]
    wide.columns = [edges(contact_reach.ASIDE_EDGES_M)[i] for i in wide.columns]
    return wide.round(3).to_string()


def main() -> None:
    args = table_parser(__doc__, "--prior-frames", 20.0,
                        "pseudo-frames at the head's own odds added to each cell's record",
                        "also read every rally of this data config (conf/data/NAME.yaml)"
                        ).parse_args()
    run = open_table_run(args, lambda m: None if m.cfg.head == "factorised"
                         else "the contact table needs the factorised head")
    t0 = time.time()
    _, held_out = split_arrays(run.path, run.vocab)
    model = with_contact_reach(run.model)
    model.contact_reach.zero_()
    train = ContactStates.concat([collect_contact_states(model, a) for a in run.arrays])
    print(f"{len(train)} recorded frames of a ball coming to a player read "
          f"({time.time() - t0:.0f} s)")
    fit = fit_contact_reach(model, train, prior_frames=args.prior_frames)
    for col, what in (("shift", "a strike's"), ("shift_jolt", "a jolt's")):
        print(f"\n{what} shift (logits), frames until the hitter's line by metres aside:\n"
              f"{grid(fit, col)}")
    held = cell_table(collect_contact_states(model, held_out), model.contact_reach)
    for col, what in (("n", "held-out frames"), ("record", "held-out record's share of "
                      "strikes"), ("head", "the head's odds"), ("shifted", "with the table"),
                      ("record_jolt", "the record's share of jolts"),
                      ("head_jolt", "the head's odds"), ("shifted_jolt", "with the table")):
        print(f"\n{what}:\n{grid(held, col)}")
    run.save(model, args.out)


if __name__ == "__main__":
    main()
