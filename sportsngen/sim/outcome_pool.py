"""`rally_win_probabilities` spread over worker processes, with results that do not depend on
how many.

A branch point's rollouts share their random stream with the other branch points of their call
(`sportsngen.sim.whatif`: branches of one prefix length are one batch), so a split by worker
would change every estimate with the number of workers. The items are therefore cut into fixed
chunks of `chunk_items` in the order given; chunk `k` is always one `rally_win_probabilities`
call with seed `seed + CHUNK_SEED_STEP * k`, whichever process runs it. Each worker loads the
model file once (`Simulator.from_pretrained`) and holds the recorded rallies it branches.
`chunk_items=0` makes all the items one chunk: one call with `seed`, the estimates of
`rally_win_probabilities` itself (and one process).
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor

import pandas as pd
import torch
from tqdm.auto import tqdm

from sportsngen.data.tracking import RallyData
from sportsngen.errors import check_int
from sportsngen.workers import pool_context

CHUNK_SEED_STEP = 7919

_WORKER: dict = {}


def _start_worker(model: str | None, sim_kwargs: dict, data: RallyData, threads: int) -> None:
    from sportsngen.sim.simulator import Simulator

    torch.set_num_threads(threads)
    _WORKER["sim"] = Simulator.from_pretrained(model, **sim_kwargs)
    _WORKER["data"] = data


def _run_chunk(job: tuple[list, int, int]) -> pd.DataFrame:
    from sportsngen.sim.whatif import rally_win_probabilities

    items, n, seed = job
    return rally_win_probabilities(_WORKER["sim"], _WORKER["data"], items, n=n, seed=seed)


def chunk_jobs(items: list, n: int, seed: int, chunk_items: int) -> list[tuple[list, int, int]]:
    """The fixed chunks: (items, n, seed of the chunk), in the order of `items`; `chunk_items`
    0: one chunk of all."""
    chunk_items = chunk_items or max(len(items), 1)
    return [(items[i:i + chunk_items], n, seed + CHUNK_SEED_STEP * k)
            for k, i in enumerate(range(0, len(items), chunk_items))]


def pooled_rally_win_probabilities(model: str | None, data: RallyData, items, n: int = 100,
                                   seed: int = 0, workers: int = 2, threads: int = 1,
                                   chunk_items: int = 32, sim_kwargs: dict | None = None,
                                   progress: bool = True) -> pd.DataFrame:
    """`rally_win_probabilities` of the model file `model` (None: the bundled model) for the
    (rally_id, frame) pairs `items`, in `workers` processes of `threads` threads each -> the
    same columns, one row a pair in the order given. The result depends on `chunk_items` and
    `seed`, not on `workers`; `workers=1` runs the chunks in this process."""
    items = [(int(r), int(f)) for r, f in items]
    workers = check_int("workers", workers, 1)
    threads = check_int("threads", threads, 1)
    chunk_items = check_int("chunk_items", chunk_items, 0)
    jobs = chunk_jobs(items, n, seed, chunk_items)
    kwargs = dict(sim_kwargs or {})
    bar = tqdm(total=len(jobs), desc="branch chunks", disable=not progress)
    if workers == 1:
        _start_worker(model, kwargs, data, torch.get_num_threads())
        parts = []
        for job in jobs:
            parts.append(_run_chunk(job))
            bar.update(1)
    else:
        with ProcessPoolExecutor(min(workers, len(jobs)), mp_context=pool_context(__name__),
                                 initializer=_start_worker,
                                 initargs=(model, kwargs, data, threads)) as pool:
            parts = []
            for part in pool.map(_run_chunk, jobs):
                parts.append(part)
                bar.update(1)
    bar.close()
    _WORKER.clear()
    if not parts:
        return pd.DataFrame(columns=["rally_id", "frame", "p", "n", "n_sims", "n_unrealistic"])
    return pd.concat(parts, ignore_index=True)
