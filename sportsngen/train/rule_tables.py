"""Tables a rollout rule reads, measured on a model file's recorded rallies and written into a
copy of the file's extra with the sampling default that turns the rule on: each receiver's
reach for the return and each player's for the rally balls (`sim.reach_table`,
`scripts/fit_return_reach.py`), each player's top running speed (`sim.top_speed`,
`scripts/fit_top_speed.py`), where the players' offsets fall inside the player head's bins
(`model.bin_quantiles`, `scripts/fit_player_bins.py`); and the simulator's serve starts
rebuilt from other data (`data.serve_starts`, `scripts/add_initial_conditions.py`).

The rallies read are the file's training split and, with `more_data`, every rally of that
data config (`train.evaluate.training_rally_data`).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from sportsngen.data.serve_starts import MAX_PER_KEY_DEFAULT, N_FRAMES_DEFAULT, InitialConditions
from sportsngen.data.tracking import RallyData
from sportsngen.model.bin_quantiles import (
    MIN_OFFSETS,
    N_QUANTILES,
    fit_bin_quantiles,
    player_offsets,
)
from sportsngen.model.export import load_model, update_extra
from sportsngen.sim.reach_table import MIN_BALLS, reach_table_from_data
from sportsngen.sim.simulator import Simulator, model_path
from sportsngen.sim.top_speed import MIN_FRAMES, QUANTILE, top_speeds_from_data
from sportsngen.train.datamodule import load_rally_data
from sportsngen.train.evaluate import data_config, training_rally_data

# Each reach table's name in the file, its sampling default, and how its balls are printed.
REACH_TABLES = {"serve": ("return_reach", "return_reach_draw", "serves", "returned"),
                "rally": ("rally_reach", "rally_reach_draw", "rally balls", "answered")}


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


def _training_rallies(src: Path, more_data: str | None) -> list[RallyData]:
    try:
        return training_rally_data(src, more_data)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None


def fit_return_reach_file(model: str | None, out: str, more_data: str | None = None,
                          min_balls: int = MIN_BALLS, rally: bool = False,
                          serves_too: bool = False) -> Path:
    """Each receiver's reach for the return (with `rally` each player's for the rally balls
    instead, with `serves_too` both) fitted on the file `model`'s rallies and written into a
    copy at `out` (`extra.return_reach` / `extra.rally_reach`) with the default that draws
    from it; a player with fewer than `min_balls` good balls plays the pooled row."""
    src = model_path(model)
    parts = _training_rallies(src, more_data)
    kinds = ("serve", "rally") if serves_too else ("rally",) if rally else ("serve",)
    fitted = {}
    for kind in kinds:
        _, _, what, verb = REACH_TABLES[kind]
        table, balls = reach_table_from_data(parts, kind, min_balls)
        print(f"{len(balls)} good {what}, {balls['answered'].mean():.3f} {verb}")
        print(f"pooled: half {verb} at {table.pooled[0]:.3f} m, scale {table.pooled[1]:.3f} m")
        for name, (c, s) in sorted(table.players.items()):
            n = int((balls["player"] == name).sum())
            print(f"{name:<20} {n:6d} balls: half {verb} at {c:.3f} m, scale {s:.3f} m")
        fitted[kind] = table
    path = write_rule_tables(src, out,
                             {REACH_TABLES[k][0]: table.to_dict() for k, table in fitted.items()},
                             **{REACH_TABLES[k][1]: True for k in fitted})
    print(f"wrote {path}")
    return path


def fit_top_speed_file(model: str | None, out: str, more_data: str | None = None,
                       quantile: float = QUANTILE, min_frames: int = MIN_FRAMES) -> Path:
    """Each player's top running speed (the `quantile` of his frame-to-frame speeds; fewer
    than `min_frames` frames: the pooled one) read from the file `model`'s rallies and written
    into a copy at `out` (`extra.top_speed`, `player_top_speed=true`)."""
    src = model_path(model)
    parts = _training_rallies(src, more_data)
    try:
        table, speeds = top_speeds_from_data(parts, quantile, min_frames)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    print(f"{len(speeds)} player frames; pooled top speed {table.pooled_mps:.2f} m/s")
    counts = speeds["player"].value_counts()
    for name, v in sorted(table.players_mps.items()):
        print(f"{name:<20} {counts[name]:8d} frames: top speed {v:.2f} m/s")
    path = write_rule_tables(src, out, {"top_speed": table.to_dict()}, player_top_speed=True)
    print(f"wrote {path}")
    return path


def fit_player_bins_file(model: str | None, out: str, more_data: str | None = None,
                         quantiles: int = N_QUANTILES, min_offsets: int = MIN_OFFSETS) -> Path:
    """Where the players' offsets (in the model's frame) fall inside the player head's bins,
    `quantiles` quantiles a bin (fewer than `min_offsets` offsets: the uniform spread), read
    from the file `model`'s rallies and written into a copy at `out`
    (`extra.player_bin_quantiles`, `player_bin_quantiles=true`)."""
    src = model_path(model)
    net = load_model(src)[0]
    server_frame = net.cfg.frame != "world"
    parts = _training_rallies(src, more_data)
    try:
        offsets = np.concatenate([player_offsets(p.frames, p.rallies, server_frame)
                                  for p in parts])
        edges = net.player_bins.edges.double().numpy()
        table = fit_bin_quantiles(offsets, edges, quantiles, min_offsets)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    mid = table.shape[1] // 2
    print(f"{len(offsets)} player offsets in the model's frame")
    for k in range(mid, mid + 8):
        print(f"bin {k}: [{edges[1, k]:.4f}, {edges[1, k + 1]:.4f}] m, lateral quantiles "
              f"{' '.join(f'{v:.4f}' for v in table[1, k, ::quantiles // 4 or 1])}")
    path = write_rule_tables(src, out, {"player_bin_quantiles": table.tolist()},
                             player_bin_quantiles=True)
    print(f"wrote {path}")
    return path


def add_initial_conditions(model: str | Path, data: str, frames: int = N_FRAMES_DEFAULT,
                           per_key: int = MAX_PER_KEY_DEFAULT) -> InitialConditions:
    """Store in the model file `model` (in place) the serve starts of `data` (a RallyData
    folder or a conf/data config's name): each serve's first `frames` frames, at most
    `per_key` a key (`InitialConditions.from_rally_data`)."""
    if Path(data).is_dir():
        rallies = RallyData.load(data)
    else:
        rallies = load_rally_data(data_config(data))
    ic = InitialConditions.from_rally_data(rallies, frames, per_key)
    update_extra(model, initial_conditions=ic.to_dict())
    print(f"{model}: {len(ic)} initial conditions of {len(ic.servers)} servers, "
          f"{ic.n_frames} frames each")
    return ic
