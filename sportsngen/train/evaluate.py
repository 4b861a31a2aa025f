"""Held-out evaluation of an exported model file (what `scripts/evaluate_model.py` runs).

The held-out rallies are those the training data module put in validation: the same data, the
same `split_rallies(arrays, val_fraction, seed)`. A model file written by `train.py` records
its data config, seed and validation fraction (`extra["split"]`); each can be overridden.

With `continuous=True` also the continuous NLL of the density the sampler draws from, which
compares across binnings (`sportsngen.studies.heads`): a bin chosen with probability p, then
a point uniform inside it, has density p / prod(widths), so per object token

    continuous NLL = discrete NLL + sum over dimensions of log(width of the target bin in m).

A target beyond the bin range falls in an edge bin (`Bins.index` clamps) where the sampler puts
no mass at all; it is scored with the edge bin's width and counted (`out-of-range share`). The
constant-velocity Gaussian (per-dimension sigma fitted on the same tokens, as in
`sportsngen.train.metrics`) is scored as a true continuous density: it does not depend on the
binning, so equal values across variants show that every variant is scored on the same tokens.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import torch
from omegaconf import OmegaConf
from torch.utils.data import DataLoader

from sportsngen.data.paths import conf_dir
from sportsngen.data.tokens import rally_arrays
from sportsngen.model.export import load_model, read_extra
from sportsngen.model.inputs import BALL
from sportsngen.train.datamodule import (
    data_fingerprint,
    load_rally_data,
    split_positions,
    split_rallies,
)
from sportsngen.train.finetune import check_data_matches, player_rallies
from sportsngen.train.metrics import (
    CV_SIGMAS_M,
    PARTS,
    NextFrameMetrics,
    evaluate_windows,
    window_states,
)
from sportsngen.train.windows import WindowDataset

CONF_DATA = conf_dir() / "data"
LOG_2PI = math.log(2.0 * math.pi)


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
                      batch_size: int = 32, device: str = "cpu",
                      continuous: bool = False) -> dict:
    """Next-frame metrics (`NextFrameMetrics.compute()`) of the model file on held-out rallies;
    with `continuous`, also `ContinuousNLL.compute()`'s continuous NLL and out-of-range shares.

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
    model = model.to(device)
    stats = continuous_windows(model, loader) if continuous else evaluate_windows(model, loader)
    stats.update({"n_rallies": len(held), "held_out_fraction": frac, "seed": seed,
                  "data": data_cfg.get("name") or data_cfg.get("path") or data_cfg["source"]})
    return stats


def gaussian_nll_grid(err_m: torch.Tensor) -> torch.Tensor:
    """(N, dims) errors -> (sigmas, dims) summed Gaussian NLL (nats) for each sigma in
    CV_SIGMAS_M: the continuous constant-velocity reference, sigma picked afterwards."""
    s = CV_SIGMAS_M[:, None, None]
    e = err_m.double()[None]
    return (0.5 * (e / s) ** 2 + torch.log(s) + 0.5 * LOG_2PI).sum(dim=1)


