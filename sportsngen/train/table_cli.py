"""The command line of the scripts that fit a table onto a model file by matching
(`scripts/fit_serve_bias.py`, `scripts/fit_receiver_start.py`, `scripts/fit_contact_reach.py`):
the same arguments, the file loaded with the rallies it was trained on, the result written with
everything else in the file unchanged."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import torch

from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.export import load_model, read_extra, save_model
from sportsngen.sim.simulator import model_path
from sportsngen.train.evaluate import training_arrays


def table_parser(doc: str, prior_flag: str | None = None, prior_default: float = 0.0,
                 prior_help: str = "", data_help: str = "also read every rally of this data "
                 "config (conf/data/NAME.yaml)") -> argparse.ArgumentParser:
    """--model, --out, --more-data, the prior's flag (`--prior-...`, where one is named) and
    --threads."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--model", default=None, help="model file (default: the bundled one)")
    ap.add_argument("--out", required=True, help="where to write the model file")
    ap.add_argument("--more-data", default=None, help=data_help)
    if prior_flag:
        ap.add_argument(prior_flag, type=float, default=prior_default, help=prior_help)
    ap.add_argument("--threads", type=int, default=2)
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


def open_table_run(args: argparse.Namespace,
                   unfit: Callable[[SportsNGEN], str | None]) -> TableRun:
    """Load `args.model` with its training rallies (exits with the reason where the file
    records no split, or where `unfit(model)` names why the table cannot be fitted on it)."""
    torch.set_num_threads(args.threads)
    path = model_path(args.model)
    model, ec, vocab, _ = load_model(path)
    why = unfit(model)
    if why:
        raise SystemExit(f"{path}: {why}")
    try:
        arrays = training_arrays(path, vocab, args.more_data)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    return TableRun(path, model, ec, vocab, read_extra(path), arrays)
