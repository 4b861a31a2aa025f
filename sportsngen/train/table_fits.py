"""A per-player table fitted onto a model file as its script runs it: the file loaded with the
rallies it was trained on (`table_cli.open_table_run`: its training split, `extra.split`, and
with `more_data` every rally of that data config), the table added and fitted, its cells
printed, the file written to `out` with everything else in it unchanged.

- `fit_serve_bias_file`: the servers' long / wide / speed shifts (`train.serve_bias`; with
  `short` the short serves' shift, with `lateral` the lateral bands', on top of them);
- `fit_receiver_start_file`: the receiver's odds of starting his run (`train.receiver_start`);
- `fit_contact_reach_file`: a contact's odds by where the ball is (`train.contact_reach`);
- `fit_serve_aim_file`: the servers' aim, on the serves the model plays from its own tosses
  (`train.own_states`, `serve_bias.fit_serve_aim`);
- `refine_serve_bias_file`: the serve shifts moved by the model's own rollouts
  (`train.serve_bias_rollouts`);
- `fit_late_on_rollouts_file`: the late strikes' (or the rally balls', or the second serves')
  error shifts moved by rollouts against a truth (`train.rollout_tables`).
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
import torch

from sportsngen.data.tokens import rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.shot_profile import strike_endings
from sportsngen.model import contact_reach
from sportsngen.model.export import load_model, read_extra, save_model
from sportsngen.sim.simulator import Simulator, model_path
from sportsngen.train.contact_reach import (
    ContactStates,
    cell_table,
    collect_contact_states,
    fit_contact_reach,
    with_contact_reach,
)
from sportsngen.train.datamodule import load_rally_data
from sportsngen.train.evaluate import data_config, split_arrays
from sportsngen.train.head_fit import HeadStates, collect_head_states
from sportsngen.train.own_states import own_serve_states
from sportsngen.train.receiver_start import (
    WaitStates,
    collect_wait_states,
    fit_receiver_start,
    with_receiver_start,
)
from sportsngen.train.rollout_tables import (
    RALLY_STAGES,
    add_rollout_late_shift,
    add_rollout_rally_shift,
    add_rollout_second_shift,
    at_serve,
    rollout_error_gaps,
)
from sportsngen.train.serve_bias import (
    fit_serve_aim,
    fit_serve_bias,
    fit_serve_lateral,
    fit_serve_short,
    with_serve_aim,
    with_serve_bias,
    with_serve_lateral,
    with_serve_short,
)
from sportsngen.train.serve_bias_rollouts import refine_serve_bias
from sportsngen.train.strike_bias import with_strike_late, with_strike_second
from sportsngen.train.table_cli import named_players, open_table_run, player_names


def fit_serve_bias_file(model: str | None, out: str, more_data: str | None = None,
                        prior_serves: float = 100.0, threads: int = 2, short: bool = False,
                        lateral: bool = False) -> None:
    """The servers' shifts of the serve head's long and wide odds and speed, fitted on the
    recorded serves (windows also turned as training turns them) with `prior_serves`
    pseudo-serves at the head's own odds; with `short` (`lateral`), on a file that has them,
    the short serves' shift (the lateral bands') added and fitted, each long (wide) shift
    refitted beside it, the others left as they are."""
    run = open_table_run(model, more_data, threads, lambda m: None if m.serve_head is not None
                         else "no serve head (model.serve_head)")
    t0 = time.time()
    states = HeadStates.concat([collect_head_states(run.model, a, "serve", flip=True)
                                for a in run.arrays])
    print(f"{len(states)} recorded serves read ({time.time() - t0:.0f} s)")
    names = player_names(run.vocab)
    if lateral or short:
        flag, add, fit = ("--lateral", with_serve_lateral, fit_serve_lateral) if lateral else \
            ("--short", with_serve_short, fit_serve_short)
        if run.model.serve_bias is None:
            raise SystemExit(f"{run.path}: {flag} needs the serve table: fit it first")
        net = add(run.model)
        table = fit(net, states, prior_serves=prior_serves)
        table.insert(0, "server", table["server_id"].map(names))
        if lateral:
            by = table.groupby(["server", "serve"])
            wide = by.first()[["n", "wide_odds", "wide_after"]]
            for kind in ("record", "head", "after", "shift"):
                wide[kind] = by[kind].apply(lambda v: " ".join(f"{x:5.2f}" for x in v))
            print(wide.to_string())
        else:
            print(table.drop(columns=["server_id"]).round(3).to_string(index=False))
        run.save(net, out)
        return
    net = with_serve_bias(run.model)
    table = fit_serve_bias(net, states, prior_serves=prior_serves)
    table.insert(0, "server", table["server_id"].map(names))
    for kind in ("speed_record", "speed_head"):
        table[kind] *= 3.6                                     # km/h
    cols = ["server", "serve", "n", "long_record", "long_head", "long_shift", "wide_record",
            "wide_head", "wide_shift", "speed_record", "speed_head", "speed_shift"]
    print(table[cols].round(3).to_string(index=False))
    run.save(net, out)


def fit_receiver_start_file(model: str | None, out: str, more_data: str | None = None,
                            prior_frames: float = 200.0, threads: int = 2) -> None:
    """The servers' shifts of the receiver's odds of starting his run at the serve, fitted
    on the recorded waiting frames (turned as training turns them) with `prior_frames`
    pseudo-frames at the head's own odds."""
    run = open_table_run(model, more_data, threads, lambda m: None if m.cfg.head == "factorised"
                         else "the receiver's shift needs the factorised head")
    t0 = time.time()
    states = WaitStates.concat([collect_wait_states(run.model, a, flip=True)
                                for a in run.arrays])
    print(f"{len(states)} recorded waiting frames read ({time.time() - t0:.0f} s)")
    net = with_receiver_start(run.model)
    table = fit_receiver_start(net, states, prior_frames=prior_frames)
    table.insert(0, "server", table["server_id"].map(player_names(run.vocab)))
    for col in ("record", "head", "shift"):
        wide = table.pivot_table(index=["server", "serve"], columns="wait", values=col)
        print(f"\n{col} by frames waited:\n{wide.round(2).to_string()}")
    run.save(net, out)


