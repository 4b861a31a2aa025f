"""Exact look-ahead within one match: the rallies its likely score paths lead to, simulated
ahead in worker processes while the match plays the rally it needs.

Why processes and not a batch. A match is sequential (a rally's context holds the score), so
the only way to play it faster on more cores is to play rallies before knowing they are
needed. In one batch that gains little on this machine's costs: a frame of 8 rallies costs
about 1.2 times one of 1 (the per-frame work is dispatch, not arithmetic), but a batch waits
for its longest rally, and a float32 matmul's last bit changes with the batch size (6e-7 between
1 and 16 rows, `docs/benchmarks.md`), so a rally played in a batch would not be the same rally
played alone. A rally played alone, from its own seed (`match.rally_seed`), is the same in
any process: the points table is identical with look-ahead on and off.

How. `Lookahead.play(path)` takes the match's likely path of rallies, the one needed now first
(`match.likely_path`). Each idle worker takes the first rally of the path no one holds; a
worker's rally that left the path is dropped when done. The calling process plays the rally it
needs itself unless a worker is playing it; then it plays the next free rally of the path
meanwhile.

What it buys: on this machine's 2 cores, a little. A best-of-1 six-game match (seed 1, 92
rallies, `bench/bench_lookahead.py`) took 80.5 s alone and 76.3 s with one worker: about half
the rallies played ahead were needed (24 of 48), and the calling process's own rallies took
about 12 % longer on average beside the worker. With the compiled frame (issue 19, fourth
step) `simulate.py`'s best-of-3 took 54.0 s alone and 50.0 s with one worker (two runs each,
the same match), so `simulate.py` takes one worker where there are 2 or more cores
(`lookahead=auto`, `lookahead_workers`); `simulate_matches` itself defaults to none.
With more cores more workers play further along the path. The workers are spawned
processes: a script that turns it on needs the `if __name__ == "__main__":` guard.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import pickle
import time
from concurrent.futures import Future, ProcessPoolExecutor

import pandas as pd

from sportsngen.data.tracking import RallyData
from sportsngen.errors import check_int

log = logging.getLogger(__name__)
_WORKER_SIM = None     # the worker process's Simulator (`_start_worker`)


def play_rally(sim, row: dict, seed: int) -> RallyData:
    """One rally of plan row `row` (`match._plan_row`'s columns) played from `seed`, alone
    (rally id 0): what both the calling process and the workers run."""
    plan = pd.DataFrame([row])
    plan.insert(0, "rally_id", [0])
    return sim.simulate_rallies(plan, seed=seed)


def _start_worker(sim_bytes: bytes) -> None:
    global _WORKER_SIM
    _WORKER_SIM = pickle.loads(sim_bytes)


def _worker_play(row: dict, seed: int) -> RallyData:
    return play_rally(_WORKER_SIM, row, seed)


class Lookahead:
    """`workers` processes that play a match's likely rallies ahead (module doc); `close()`
    it when the match is over."""

    def __init__(self, sim, workers: int = 1):
        self.workers = check_int("lookahead workers", workers, 1, 64)
        self.sim = sim
        self._pool = ProcessPoolExecutor(
            max_workers=self.workers, mp_context=multiprocessing.get_context("spawn"),
            initializer=_start_worker, initargs=(pickle.dumps(sim),))
        self._futures: dict[int, Future] = {}
        self._done: dict[int, RallyData] = {}
        self.played_here = 0       # rallies the calling process played
        self.taken_ahead = 0       # rallies needed that a worker (or an early turn) had played
        self.wasted = 0            # rallies played ahead that the match never needed
        self.waited_s = 0.0        # the calling process's time waiting on a worker
        self.here_s = 0.0          # ... and playing rallies itself

    def close(self) -> None:
        self.wasted += len(self._done) + sum(f.running() or f.done()
                                             for f in self._futures.values())
        self._pool.shutdown(wait=True, cancel_futures=True)
        log.info("look-ahead: %d rallies played here, %d taken played ahead, %d played ahead "
                 "unused; %.1f s playing, %.1f s waiting", self.played_here, self.taken_ahead,
                 self.wasted, self.here_s, self.waited_s)
        self._futures.clear()
        self._done.clear()

    def play(self, path: list[tuple[int, dict]]) -> RallyData:
        """The rally of `path[0]` ((seed, plan row) pairs, the needed rally first, then the
        likely ones after it) -> its RallyData, identical to `play_rally(sim, row, seed)`."""
        need = path[0][0]
        keep = {seed for seed, _ in path}
        for seed in [s for s in self._done if s not in keep]:
            del self._done[seed]
            self.wasted += 1
        while True:
            for seed, fut in list(self._futures.items()):
                if fut.done():
                    del self._futures[seed]
                    if seed in keep:
                        self._done[seed] = fut.result()
                    else:
                        self.wasted += 1
            if need in self._done:
                self.taken_ahead += 1
                return self._done.pop(need)
            self._prune(keep)
            fut = self._futures.get(need)
            if fut is None:
                self._feed(path[1:], None)
                return self._play_here(path[0])
            # A worker plays the needed rally: play the next free one of the path meanwhile.
            free = next((item for item in path[1:]
                         if item[0] not in self._done and item[0] not in self._futures), None)
            if free is None:
                t0 = time.perf_counter()
                fut.exception()               # wait; the loop above collects it
                self.waited_s += time.perf_counter() - t0
                continue
            self._feed(path[1:], free[0])
            self._done[free[0]] = self._play_here(free)

    def _play_here(self, item: tuple[int, dict]) -> RallyData:
        self.played_here += 1
        t0 = time.perf_counter()
        out = play_rally(self.sim, item[1], item[0])
        self.here_s += time.perf_counter() - t0
        return out

    def _prune(self, keep: set[int]) -> None:
        """Cancel the queued rallies that left the path (a running one finishes, unused)."""
        for seed, fut in list(self._futures.items()):
            if seed not in keep and fut.cancel():
                del self._futures[seed]

    def _feed(self, rest: list[tuple[int, dict]], mine: int | None) -> None:
        """Give each idle worker the first rally of `rest` no one holds (`mine`: the one the
        calling process is about to play). At most one rally a worker, so a future that runs
        is being played (the pool would start a queued one early, uncancellable)."""
        busy = len(self._futures)
        for seed, row in rest:
            if busy >= self.workers:
                break
            if seed == mine or seed in self._done or seed in self._futures:
                continue
            self._futures[seed] = self._pool.submit(_worker_play, row, seed)
            busy += 1


def lookahead_workers(setting, n_matches: int, cores: int | None = None) -> int:
    """`simulate.py`'s `lookahead` -> worker processes for `sim.lookahead`: a count, or "auto":
    one where a single match is played on a machine with 2 or more cores (`cores`, default
    the cores this process may run on), else none. On 2 cores a best-of-3 took 54.0 s
    without and 50.0 s with one worker, the same match (docs/benchmarks.md); several matches
    already play their rallies together."""
    if setting != "auto":
        workers = check_int("lookahead", setting, 0, 64)
    else:
        if cores is None:
            cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") \
                else (os.cpu_count() or 1)
        workers = 1 if cores >= 2 else 0
    return workers if n_matches == 1 else 0
