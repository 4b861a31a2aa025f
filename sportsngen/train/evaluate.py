"""Held-out evaluation of an exported model file (what `scripts/evaluate_model.py` runs).

The held-out rallies are those the training data module put in validation: the same data, the
same `split_rallies(arrays, val_fraction, seed)`. A model file written by `train.py` records
its data config, seed and validation fraction (`extra["split"]`); each can be overridden.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

from omegaconf import OmegaConf
from torch.utils.data import DataLoader

from sportsngen.data.tokens import WindowDataset, rally_arrays
from sportsngen.model.export import load_model, read_extra
from sportsngen.train.datamodule import (
    data_fingerprint,
    load_rally_data,
    split_positions,
    split_rallies,
)
from sportsngen.train.finetune import check_data_matches, player_rallies
from sportsngen.train.metrics import evaluate_windows

CONF_DATA = Path(__file__).resolve().parents[2] / "conf" / "data"


def data_config(spec: str | dict | None) -> dict:
    """A data config from a name of ``conf/data/<name>.yaml`` (synthetic_small, ...), a folder
    of tracking (`RallyData.save`), or a dict (returned as is)."""
    if isinstance(spec, dict):
        return dict(spec)
    if not spec:
        raise ValueError("no data given and the model file records none: pass --data")
    named = CONF_DATA / f"{spec}.yaml"
    if "/" not in spec and named.is_file():
        return OmegaConf.to_container(OmegaConf.load(named), resolve=True)
    if Path(spec).expanduser().is_dir():
        return {"source": "folder", "path": str(Path(spec).expanduser())}
    known = sorted(p.stem for p in CONF_DATA.glob("*.yaml"))
    raise ValueError(f"data {spec!r} is neither a config in conf/data ({known}) nor a folder")


def evaluate_held_out(model_path: str | Path, data: str | dict | None = None,
                      held_out_fraction: float | None = None, seed: int | None = None,
                      batch_size: int = 32, device: str = "cpu") -> dict:
    """Next-frame metrics (`NextFrameMetrics.compute()`) of the model file on held-out rallies.

    `data`, `held_out_fraction` and `seed` default to what the model file recorded (else 0.1
    and 0); a fraction of 1 evaluates every rally (data the model never saw).
    """
    model, _, vocab, cfg = load_model(model_path, map_location=device)
    split = read_extra(model_path).get("split") or {}
    data_cfg = data_config(data if data is not None else split.get("data"))
    frac = float(held_out_fraction if held_out_fraction is not None
                 else split.get("val_fraction", 0.1))
    seed = int(seed if seed is not None else split.get("seed", 0))
    if not 0.0 < frac <= 1.0:
        raise ValueError(f"held-out fraction must be in (0, 1], got {frac}")
    tracking = load_rally_data(data_cfg)
    check_data_matches(cfg, vocab, tracking)
    if split.get("player") and data is None:  # a fine-tuned model: the player's rallies
        tracking = player_rallies(tracking, split["player"], split.get("n_sequences"))
    recorded = split.get("fingerprint")
    if recorded and frac < 1.0 and data_fingerprint(tracking) != recorded:
        msg = (f"the data loaded for {data_cfg.get('name') or data_cfg['source']} differ from "
               "the data the model was trained on (regenerated after the generator's profiles "
               "or version changed?), so the held-out split would mix in training rallies")
        if data is None:
            raise ValueError(msg + "; pass the data explicitly to evaluate anyway")
        warnings.warn(msg, stacklevel=2)
    arrays = rally_arrays(tracking, vocab, cfg.unknown)
    held = arrays if frac >= 1.0 else split_rallies(arrays, frac, seed)[1]
    loader = DataLoader(WindowDataset(held, cfg.window_frames, None), batch_size=batch_size)
    stats = evaluate_windows(model.to(device), loader)
    stats.update({"n_rallies": len(held), "held_out_fraction": frac, "seed": seed,
                  "data": data_cfg.get("name") or data_cfg.get("path") or data_cfg["source"]})
    return stats


def _f(v: float, fmt: str) -> str:
    return "n/a" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, fmt)


def metrics_table(stats: dict) -> list[str]:
    """Markdown lines: per object kind, the model's and the constant-velocity reference's
    per-token NLL (nats) and top-1 bin accuracy."""
    lines = [
        "| object | tokens | model NLL | CV NLL | model top-1 | CV-bin top-1 |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    n_ball = stats["n_ball_flight"] + stats["n_ball_contact"]
    rows = [("ball (all frames)", n_ball, ""), ("ball in flight", stats["n_ball_flight"],
                                                "_flight"),
            ("ball at contact (+-1 frame)", stats["n_ball_contact"], "_contact")]
    for label, n, suffix in rows:
        lines.append(f"| {label} | {int(n)} | {_f(stats[f'nll_ball{suffix}'], '.3f')} | "
                     f"{_f(stats[f'cv_nll_ball{suffix}'], '.3f')} | "
                     f"{_f(stats[f'acc_ball{suffix}'], '.3f')} | "
                     f"{_f(stats[f'cv_acc_ball{suffix}'], '.3f')} |")
    lines.append(f"| players | {int(stats['n_player_tokens'])} | "
                 f"{_f(stats['nll_player'], '.3f')} | {_f(stats['cv_nll_player'], '.3f')} | "
                 f"{_f(stats['acc_player'], '.3f')} | {_f(stats['cv_acc_player'], '.3f')} |")
    return lines


__all__ = ["data_config", "evaluate_held_out", "metrics_table"]



def _recorded_split(model_path: str | Path) -> dict:
    split = read_extra(model_path).get("split")
    if not split or "data" not in split:
        raise ValueError(f"{model_path} records no training data split (extra.split)")
    return split


def split_arrays(model_path: str | Path, vocab) -> tuple:
    """The model file's own training and validation rallies (`extra.split`) -> (train, val)
    RallyArrays."""
    split = _recorded_split(model_path)
    return split_rallies(rally_arrays(load_rally_data(split["data"]), vocab),
                         float(split["val_fraction"]), int(split["seed"]))


def training_rally_data(model_path: str | Path, more_data: str | None = None) -> list:
    """`training_arrays`' rallies as tables: the file's training split (`extra.split`, the
    same rallies `split_arrays` keeps) and, with `more_data`, every rally of that data config
    -> [RallyData, ...]."""
    split = _recorded_split(model_path)
    data = load_rally_data(split["data"])
    train, _ = split_positions(len(data.rallies), float(split["val_fraction"]),
                               int(split["seed"]))
    parts = [data.subset(data.rallies["rally_id"].to_numpy()[train])]
    return parts + ([load_rally_data(data_config(more_data))] if more_data else [])


def training_arrays(model_path: str | Path, vocab, more_data: str | None = None) -> list:
    """The recorded rallies a per-player table is fitted on (`scripts/fit_serve_bias.py`,
    `scripts/fit_receiver_start.py`): the model file's own training split (`extra.split`) and,
    with `more_data`, every rally of that data config -> [RallyArrays, ...]."""
    train, _ = split_arrays(model_path, vocab)
    if not more_data:
        return [train]
    return [train, rally_arrays(load_rally_data(data_config(more_data)), vocab)]