def contact_grid(table: pd.DataFrame, col: str) -> str:
    """A cell table's column as frames-until-his-line rows by metres-aside columns."""
    def edges(e: tuple) -> list[str]:
        return [f"<{e[0]:g}"] + [f"{a:g}-{b:g}" for a, b in zip(e, e[1:])] + [f">{e[-1]:g}"]
    wide = table.pivot_table(index="frames_cell", columns="aside_cell", values=col)
    wide.index = [edges(contact_reach.FRAMES_EDGES)[i] for i in wide.index]
    wide.columns = [edges(contact_reach.ASIDE_EDGES_M)[i] for i in wide.columns]
    return wide.round(3).to_string()


def fit_contact_reach_file(model: str | None, out: str, more_data: str | None = None,
                           prior_frames: float = 20.0, threads: int = 2) -> None:
    """The shifts of a contact's odds by where the ball is from its hitter, fitted from zero
    with `prior_frames` pseudo-frames; the record's shares, the head's odds and the shifted
    odds printed per cell on the file's held-out split."""
    run = open_table_run(model, more_data, threads, lambda m: None if m.cfg.head == "factorised"
                         else "the contact table needs the factorised head")
    t0 = time.time()
    _, held_out = split_arrays(run.path, run.vocab)
    net = with_contact_reach(run.model)
    net.contact_reach.zero_()
    train = ContactStates.concat([collect_contact_states(net, a) for a in run.arrays])
    print(f"{len(train)} recorded frames of a ball coming to a player read "
          f"({time.time() - t0:.0f} s)")
    fit = fit_contact_reach(net, train, prior_frames=prior_frames)
    for col, what in (("shift", "a strike's"), ("shift_jolt", "a jolt's")):
        print(f"\n{what} shift (logits), frames until the hitter's line by metres aside:\n"
              f"{contact_grid(fit, col)}")
    held = cell_table(collect_contact_states(net, held_out), net.contact_reach)
    for col, what in (("n", "held-out frames"), ("record", "held-out record's share of "
                      "strikes"), ("head", "the head's odds"), ("shifted", "with the table"),
                      ("record_jolt", "the record's share of jolts"),
                      ("head_jolt", "the head's odds"), ("shifted_jolt", "with the table")):
        print(f"\n{what}:\n{contact_grid(held, col)}")
    run.save(net, out)


