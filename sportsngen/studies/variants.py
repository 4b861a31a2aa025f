"""Variants of one training: frozen data, Hydra overrides, a cached result per run.

A study trains several variants that must differ only in their overrides: the data are frozen
first into a `RallyData` folder (a cached synthetic set is regenerated whenever the
generator's profiles or version change, which must not happen between two variants), and each
run's result (training time, parameter count, overrides, metrics) is kept in
`<run dir>/result.json`, reused unless forced.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

from hydra import compose, initialize_config_dir
from omegaconf import DictConfig

from sportsngen.data.tracking import RallyData
from sportsngen.train.evaluate import CONF_DATA
from sportsngen.train.run import train_from_config


def compose_train(overrides: list[str]) -> DictConfig:
    """conf/train.yaml with Hydra `overrides`, as `python train.py <overrides>` composes it."""
    with initialize_config_dir(config_dir=str(CONF_DATA.parent), version_base=None):
        return compose(config_name="train", overrides=overrides)


def freeze_data(dest: Path, load: Callable[[], RallyData]) -> Path:
    """`dest`, holding `load()`'s rallies (saved once: a later study reuses the folder)."""
    if not (dest / "meta.json").is_file():
        load().save(dest)
    return dest


def train_variant(overrides: list[str], out_dir: Path) -> dict:
    """`train_from_config` of the composed overrides into out_dir; -> wall time (s),
    parameter count, overrides."""
    cfg = compose_train(overrides)
    t0 = time.perf_counter()
    summary = train_from_config(cfg, out_dir)
    return {"train_wall_s": time.perf_counter() - t0, "n_params": summary["n_params"],
            "overrides": overrides}


def run_variant(out_dir: Path, overrides: list[str], labels: dict,
                evaluate: Callable[[Path], dict], force: bool = False,
                tag: str = "study") -> dict:
    """Train one variant (unless out_dir/result.json exists and not `force`) and score its
    model file with `evaluate`; -> {**labels, **train_variant's, **metrics}, also written to
    result.json."""
    result_path = out_dir / "result.json"
    if result_path.is_file() and not force:
        return json.loads(result_path.read_text())
    name = " ".join(f"{k} {v}" if k in ("steps", "seed") else str(v) for k, v in labels.items()
                    if k != "note")
    print(f"[{tag}] training {name}", flush=True)
    res = {**labels, **train_variant(overrides, out_dir)}
    res.update(evaluate(out_dir / "model.pt"))
    result_path.write_text(json.dumps(res, indent=2))
    print(f"[{tag}] {name}: ball {res['nll_ball']:.3f} player {res['nll_player']:.3f} "
          f"({res['train_wall_s']:.0f} s)", flush=True)
    return res
