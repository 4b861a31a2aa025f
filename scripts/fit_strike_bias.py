"""Add and fit a model file's per-hitter shifts of the strike head's odds of a rally ball long,
wide or into the net (`model.strike_bias`; `sportsngen.train.strike_bias`).

    .venv/bin/python scripts/fit_strike_bias.py --model FILE --out FILE [--more-data NAME]
        [--prior-strikes 200] [--width | --returns | --pressure | --shape | --shots |
        --players | --late | --depth | --return-surface] [--states FILE] [--view 8]
        [--draws K] [--more-data-only] [--surface]
        [--threads 2]

The recorded rally strikes are the file's own training split (`extra.split`) and with
`--more-data NAME` every rally strike of the data config conf/data/NAME.yaml (synthetic_named:
the named players' round robins). With `--width` the per-hitter width of the balls in play
(`model.strike_width`, `fit_strike_width`) is fitted after the errors, and each wide error's
shift again with it (on a file with the opponents' table: the width alone, then the error
tables refitted with it as `--pressure` fits them). With `--returns` (a file with the table
fitted) each receiver's shifts are split instead: refitted on his strikes that are not
returns, and the returns' own table (`model.strike_return`, `fit_strike_return`) fitted on his
returns. With `--pressure` (a file with the returns' table) a per-opponent table is added
(`model.strike_pressure`, `fit_strike_pressure`) and fitted in turn with the hitters' rows on
the strikes that are not returns, then the returns' table again on top. With `--shape` (a file
with the opponents' table) per-hitter and per-opponent tilts of the depth of the balls in play
and of their height over the net are added (`model.strike_shape`, `fit_strike_shape`), fitted
in turn on the strikes that are not returns, and the error tables refitted with them as
`--pressure` fits them. With `--shots` (a file with the opponents' table) the strike head's
input gets a learned shift by the strike's number in the rally (`model.strike_shots`,
`train.strike_shots`), fitted on the strikes outside the held-out rallies (the head and the
tables frozen; the held-out rallies' teacher-forced depth, height and NLL by shot printed before
and after), then the error tables refitted with it as `--pressure` fits them. `--players` does
the same with a shift per hitter and role and one per opponent and the hitter's role
(`model.strike_players`). With `--late` (a file with the opponents' table) a per-hitter table
of the error shifts on his strikes from the rally's fifth on is added (`model.strike_late`)
and fitted in turn with the hitters' and opponents' tables, then the returns' table again on
top (with `--late-only` the late table alone, on top of the file's tables as they are). With
`--depth` (a file with the opponents' table) a table by the contact's depth behind the
baseline and the hitter's role (`model.strike_depth`) is added and fitted alone on top of the
file's tables as they are, then centred (it tilts the errors by depth, the level stays).
With `--return-surface` (a file with the returns' table) a table of the returns' error shifts
by surface and serve is added (`model.strike_return_surface`) and fitted in turn with the
receivers' returns table on the returns (`train.return_surface.fit_return_surface`; states
read before this part hold no surfaces: read them again).
`--view 8` reads each strike's state from its own window ending 8 frames after it (the
history a rollout gives it) and `--draws K` matches the odds at K of the head's own draws of
the earlier dimensions (as a rollout draws) with `--pressure`, `--late` or `--depth`.
`--surface` then adds a table per hitter, surface and stroke (rally balls, returns;
`model.strike_surface`), fitted from zero on top of every other table as the file (or the fit
before it) has them (`train.strike_surface.fit_strike_surface`): a named player's play by
surface (generator version 6.3 on). It goes alone or after another flag's fit, e.g.
`--pressure --view 8 --draws 4 --surface`.
`--states FILE` keeps
the decoder's states read (most of the time; they do not depend on the tables). Everything
else in the file is copied unchanged.
"""

from __future__ import annotations

import time

