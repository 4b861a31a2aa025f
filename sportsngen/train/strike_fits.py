"""The strike head's error tables fitted onto a model file, as `scripts/fit_strike_bias.py`
runs them: the per-hitter shifts of the odds of a rally ball long, wide or into the net
(`model.strike_bias`; `train.strike_bias`) and the tables fitted on top of them.

The recorded rally strikes are the file's own training split (`extra.split`) and with
`more_data` every rally strike of that data config (synthetic_named: the named players' round
robins; with `more_data_only` those alone). One of the exclusive fits (`FITS`), else the
hitters' table:

- `width`: the per-hitter width of the balls in play (`model.strike_width`, `fit_strike_width`)
  fitted after the errors, and each wide error's shift again with it (on a file with the
  opponents' table: the width alone, then the error tables refitted with it as `pressure`
  fits them);
- `returns` (a file with the hitters' table): each receiver's shifts split: refitted on his
  strikes that are not returns, and the returns' own table (`model.strike_return`,
  `fit_strike_return`) fitted on his returns;
- `pressure` (a file with the returns' table): a per-opponent table (`model.strike_pressure`,
  `fit_strike_pressure`) fitted in turn with the hitters' rows on the strikes that are not
  returns, then the returns' table again on top;
- `shape` (a file with the opponents' table): per-hitter and per-opponent tilts of the depth of
  the balls in play and of their height over the net (`model.strike_shape`,
  `fit_strike_shape`), fitted in turn on the strikes that are not returns, the error tables
  refitted with them as `pressure` fits them;
- `shots` (a file with the opponents' table): a learned shift of the strike head's input by
  the strike's number in the rally (`model.strike_shots`, `train.strike_inputs`), fitted on
  the strikes outside the held-out rallies (the head and the tables frozen; the held-out
  rallies' teacher-forced depth, height and NLL by shot printed before and after), then the
  error tables refitted with it; `players` does the same with a shift per hitter and role and
  one per opponent and the hitter's role (`model.strike_players`);
- `late` (a file with the opponents' table): a per-hitter table of the error shifts on his
  strikes from the rally's fifth on (`model.strike_late`) fitted in turn with the hitters' and
  opponents' tables, then the returns' table again on top (with `late_only` the late table
  alone, on top of the file's tables as they are);
- `depth` (a file with the opponents' table): a table by the contact's depth behind the
  baseline and the hitter's role (`model.strike_depth`) fitted alone on top of the file's
  tables as they are, then centred (it tilts the errors by depth, the level stays);
- `return_surface` (a file with the returns' table): a table of the returns' error shifts by
  surface and serve (`model.strike_return_surface`) fitted in turn with the receivers'
  returns table on the returns (`train.return_surface.fit_return_surface`; states read before
  this part hold no surfaces: read them again).

`view` (8) reads each strike's state from its own window ending that many frames after it (the
history a rollout gives it) and `draws` K matches the odds at K of the head's own draws of the
earlier dimensions (as a rollout draws) with `pressure`, `late`, `depth`, `return_surface` or
`surface`. `surface` then adds a table per hitter, surface and stroke (rally balls, returns;
`model.strike_surface`), fitted from zero on top of every other table as the file (or the fit
before it) has them (`train.strike_surface.fit_strike_surface`): a named player's play by
surface (generator version 6.3 on); alone or after another flag's fit. `states` (a file) keeps
the decoder's states read (most of the time; they do not depend on the tables).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from sportsngen.errors import ArgumentError
from sportsngen.model.decoder import SportsNGEN
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
from sportsngen.train.table_cli import TableRun, open_table_run, player_names

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
FIT_NAMES = tuple(flag[2:].replace("-", "_") for flag, _ in FITS)
# The error columns the tables print.
ERROR_COLUMNS = [f"{k}_{w}" for k in KINDS for w in ("record", "after", "shift")]


@dataclass(frozen=True)
class StrikeFit:
    """What to fit (the module's docstring): `which` of the exclusive fits (`FITS`' flag
    without its dashes, e.g. "return_surface"; None: the hitters' table), then `surface`."""

    which: str | None = None
    prior_strikes: float = 200.0
    late_only: bool = False
    states: str | None = None
    view: int | None = None
    more_data_only: bool = False
    surface: bool = False
    draws: int = 0

    def __post_init__(self) -> None:
        if self.which not in (None, *FIT_NAMES):
            raise ArgumentError(f"no fit {self.which!r}: one of {FIT_NAMES}")
        if self.late_only and self.which != "late":
            raise ArgumentError("--late-only goes with --late")
        if self.draws and not (self.which in ("pressure", "late", "depth", "return_surface")
                               or self.surface):
            raise ArgumentError("--draws goes with --pressure, --late, --depth, "
                                "--return-surface or --surface")


def fit_strike_tables_file(model: str | None, out: str, more_data: str | None = None,
                           threads: int = 2, **options) -> None:
    """The fit `options` name (`StrikeFit`'s fields) on the model file `model`, written to
    `out` with everything else in the file unchanged; the exclusive fits come as flags
    (`width=True`, ...) as the script parses them (`ArgumentError` on options that do not go
    together, before anything is read)."""
    asked = [name for name in FIT_NAMES if options.pop(name, False)]
    if len(asked) > 1:
        raise ArgumentError(f"one fit at a time, got {asked}")
    fit = StrikeFit(asked[0] if asked else None, **options)
    if fit.more_data_only and not more_data:
        raise ArgumentError("--more-data-only goes with --more-data")
    run = open_table_run(model, more_data, threads, lambda m: None if m.strike_head is not None
                         else "no strike head (model.strike_head)")
    net, vocab = run.model, run.vocab
    states = read_strike_states(net, run, more_data, fit)
    names = player_names(vocab)
    if fit.surface and net.strike_surface is not None:
        # Refitted from zero: the other tables are fitted without it.
        net.strike_surface.zero_()
    if not fit.surface or fit.which:
        net = _fit(net, states, fit, run, names)
    if fit.surface:
        net = _fit_surface(net, states, fit, names, vocab.surfaces)
    run.save(net, out)


def read_strike_states(model: SportsNGEN, run: TableRun, more_data: str | None,
                       fit: StrikeFit) -> HeadStates:
    """The decoder's states at the run's rally strikes, from `fit.states` where it holds
    them for this file and data, else read (and kept there: `head_fit.cached_states`)."""
    t0 = time.time()
    try:
        view = f"|view{fit.view}" if fit.view else ""
        arrays = run.arrays[1:] if fit.more_data_only else run.arrays
        got, cached = cached_states(
            fit.states, f"{run.path.resolve()}|{more_data}"
            f"{'|only' if fit.more_data_only else ''}{view}",
            lambda: {"states": HeadStates.concat([collect_head_states(
                model, a, "strike", lead_frames=fit.view) for a in arrays])})
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    states = got["states"]
    print(f"{len(states)} recorded rally strikes "
          + (f"from {fit.states}" if cached else f"read ({time.time() - t0:.0f} s)"))
    return states


def _fit(model: SportsNGEN, states: HeadStates, fit: StrikeFit, run: TableRun,
         names: dict) -> SportsNGEN:
    """The fit the exclusive flags name (the hitters' table where none) -> the model."""
    if fit.which == "return_surface":
        return _fit_return_surface(model, states, fit, run, names)
    if fit.which == "width" and model.strike_pressure is not None:
        # The error tables split by returns and opponents: the width alone, then those tables
        # refitted with its tilt (`fit_strike_pressure` reads it, the returns' table last).
        model = with_strike_width(model)
        width = fit_strike_width(model, states, prior_strikes=fit.prior_strikes,
                                 refit_wide=False)
        width.insert(0, "hitter", width.pop("hitter_id").map(names))
        print(width.round(3).to_string(index=False))
        table = fit_strike_pressure(model, states, states.returns(),
                                    prior_strikes=fit.prior_strikes)
        table.insert(0, "player", table["id"].map(names))
        print(table[["table", "player", "receiver", "n", "wide_record", "wide_after",
                     "wide_shift"]].round(3).to_string(index=False))
        return model
    if fit.which in ("shots", "players"):
        return _fit_inputs(model, states, fit, run, names)
    if fit.which in IN_TURN:
        return _fit_in_turn(model, states, fit, run, names)
    return _fit_hitters(model, states, fit, run, names)


def _fit_return_surface(model: SportsNGEN, states: HeadStates, fit: StrikeFit, run: TableRun,
                        names: dict) -> SportsNGEN:
    if model.strike_return is None:
        raise SystemExit(f"{run.path}: no model.strike_return: fit it first (--returns)")
    model = with_return_surface(model)
    try:
        table = fit_return_surface(model, states, states.returns(),
                                   prior_strikes=fit.prior_strikes, draws=fit.draws)
    except ValueError as exc:
        hint = f" (remove {fit.states})" if fit.states else ""
        raise SystemExit(f"{exc}{hint}") from None
    surfaces = dict(enumerate(run.vocab.surfaces))
    table.insert(0, "player", [names[i] if t == "receiver" else surfaces[i]
                               for t, i in zip(table["table"], table.pop("id"))])
    print(table[["table", "player", "serve", "n"] + ERROR_COLUMNS].round(3)
          .to_string(index=False))
    return model


def _fit_inputs(model: SportsNGEN, states: HeadStates, fit: StrikeFit, run: TableRun,
                names: dict) -> SportsNGEN:
    """`shots` / `players`: the strike head's input shifts, then the error tables."""
    if model.strike_pressure is None:
        raise SystemExit(f"{run.path}: no model.strike_pressure: fit it first (--pressure)")
    try:
        shots = fit.which == "shots"
        model = with_strike_shots(model) if shots else with_strike_players(model)
    except ValueError as exc:
        raise SystemExit(f"{run.path}: {exc}") from None
    val = held_out(states)
    before = shot_profile(model, states, val)
    # A row per player: weight decay holds the rows of players with few strikes near 0.
    history = fit_strike_inputs(model, states, ("shot",)) if shots else \
        fit_strike_inputs(model, states, ("players",), steps=4000, weight_decay=0.01)
    print(f"held-out NLL {history[0]['val_nll']:.4f} -> "
          f"{min(h['val_nll'] for h in history):.4f} nats a strike")
    after = shot_profile(model, states, val)
    both = before.merge(after, on=["shot_row", "serve", "n"], suffixes=("", "_shots"))
    print(both.drop(columns=[c for c in both.columns if c.endswith("record_m_shots")])
          .round(3).to_string(index=False))
    table = fit_strike_pressure(model, states, states.returns(),
                                prior_strikes=fit.prior_strikes)
    table.insert(0, "player", table.pop("id").map(names))
    print(table[["table", "player", "receiver", "n"] + ERROR_COLUMNS].round(3)
          .to_string(index=False))
    return model


# The fits in turn: which -> (the table the file must have, the flag that fits it, the table
# added, its fit).
IN_TURN = {
    "shape": ("strike_pressure", "--pressure", with_strike_shape, fit_strike_shape),
    "late": ("strike_pressure", "--pressure", with_strike_late, fit_strike_pressure),
    "depth": ("strike_pressure", "--pressure", with_strike_depth, fit_strike_pressure),
    "pressure": ("strike_return", "--returns", with_strike_pressure, fit_strike_pressure),
}


def _fit_in_turn(model: SportsNGEN, states: HeadStates, fit: StrikeFit, run: TableRun,
                 names: dict) -> SportsNGEN:
    """`shape`, `late`, `depth`, `pressure`: tables fitted in turn over the strikes that are
    not returns, on top of the one the file must already have."""
    needs, fit_first, add, fit_table = IN_TURN[fit.which]
    if getattr(model, needs) is None:
        raise SystemExit(f"{run.path}: no model.{needs}: fit it first ({fit_first})")
    model = add(model)
    kw = {"late_only": True} if fit.which == "late" and fit.late_only else \
        {"depth_only": True} if fit.which == "depth" else {}
    if fit.draws and fit.which != "shape":
        kw["draws"] = fit.draws
    table = fit_table(model, states, states.returns(), prior_strikes=fit.prior_strikes, **kw)
    ids = table.pop("id")
    table.insert(0, "player", ids.map(names) if fit.which != "depth" else
                 ids.map(lambda b: f"depth band {b}"))
    cols = list(table.columns) if fit.which == "shape" else \
        ["table", "player", "receiver", "n"] + ERROR_COLUMNS
    print(table[cols].round(3).to_string(index=False))
    if fit.which == "depth":
        print("centred table (band x role x long/wide/net):\n"
              + str(model.strike_depth.numpy().round(3)))
    return model


def _fit_hitters(model: SportsNGEN, states: HeadStates, fit: StrikeFit, run: TableRun,
                 names: dict) -> SportsNGEN:
    """The hitters' table (with `returns` split into the returns' own), then with `width`
    the width of the balls in play."""
    if fit.which == "returns":
        if model.strike_bias is None:
            raise SystemExit(f"{run.path}: no per-hitter table to split (model.strike_bias): "
                             "fit it first")
        model = with_strike_return(model)
        returns = states.returns()
        print(f"{int(returns.sum())} returns among them")
        table = fit_strike_return(model, states, returns, prior_strikes=fit.prior_strikes)
        role = "is_return"
    else:
        model = with_strike_bias(model)
        table = fit_strike_bias(model, states, prior_strikes=fit.prior_strikes)
        role = "receiver"
    shares = error_shares(table)
    table.insert(0, "hitter", table["hitter_id"].map(names))
    for col in ("error_record", "error_head", "error_after"):
        table[col] = shares[col]
    cols = ["hitter", role, "n", "error_record", "error_head", "error_after",
            "long_shift", "wide_shift", "net_shift"]
    print(table[cols].round(3).to_string(index=False))
    if fit.which == "width":
        model = with_strike_width(model)
        width = fit_strike_width(model, states, prior_strikes=fit.prior_strikes)
        width.insert(0, "hitter", width["hitter_id"].map(names))
        print(width.drop(columns="hitter_id").round(3).to_string(index=False))
    return model


def _fit_surface(model: SportsNGEN, states: HeadStates, fit: StrikeFit, names: dict,
                 surfaces: list[str]) -> SportsNGEN:
    """`surface`: the hitters' surfaces table added (or zeroed) and fitted on top of the
    model's other tables -> the model."""
    if model.strike_bias is None:
        raise SystemExit("--surface needs the hitters' table (model.strike_bias): fit it first")
    model = with_strike_surface(model)
    try:
        table = fit_strike_surface(model, states, prior_strikes=fit.prior_strikes,
                                   draws=fit.draws)
    except ValueError as exc:
        hint = f" (remove {fit.states})" if fit.states else ""
        raise SystemExit(f"{exc}{hint}") from None
    table.insert(0, "player", table.pop("id").map(names))
    table["surface"] = table["surface"].map(dict(enumerate(surfaces)))
    print(table[["player", "surface", "stroke", "n"] + ERROR_COLUMNS].round(3)
          .to_string(index=False))
    return model
