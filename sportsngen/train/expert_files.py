"""The expert's rallies written to a file to train on (`scripts/expert_data.py`; `train.py
init=<the same model> expert.path=<file>` mixes them in).

`write_expert_data`: branches of a generated data config's training split (the split
`train.py` makes with the same `val_fraction` and `split_seed`) rolled out by the model at its
stored sampling, the generator's players playing each rally on from the model's state
(`train.expert.expert_arrays`); or recorded shots whose ball flies on unstruck, answered by the
kernel (`late_contact_arrays`); or, with `fidelity`, only the expert measured on recorded
serves. `write_simulated_answers`: whole simulated points (`RallyData` folders, e.g.
`check_simulation.py --save-sim`) answered at every shot of `shots` from 8 frames after the
shot before it (`eval.expert_answers.simulated_expert_arrays`).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import torch

from sportsngen.data.tokens import RallyArrays, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.sim import Simulator
from sportsngen.synth.dataset import matchups
from sportsngen.train.datamodule import load_rally_data, split_positions
from sportsngen.train.evaluate import data_config
from sportsngen.train.expert import (
    ExpertConfig,
    expert_arrays,
    late_contact_arrays,
    save_expert,
    serve_return_fidelity,
)


def _written(out: RallyArrays, path: str | Path, counts: dict, t0: float) -> Path:
    """`out` saved at `path`, its counts printed with the frames and seconds."""
    path = save_expert(out, path)
    counts["frames"] = int(out.length.sum())
    counts["seconds"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(counts))
    print(f"wrote {path}")
    return path


def write_expert_data(model: str | None, out: str | None, data: str = "synthetic_small",
                      config: ExpertConfig | None = None, val_fraction: float = 0.1,
                      split_seed: int = 0, fidelity: list[int] | None = None,
                      late_contacts: list[int] | None = None,
                      threads: int | None = None) -> Path | None:
    """The expert's rallies on the model file `model`'s rollouts of `data`'s training split
    (`config`: branches, frames, seed) written to `out` (.npz); with `late_contacts` (frame
    delays) the kernel's answers to recorded shots instead; with `fidelity` (frames after the
    branch, [] for 2 and 6) only the share of recorded serves the kernel returns printed,
    nothing written. -> the path written."""
    if threads:
        torch.set_num_threads(threads)
    config = config or ExpertConfig()
    cfg = data_config(data)
    if cfg.get("source") != "synthetic":
        raise SystemExit(f"--data {data} is not generated: the expert is the generator, "
                         "whose players must be the data's")
    t0 = time.perf_counter()
    rallies = load_rally_data(cfg)
    profiles = {p.name: p for pair in matchups(cfg) for p in pair}
    sim = Simulator.from_pretrained(model)
    arrays = rally_arrays(rallies, sim.vocab, unknown="generic")
    train, _ = split_positions(len(arrays), val_fraction, split_seed)
    if fidelity is not None:
        for k in fidelity or [2, 6]:
            print(json.dumps(serve_return_fidelity(rallies, arrays, train, profiles, k,
                                                   n_branches=config.n_branches,
                                                   seed=config.seed)))
        return None
    if not out:
        raise SystemExit("--out is required (the .npz file to write)")
    if late_contacts:
        got, counts = late_contact_arrays(rallies, arrays, train, profiles,
                                          tuple(late_contacts), config.n_branches,
                                          config.keep_frames, config.seed, progress=True)
    else:
        got, counts = expert_arrays(sim, rallies, arrays, train, profiles, config,
                                    progress=True)
    return _written(got, out, counts, t0)


def write_simulated_answers(model: str | None, out: str | None, folders: list[str],
                            shots: tuple[int, ...] = (2, 3, 4, 5, 6), repeat: int = 1,
                            seed: int = 0, threads: int | None = None) -> Path:
    """The kernel's answers on the simulated points saved in `folders`, each rally written
    `repeat` times (its weight among the training windows), to `out` (.npz)."""
    from sportsngen.eval.expert_answers import simulated_expert_arrays

    if threads:
        torch.set_num_threads(threads)
    if not out or repeat < 1:
        raise SystemExit("--out is required and --repeat must be >= 1")
    t0 = time.perf_counter()
    sim = Simulator.from_pretrained(model)
    parts, counts = [], {}
    for folder in folders:
        data = RallyData.load(folder, validate=False)   # simulated: physics flagged, not refused
        arr, c = simulated_expert_arrays(data, sim.vocab, tuple(shots), seed=seed)
        parts += [arr] * repeat
        counts[str(folder)] = c
    return _written(RallyArrays.concat(parts), out, counts, t0)