from sportsngen.data.tokens import N_SPECIAL_IDS
from sportsngen.train.head_fit import HeadStates, cached_states, collect_head_states
from sportsngen.train.return_surface import fit_return_surface, with_return_surface
from sportsngen.train.strike_bias import (
    KINDS,
    error_shares,
    fit_strike_bias,
    fit_strike_pressure,
    fit_strike_return,
    fit_strike_shape,
    fit_strike_width,
    with_strike_bias,
    with_strike_depth,
    with_strike_late,
    with_strike_pressure,
    with_strike_return,
    with_strike_shape,
    with_strike_width,
)
from sportsngen.train.strike_inputs import (
    fit_strike_inputs,
    held_out,
    shot_profile,
    with_strike_players,
    with_strike_shots,
)
from sportsngen.train.strike_surface import fit_strike_surface, with_strike_surface
from sportsngen.train.table_cli import open_table_run, table_parser


def _read_states(model, run, args) -> HeadStates:
    """The decoder's states at the split's rally strikes, from `args.states` where it holds
    them for this file and data, else read (and kept there: `head_fit.cached_states`)."""
    t0 = time.time()
    try:
        view = f"|view{args.view}" if args.view else ""
        arrays = run.arrays[1:] if args.more_data_only else run.arrays
        got, cached = cached_states(
            args.states, f"{run.path.resolve()}|{args.more_data}"
            f"{'|only' if args.more_data_only else ''}{view}",
            lambda: {"states": HeadStates.concat([collect_head_states(
                model, a, "strike", lead_frames=args.view) for a in arrays])})
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    states = got["states"]
    print(f"{len(states)} recorded rally strikes "
          + (f"from {args.states}" if cached else f"read ({time.time() - t0:.0f} s)"))
    return states


# What each of the exclusive fits adds (each on top of the table the docstring names).
FITS = (
    ("--width", "also fit each hitter's width of the balls in play (model.strike_width)"),
    ("--returns", "split each receiver's shifts: his returns' own (model.strike_return) and "
                  "the rest"),
    ("--pressure", "add a per-opponent table (model.strike_pressure) fitted in turn with the "
                   "hitters' rows"),
    ("--shape", "add per-hitter and per-opponent tilts of the balls' depth and height over "
                "the net (model.strike_shape), the error tables refitted with them"),
    ("--shots", "add a shift of the strike head's input by the strike's number in the rally "
                "(model.strike_shots), the error tables refitted with it"),
    ("--late", "add a per-hitter table of the error shifts on his strikes from the rally's "
               "fifth on (model.strike_late), fitted in turn with the hitters' and opponents'"),
    ("--depth", "add a table by the contact's depth behind the baseline (model.strike_depth), "
                "fitted alone on top of the file's tables and centred"),
    ("--return-surface", "add a table of the returns' error shifts by surface and serve "
                         "(model.strike_return_surface) fitted in turn with the receivers'"),
    ("--players", "add shifts of the strike head's input per hitter and per opponent "
                  "(model.strike_players), the error tables refitted with them"),
)


def main() -> None:
    ap = table_parser(__doc__, "--prior-strikes", 200.0,
                      "pseudo-strikes at the head's own odds added to each hitter's record",
                      "also read every rally strike of this data config (conf/data/NAME.yaml)")
    how = ap.add_mutually_exclusive_group()
    for flag, what in FITS:
        how.add_argument(flag, action="store_true", help=what)
    ap.add_argument("--late-only", action="store_true",
                    help="with --late: fit the late table alone, on top of the file's other "
                         "tables as they are")
    ap.add_argument("--states", default=None,
                    help="cache of the decoder's states: written on the first run, read after")
    ap.add_argument("--view", type=int, default=None, metavar="LEAD",
                    help="read each strike's state from its own window ending LEAD frames "
                         "after it, as a rollout reads it (8), not from windows tiling the "
                         "rally (about twice the time; run with MALLOC_MMAP_THRESHOLD_=65536)")
    ap.add_argument("--more-data-only", action="store_true",
                    help="read the --more-data rallies alone, not the file's training split "
                         "(the named players' round robins: the rows of players only in the "
                         "split are left as they are)")
    ap.add_argument("--surface", action="store_true",
                    help="then add (or refit from zero) the hitters' surfaces table "
                         "(model.strike_surface) on top of every other table: alone, or after "
                         "the fit another flag names")
    ap.add_argument("--draws", type=int, default=0,
                    help="with --pressure, --late, --depth or --return-surface: match each "
                         "strike's odds at "
                         "that many of the head's own draws of the earlier dimensions (as a "
                         "rollout draws), not at the record's")
    args = ap.parse_args()
    if args.late_only and not args.late:
        ap.error("--late-only goes with --late")
    if args.more_data_only and not args.more_data:
        ap.error("--more-data-only goes with --more-data")
    if args.draws and not (args.pressure or args.late or args.depth or args.return_surface
                           or args.surface):
        ap.error("--draws goes with --pressure, --late, --depth, --return-surface or "
                 "--surface")
    run = open_table_run(args, lambda m: None if m.strike_head is not None
                         else "no strike head (model.strike_head)")
    model, vocab = run.model, run.vocab
    states = _read_states(model, run, args)
    names = {N_SPECIAL_IDS + i: p for i, p in enumerate(vocab.players)}
    if args.surface and model.strike_surface is not None:
        # Refitted from zero: the other tables are fitted without it.
        model.strike_surface.zero_()
    if not args.surface or any(getattr(args, f[0][2:].replace("-", "_")) for f in FITS):
        model = _fit(model, states, args, run, names)
    if args.surface:
        model = _fit_surface(model, states, args, names, vocab.surfaces)
    run.save(model, args.out)


