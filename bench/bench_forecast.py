"""The ball forecast's flight loop: compiled (`model.flight_kernel`, what `ball_forecast`
runs) against the same loop in torch operations (`ball_forecast_torch`), in one run.

    python bench/bench_forecast.py [--calls 300]

Random balls in flight (some spinning, some without a frame before), the path included as
the chase rule asks for it, one torch thread as a rollout of up to 8 rallies runs; ms a call,
and the largest difference between the two.
"""

from __future__ import annotations

import argparse
import time

import torch

from sportsngen.model.forecast import ball_forecast, ball_forecast_torch, random_flights


def ms_a_call(fn, args, calls: int) -> float:
    fn(*args, 25.0, path=True)
    t = time.perf_counter()
    for _ in range(calls):
        fn(*args, 25.0, path=True)
    return (time.perf_counter() - t) / calls * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=300)
    args = ap.parse_args()
    torch.set_num_threads(1)
    t = time.perf_counter()
    ball_forecast(*random_flights(2), 25.0, path=True)
    print(f"first call (numba: compile, or load its cache): {time.perf_counter() - t:.2f} s")
    print("| balls | torch ms | compiled ms | speed-up | max abs diff m |")
    print("|---:|---:|---:|---:|---:|")
    for n in (1, 8, 64, 256):
        x = random_flights(n, seed=n)
        a = ms_a_call(ball_forecast_torch, x, args.calls)
        b = ms_a_call(ball_forecast, x, args.calls)
        d = max((u - v).abs().max().item() for u, v in zip(
            ball_forecast_torch(*x, 25.0, path=True), ball_forecast(*x, 25.0, path=True)))
        print(f"| {n} | {a:.3f} | {b:.4f} | {a / b:.0f}x | {d:.1e} |")


if __name__ == "__main__":
    main()
