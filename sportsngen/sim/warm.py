"""Compile the numba kernels once, at install (`make setup`), by playing one rally with the
bundled model: numba caches each compiled kernel beside its source, and compiling them all
took 14 s of the first rally in a fresh clone (0.5 s once cached; docs/benchmarks.md, issue
19). `python -m sportsngen.sim.warm`."""

from __future__ import annotations

import time


def warm_kernels(n_rallies: int = 2, seed: int = 0) -> float:
    """Play `n_rallies` first serves of the bundled model, then one alone (every kernel a
    rally uses is compiled and cached on the way) -> the seconds it took. Both batch sizes,
    since numba compiles a kernel once per array layout: a frame sliced from a batch of one
    is contiguous, from a batch of two it is not."""
    from sportsngen.sim import Simulator

    start = time.perf_counter()
    sim = Simulator.from_pretrained()
    sim.simulate_points("Roger Federer", "Rafael Nadal", "hard", n_rallies, seed=seed,
                        serve_number=1)
    sim.simulate_points("Roger Federer", "Rafael Nadal", "hard", 1, seed=seed, serve_number=1)
    return time.perf_counter() - start


if __name__ == "__main__":
    print(f"kernels compiled and cached in {warm_kernels():.1f} s")
