"""What the scripts that fit a table onto a model file share: their arguments (`model_parser`,
`table_parser` for the fits by matching, `rule_table_parser` for a rule's table in the extra),
the file loaded with the rallies it was trained on (`open_table_run`), the result written with
everything else in the file unchanged (`TableRun.save`), the players' names by token id, and
sampling defaults read from KEY=VALUE words (`set_sim_defaults`)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import torch

from sportsngen.errors import ArgumentError
from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.export import load_model, read_extra, save_model
from sportsngen.model.inputs import N_SPECIAL_IDS
from sportsngen.sim.simulator import Simulator, model_path
from sportsngen.train.evaluate import training_arrays


def model_parser(doc: str) -> argparse.ArgumentParser:
    """--model (default: the bundled file) and --out, described by `doc`'s first line."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--model", default=None, help="model file (default: the bundled one)")
    ap.add_argument("--out", required=True, help="where to write the model file")
    return ap


def table_parser(doc: str, prior_flag: str | None = None, prior_default: float = 0.0,
                 prior_help: str = "", data_help: str = "also read every rally of this data "
                 "config (conf/data/NAME.yaml)") -> argparse.ArgumentParser:
    """--model, --out, --more-data, the prior's flag (`--prior-...`, where one is named) and
    --threads."""
    ap = model_parser(doc)
    ap.add_argument("--more-data", default=None, help=data_help)
    if prior_flag:
        ap.add_argument(prior_flag, type=float, default=prior_default, help=prior_help)
    ap.add_argument("--threads", type=int, default=2)
    return ap


def rule_table_parser(doc: str, options: tuple = ()) -> argparse.ArgumentParser:
    """--model, --out and --more-data of a script that writes a rule's table, and its own
    `options`: (flag, type, default, help) each."""
    ap = model_parser(doc)
    ap.add_argument("--more-data", default=None,
                    help="also read every rally of this data config (conf/data/NAME.yaml)")
    for flag, kind, default, text in options:
        ap.add_argument(flag, type=kind, default=default, help=text)
    return ap


@dataclass
class TableRun:
    """A model file opened for a table's fit: the model and what is written back with it."""

    path: Path
    model: SportsNGEN
    event_model: object
    vocab: object
    extra: dict
    arrays: list          # RallyArrays: the training split (and --more-data)

    def save(self, model: SportsNGEN, out: str) -> None:
        save_model(out, model, self.vocab, self.event_model, extra=self.extra)
        print(f"wrote {out}")


def open_table_run(model: str | None, more_data: str | None, threads: int,
                   unfit: Callable[[SportsNGEN], str | None]) -> TableRun:
    """Load the model file `model` (None: the bundled one) with its training rallies (and
    `more_data`'s); exits with the reason where the file records no split, or where
    `unfit(model)` names why the table cannot be fitted on it."""
    torch.set_num_threads(threads)
    path = model_path(model)
    net, ec, vocab, _ = load_model(path)
    why = unfit(net)
    if why:
        raise SystemExit(f"{path}: {why}")
    try:
        arrays = training_arrays(path, vocab, more_data)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    return TableRun(path, net, ec, vocab, read_extra(path), arrays)


def player_names(vocab) -> dict[int, str]:
    """Token id -> player name, as the fitted tables' `..._id` columns hold them."""
    return {N_SPECIAL_IDS + i: p for i, p in enumerate(vocab.players)}


def named_players(players: str | None, extra: dict) -> list[str]:
    """`players` (comma-separated) or else the named players of the file's training data
    (`extra.split`); exits where neither names one."""
    if players:
        names = [p.strip() for p in players.split(",") if p.strip()]
    else:
        names = list(extra.get("split", {}).get("data", {}).get("players", {}).get("named", []))
    if not names:
        raise SystemExit("no players: pass --players (the file's data names none)")
    return names


def parse_value(text: str) -> bool | float:
    """A sampling default's value: true / false, or a number."""
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    try:
        return float(text)
    except ValueError:
        raise ArgumentError(f"a value is true, false or a number, got {text!r}") from None


def set_sim_defaults(model: str | Path, values: list[str]) -> dict:
    """Store KEY=VALUE `values` among the model file's sampling defaults, keeping the others
    -> the file's defaults (`ArgumentError` on a value or key they cannot hold)."""
    pairs = dict(v.split("=", 1) if "=" in v else (v, "") for v in values)
    return Simulator.set_defaults(model, **{k: parse_value(v) for k, v in pairs.items()})