def fit_serve_aim_file(model: str | None, out: str, data: str = "synthetic_named",
                       players: str | None = None, max_rallies: int = 12000,
                       prior_serves: float = 100.0, seed: int = 0, threads: int = 2) -> None:
    """The servers' aim inside the box, fitted on the serves the model plays from its own
    tosses: at most `max_rallies` rallies of `data` served by `players` (comma-separated;
    default the file's named players), drawn with `seed`, each played once from the model's
    serve start and its state paired with the record's serve; the wide shift refitted to hold
    each server's wide faults. The file must have the serve table."""
    torch.set_num_threads(threads)
    path = model_path(model)
    net, ec, vocab, _ = load_model(path)
    if net.serve_bias is None:
        raise SystemExit(f"{path}: no serve table (model.serve_bias): run "
                         "scripts/fit_serve_bias.py first")
    extra = read_extra(path)
    servers = named_players(players, extra)
    for p in servers:
        vocab.player_index(p, unknown="error")
    t0 = time.time()
    rallies = load_rally_data(data_config(data))
    ids = rallies.rallies.loc[rallies.rallies["server"].isin(servers), "rally_id"].to_numpy()
    if not len(ids):
        raise SystemExit(f"no rally of {data} is served by {servers}")
    rng = np.random.default_rng(seed)
    ids = np.sort(rng.choice(ids, min(max_rallies, len(ids)), replace=False))
    rallies = rallies.subset(ids)
    print(f"{len(ids)} rallies of {data} ({time.time() - t0:.0f} s)")
    sim = Simulator.from_pretrained(path)
    _, own = own_serve_states(sim, rallies, rally_arrays(rallies, vocab), seed=seed,
                              progress=True)
    print(f"{len(own)} serves played from the model's own tosses ({time.time() - t0:.0f} s)")
    net = with_serve_aim(net)
    table = fit_serve_aim(net, own, prior_serves=prior_serves)
    table.insert(0, "server", table["server_id"].map(player_names(vocab)))
    table = table[table["server"].isin(servers)]
    print(table.drop(columns="server_id").round(3).to_string(index=False))
    save_model(out, net, vocab, ec, extra=extra)
    print(f"wrote {out}")


def refine_serve_bias_file(model: str | None, out: str, more_data: str | None = None,
                           threads: int = 2, players: str | None = None, serves: int = 400,
                           rounds: int = 3, seed: int = 0, csv: str | None = None) -> None:
    """Each named server's long and wide shifts moved until his rolled-out serves (`serves` a
    server, serve and round; `rounds` updates) fault as often as his record; the rounds'
    table written to `csv` where given."""
    run = open_table_run(model, more_data, threads, lambda m: None if m.serve_bias is not None
                         else "no per-server table (model.serve_bias): run "
                              "scripts/fit_serve_bias.py first")
    servers = named_players(players, run.extra)
    sim = Simulator.from_pretrained(run.path)
    t0 = time.time()
    table = refine_serve_bias(sim, run.arrays, servers, n_serves=serves, rounds=rounds,
                              seed=seed)
    print(f"({time.time() - t0:.0f} s)")
    last = table[table["round"] == rounds]
    print(last[["server", "serve", "record_n", "record_share", "rollout_n",
                "rollout_share"]].round(3).to_string(index=False))
    if csv:
        table.to_csv(csv, index=False)
    run.save(sim.model, out)


def fit_late_on_rollouts_file(model: str | None, out: str, pair: list[tuple[str, str]],
                              prior_strikes: float = 200.0, rally: bool = False,
                              second: bool = False) -> None:
    """The late strikes' error table (`model.strike_late`, added at zero where the file has
    none) moved by the log-odds gaps between each (rollouts, truth) folder `pair`'s error
    shares, pooled and shrunk by n / (n + `prior_strikes`); with `rally` the gaps over every
    strike after the return move the player's own table instead, with `second` those of
    second-serve points the second serves' table (`model.strike_second`)."""
    path = model_path(model)
    net, event_model, vocab, _ = load_model(path)
    if second:
        if net.strike_bias is None:
            raise SystemExit(f"{path}: no model.strike_bias, which the second serves' table "
                             f"adds to")
        net = with_strike_second(net)
    elif not rally:
        if net.strike_pressure is None:
            raise SystemExit(f"{path}: no model.strike_pressure, which the late table needs")
        net = with_strike_late(net)
    pairs = []
    for sim_dir, truth_dir in pair:
        sim = strike_endings(RallyData.load(sim_dir, validate=False), by_serve=second)
        truth = strike_endings(RallyData.load(truth_dir), by_serve=second)
        pairs.append((at_serve(sim, 2), at_serve(truth, 2)) if second else (sim, truth))
    add, stages = (add_rollout_second_shift, RALLY_STAGES) if second else \
        (add_rollout_rally_shift, RALLY_STAGES) if rally else (add_rollout_late_shift, None)
    try:
        gaps = rollout_error_gaps(pairs, stages) if stages else rollout_error_gaps(pairs)
        table = add(net, vocab, gaps, prior_strikes=prior_strikes)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    print(table.round(3).to_string())
    save_model(out, net, vocab, event_model, extra=read_extra(path))
    print(f"wrote {out}")