class ContinuousNLL:
    """Token sums of the continuous NLL, the out-of-range count and the constant-velocity
    Gaussian's NLL grid, per part (`PARTS`: players, ball in flight, ball at contact)."""

    def __init__(self) -> None:
        dims = {"player": 2, "flight": 3, "contact": 3}
        self.dims = dims
        self.sums = {p: {"n": 0, "cont": 0.0, "disc": 0.0, "oor": 0,
                         "cv": torch.zeros(len(CV_SIGMAS_M), dims[p], dtype=torch.float64)}
                     for p in PARTS}

    @torch.no_grad()
    def update(self, model, batch: dict, h: torch.Tensor) -> None:
        """Add one batch (a `WindowDataset` collate; `h` the decoder's output)."""
        pos, vel, nxt = batch["pos_m"], batch["vel_mps"], batch["next_pos_m"]
        p_idx, b_idx = model.target_bins(pos, vel, nxt, batch.get("prev_vel_mps"))
        p_nll, b_nll = model.nll(h, p_idx, b_idx)
        off = nxt - model.centres(pos, vel, batch.get("prev_vel_mps"))
        cv_err = nxt - (pos + vel / model.cfg.fps)
        m = batch["has_next"].bool()
        near = batch["near_contact"].bool()
        selections = {
            "player": (model.player_bins, p_idx[m], p_nll[m], off[..., :BALL, :2][m],
                       cv_err[..., :BALL, :2][m]),
        }
        for part, sel in (("flight", m & ~near), ("contact", m & near)):
            selections[part] = (model.ball_bins, b_idx[sel], b_nll[sel],
                                off[..., BALL, :][sel], cv_err[..., BALL, :][sel])
        for part, (bins, idx, nll, o, e) in selections.items():
            d = self.dims[part]
            idx, nll = idx.reshape(-1, d), nll.reshape(-1)
            o, e = o.reshape(-1, d), e.reshape(-1, d)
            log_w = torch.log(bins.width(idx).double()).sum(-1)
            out = ((o < bins.edges[:, 0]) | (o > bins.edges[:, -1])).any(-1)
            s = self.sums[part]
            s["n"] += nll.numel()
            s["disc"] += float(nll.double().sum())
            s["cont"] += float((nll.double() + log_w).sum())
            s["oor"] += int(out.sum())
            s["cv"] += gaussian_nll_grid(e)

    def compute(self, discrete: dict) -> dict:
        """Per-token means; `discrete` is `NextFrameMetrics.compute()` of the same tokens, whose
        NLLs the sums here must reproduce (else the token selections differ)."""
        sums = self.sums
        res = {}
        n_ball = sums["flight"]["n"] + sums["contact"]["n"]
        cv_ball = sums["flight"]["cv"] + sums["contact"]["cv"]
        best_b = cv_ball.argmin(dim=0)[None]
        best_p = sums["player"]["cv"].argmin(dim=0)[None]
        res["cont_nll_player"] = sums["player"]["cont"] / sums["player"]["n"]
        res["cont_nll_ball"] = (sums["flight"]["cont"] + sums["contact"]["cont"]) / n_ball
        res["oor_player"] = sums["player"]["oor"] / sums["player"]["n"]
        res["oor_ball"] = (sums["flight"]["oor"] + sums["contact"]["oor"]) / n_ball
        res["cv_cont_nll_player"] = float(sums["player"]["cv"].gather(0, best_p).sum()) / \
            sums["player"]["n"]
        res["cv_cont_nll_ball"] = float(cv_ball.gather(0, best_b).sum()) / n_ball
        for part in ("flight", "contact"):
            s = sums[part]
            res[f"cont_nll_ball_{part}"] = s["cont"] / s["n"] if s["n"] else math.nan
            res[f"oor_ball_{part}"] = s["oor"] / s["n"] if s["n"] else math.nan
            res[f"cv_cont_nll_ball_{part}"] = float(s["cv"].gather(0, best_b).sum()) / s["n"] \
                if s["n"] else math.nan
        for mine, theirs in (("player", "nll_player"), ("flight", "nll_ball_flight")):
            if abs(sums[mine]["disc"] / sums[mine]["n"] - discrete[theirs]) > 1e-5:
                raise RuntimeError(f"discrete NLL mismatch for {mine}: token selection differs")
        return res


@torch.no_grad()
def continuous_windows(model, loader) -> dict:
    """`evaluate_windows`' metrics and `ContinuousNLL`'s of `model` (eval mode) in one pass."""
    model.eval()
    disc, cont = NextFrameMetrics(), ContinuousNLL()
    device = next(model.parameters()).device
    for batch in loader:
        batch = {k: v.to(device) if isinstance(v, torch.Tensor) else v for k, v in batch.items()}
        h = window_states(model, batch)
        disc.update(model, batch, h)
        cont.update(model, batch, h)
    res = disc.compute()
    return {**res, **cont.compute(res)}


def format_or_na(v: float | None, fmt: str = ".3f") -> str:
    """`v` formatted, or "n/a" for None or NaN (a part without tokens)."""
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
    f = format_or_na
    for label, n, suffix in rows:
        lines.append(f"| {label} | {int(n)} | {f(stats[f'nll_ball{suffix}'])} | "
                     f"{f(stats[f'cv_nll_ball{suffix}'])} | {f(stats[f'acc_ball{suffix}'])} | "
                     f"{f(stats[f'cv_acc_ball{suffix}'])} |")
    lines.append(f"| players | {int(stats['n_player_tokens'])} | {f(stats['nll_player'])} | "
                 f"{f(stats['cv_nll_player'])} | {f(stats['acc_player'])} | "
                 f"{f(stats['cv_acc_player'])} |")
    return lines


def print_held_out(model: str, data: str | None = None, held_out_fraction: float | None = None,
                   seed: int | None = None, batch_size: int = 32, device: str = "cpu",
                   threads: int | None = None, json_path: str | None = None) -> dict:
    """`evaluate_held_out` printed as `metrics_table` (what `scripts/evaluate_model.py` shows);
    with `json_path`, every figure also written there as JSON."""
    if threads:
        torch.set_num_threads(threads)
    stats = evaluate_held_out(model, data, held_out_fraction, seed, batch_size, device)
    print(f"{model} on {stats['n_rallies']} held-out rallies of {stats['data']} "
          f"(fraction {stats['held_out_fraction']:g}, seed {stats['seed']}); NLL in nats per "
          "object token.\n")
    print("\n".join(metrics_table(stats)))
    print(f"\nCV sigma fitted (m): players {stats['cv_sigma_player_m']}, "
          f"ball {stats['cv_sigma_ball_m']}")
    if json_path:
        with open(json_path, "w") as fh:
            json.dump(stats, fh, indent=2)
    return stats


__all__ = ["ContinuousNLL", "data_config", "evaluate_held_out", "format_or_na", "metrics_table",
           "print_held_out"]


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
