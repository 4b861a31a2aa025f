"""The command line of the scripts that fit a table onto a model file by matching
(`scripts/fit_serve_bias.py`, `scripts/fit_receiver_start.py`, `scripts/fit_contact_reach.py`):
the same arguments, the file loaded with the rallies it was trained on, the result written with
everything else in the file unchanged; and of those that write a rollout rule's table into the
file's extra (`scripts/fit_return_reach.py`, `scripts/fit_top_speed.py`: `rule_table_parser`,
`write_rule_tables`)."""

from __future__ import annotations

import argparse
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import torch

from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.export import load_model, read_extra, save_model, update_extra
from sportsngen.sim.simulator import Simulator, model_path
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


def rule_table_parser(doc: str, options: tuple = ()) -> argparse.ArgumentParser:
    """--model, --out and --more-data of a script that writes a rule's table, and its own
    `options`: (flag, type, default, help) each."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--model", default=None, help="model file (default: the bundled one)")
    ap.add_argument("--out", required=True, help="where to write the model file")
    ap.add_argument("--more-data", default=None,
                    help="also read every rally of this data config (conf/data/NAME.yaml)")
    for flag, kind, default, text in options:
        ap.add_argument(flag, type=kind, default=default, help=text)
    return ap


def write_rule_tables(src: Path, out: str, tables: dict[str, dict], **defaults) -> Path:
    """A copy of the model file `src` at `out` (the file itself where they are one) with
    `tables` in its extra and `defaults` among its sampling defaults; everything else as it
    was. -> the path written."""
    path = Path(out)
    if path.resolve() != Path(src).resolve():
        shutil.copyfile(src, path)
    update_extra(path, **tables)
    Simulator.set_defaults(path, **defaults)
    return path


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