def _fit(model, states, args, run, names: dict):
    """The fit the exclusive flags name (the hitters' table where none) -> the model."""
    vocab = run.vocab
    if args.return_surface:
        if model.strike_return is None:
            raise SystemExit(f"{run.path}: no model.strike_return: fit it first (--returns)")
        model = with_return_surface(model)
        try:
            table = fit_return_surface(model, states, states.returns(),
                                       prior_strikes=args.prior_strikes, draws=args.draws)
        except ValueError as exc:
            hint = f" (remove {args.states})" if args.states else ""
            raise SystemExit(f"{exc}{hint}") from None
        surfaces = dict(enumerate(vocab.surfaces))
        table.insert(0, "player", [names[i] if t == "receiver" else surfaces[i]
                                   for t, i in zip(table["table"], table.pop("id"))])
        print(table[["table", "player", "serve", "n"] + [f"{k}_{w}" for k in KINDS
                                                       for w in ("record", "after", "shift")]]
              .round(3).to_string(index=False))
        return model
    if args.width and model.strike_pressure is not None:
        # The error tables split by returns and opponents: the width alone, then those tables
        # refitted with its tilt (`fit_strike_pressure` reads it, the returns' table last).
        model = with_strike_width(model)
        width = fit_strike_width(model, states, prior_strikes=args.prior_strikes,
                                 refit_wide=False)
        width.insert(0, "hitter", width.pop("hitter_id").map(names))
        print(width.round(3).to_string(index=False))
        table = fit_strike_pressure(model, states, states.returns(),
                                    prior_strikes=args.prior_strikes)
        table.insert(0, "player", table["id"].map(names))
        print(table[["table", "player", "receiver", "n", "wide_record", "wide_after",
                     "wide_shift"]].round(3).to_string(index=False))
        return model
    if args.shots or args.players:
        if model.strike_pressure is None:
            raise SystemExit(f"{run.path}: no model.strike_pressure: fit it first (--pressure)")
        try:
            model = with_strike_shots(model) if args.shots else with_strike_players(model)
        except ValueError as exc:
            raise SystemExit(f"{run.path}: {exc}") from None
        val = held_out(states)
        before = shot_profile(model, states, val)
        # A row per player: weight decay holds the rows of players with few strikes near 0.
        history = fit_strike_inputs(model, states, ("shot",)) if args.shots else \
            fit_strike_inputs(model, states, ("players",), steps=4000, weight_decay=0.01)
        print(f"held-out NLL {history[0]['val_nll']:.4f} -> "
              f"{min(h['val_nll'] for h in history):.4f} nats a strike")
        after = shot_profile(model, states, val)
        both = before.merge(after, on=["shot_row", "serve", "n"], suffixes=("", "_shots"))
        print(both.drop(columns=[c for c in both.columns if c.endswith("record_m_shots")])
              .round(3).to_string(index=False))
        table = fit_strike_pressure(model, states, states.returns(),
                                    prior_strikes=args.prior_strikes)
        table.insert(0, "player", table.pop("id").map(names))
        print(table[["table", "player", "receiver", "n"] + [f"{k}_{w}" for k in KINDS
                                                          for w in ("record", "after", "shift")]]
              .round(3).to_string(index=False))
        return model
    if args.shape or args.pressure or args.late or args.depth:
        # Tables fitted in turn over the strikes that are not returns, on top of the one the
        # file must already have.
        needs, fit_first, add, fit = (
            ("strike_pressure", "--pressure", with_strike_shape, fit_strike_shape) if args.shape
            else ("strike_pressure", "--pressure", with_strike_late, fit_strike_pressure)
            if args.late
            else ("strike_pressure", "--pressure", with_strike_depth, fit_strike_pressure)
            if args.depth
            else ("strike_return", "--returns", with_strike_pressure, fit_strike_pressure))
        if getattr(model, needs) is None:
            raise SystemExit(f"{run.path}: no model.{needs}: fit it first ({fit_first})")
        model = add(model)
        kw = {"late_only": True} if args.late and args.late_only else \
            {"depth_only": True} if args.depth else {}
        if args.draws and not args.shape:
            kw["draws"] = args.draws
        table = fit(model, states, states.returns(), prior_strikes=args.prior_strikes, **kw)
        ids = table.pop("id")
        table.insert(0, "player", ids.map(names) if not args.depth else
                     ids.map(lambda b: f"depth band {b}"))
        cols = list(table.columns) if args.shape else \
            ["table", "player", "receiver", "n"] + [f"{k}_{w}" for k in KINDS
                                                    for w in ("record", "after", "shift")]
        print(table[cols].round(3).to_string(index=False))
        if args.depth:
            print("centred table (band x role x long/wide/net):\n"
                  + str(model.strike_depth.numpy().round(3)))
        return model
    if args.returns:
        if model.strike_bias is None:
            raise SystemExit(f"{run.path}: no per-hitter table to split (model.strike_bias): "
                             "fit it first")
        model = with_strike_return(model)
        returns = states.returns()
        print(f"{int(returns.sum())} returns among them")
        table = fit_strike_return(model, states, returns, prior_strikes=args.prior_strikes)
        role = "is_return"
    else:
        model = with_strike_bias(model)
        table = fit_strike_bias(model, states, prior_strikes=args.prior_strikes)
        role = "receiver"
    shares = error_shares(table)
    table.insert(0, "hitter", table["hitter_id"].map(names))
    for col in ("error_record", "error_head", "error_after"):
        table[col] = shares[col]
    cols = ["hitter", role, "n", "error_record", "error_head", "error_after",
            "long_shift", "wide_shift", "net_shift"]
    print(table[cols].round(3).to_string(index=False))
    if args.width:
        model = with_strike_width(model)
        width = fit_strike_width(model, states, prior_strikes=args.prior_strikes)
        width.insert(0, "hitter", width["hitter_id"].map(names))
        print(width.drop(columns="hitter_id").round(3).to_string(index=False))
    return model


def _fit_surface(model, states, args, names: dict, surfaces: list[str]):
    """`--surface`: the hitters' surfaces table added (or zeroed) and fitted on top of the
    model's other tables -> the model."""
    if model.strike_bias is None:
        raise SystemExit("--surface needs the hitters' table (model.strike_bias): fit it first")
    model = with_strike_surface(model)
    try:
        table = fit_strike_surface(model, states, prior_strikes=args.prior_strikes,
                                   draws=args.draws)
    except ValueError as exc:
        hint = f" (remove {args.states})" if args.states else ""
        raise SystemExit(f"{exc}{hint}") from None
    table.insert(0, "player", table.pop("id").map(names))
    table["surface"] = table["surface"].map(dict(enumerate(surfaces)))
    print(table[["player", "surface", "stroke", "n"] + [f"{k}_{w}" for k in KINDS
                                                     for w in ("record", "after", "shift")]]
          .round(3).to_string(index=False))
    return model


if __name__ == "__main__":
    main()
