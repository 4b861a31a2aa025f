"""Floors under issue 19's rollout targets: the least time the work could take on this machine.

    python bench/bench_floors.py [--threads 2]

A target below its floor cannot be met by faster code, only by less work (a different rollout
design or model) or a bigger machine; a target above it may be. The child process plays the
end-to-end bench's workloads (a 100-rollout rally win probability and a 2-option x 100
counterfactual: Roger Federer v Rafael Nadal on hard, a generated rally branched 10 frames
before its third shot) and counts every decoder pass they make:

- cached steps: rows x frames, and each step's FLOPs at its cache's length;
- full-window passes: the first pass over the initial frames, and the refreshes that fill the
  cache again from the last window once a rally outgrows it (`rollout(refresh_frames=...)`, 25
  in the bundled file: the rollout then reads the rally as training's windows do,
  docs/evaluation.md).

FLOPs (multiply-add = 2) are those `bench_sim` counts: a step's `flops_per_frame` at its
cache's length (heads included), a full-window pass's `window_flops` (every token through the
embedding and the blocks' projections, `token_flops`, and attention over the pairs the mask
lets an object token see; heads left out). A full-window pass after the first step is counted
as a refresh (a rollout's later batches would be miscounted as refreshes if their initial
frames were exactly a window; these workloads' are not). Layer norms, GELUs and sampling are
left out, so the floors are low. Each floor is those FLOPs at this machine's matmul peak, as if
every pass ran at the speed of one large 1024^2 float32 product.
"""

from __future__ import annotations

import argparse
import textwrap

from bench_sim import (
    _BANDWIDTH_CHILD,
    _PEAK_CHILD,
    BUNDLED,
    _child,
    flops_per_frame,
    token_flops,
)

TARGETS_S = {"win_probability": 1.0, "counterfactual": 3.0}
N_CTX = 4              # context tokens a rally's window starts with

# The workloads in a child process, every decoder pass counted: steps by rows and cache
# length, full-window passes by kind and frames.
_WORKLOAD_CHILD = textwrap.dedent("""
    import collections, json, sys, time
    import torch
    from sportsngen.model import decoder
    from sportsngen.sim import Simulator
    from sportsngen.synth.generate import generate_matches
    torch.set_num_threads(int(sys.argv[1]))
    sim = Simulator.from_pretrained()
    w = sim.model.cfg.window_frames
    log = {}
    forward, forward_step = decoder.SportsNGEN.forward, decoder.SportsNGEN.forward_step

    def counted_forward(self, feats, *a, **k):
        b, t = feats.shape[:2]
        kind = "refresh" if t == w and log["steps"] else "first"
        log[kind][t] += b
        return forward(self, feats, *a, **k)

    def counted_step(self, feats, cache):
        b = feats.shape[0]
        log["steps"] += 1
        log["small_steps"] += b <= 8
        log["step_rows"][cache.n_frames] += b
        return forward_step(self, feats, cache)

    real = generate_matches([("Roger Federer", "Rafael Nadal")], "hard", 30, seed=3)
    shots = real.shots[real.shots["shot_index"] == 2]
    rid, frame = int(shots["rally_id"].iat[0]), int(shots["frame"].iat[0])
    sim.rally_win_probability(real, rid, frame - 10, n=4)          # warm the kernels
    runs = {"win_probability": lambda: sim.rally_win_probability(real, rid, frame - 10, n=100),
            "counterfactual": lambda: sim.counterfactual(real, rid, 2, n=100),
            "win_probability_band": lambda: sim.rally_win_probability(real, rid, frame - 10,
                                                                      n=100)}
    out = {}
    decoder.SportsNGEN.forward, decoder.SportsNGEN.forward_step = counted_forward, counted_step
    for name, run in runs.items():
        if name.endswith("_band"):
            sim.refresh_frames = None       # the band: no refreshes
        log.update(steps=0, small_steps=0, step_rows=collections.Counter(),
                   first=collections.Counter(), refresh=collections.Counter())
        t0 = time.perf_counter()
        run()
        out[name] = {"wall_s": time.perf_counter() - t0, **log}
    print(json.dumps(out))
""")


def window_flops(cfg, n_frames: int) -> float:
    """FLOPs of a full pass over a rally's first `n_frames` frames (at most a window): every
    object and context token through the projections, and attention for the object tokens,
    each seeing the context and the objects of its own frame and those before it."""
    if n_frames > cfg.window_frames:
        raise ValueError(f"a pass of {n_frames} frames reaches past the band's window")
    pairs = 3 * (N_CTX * n_frames + 3 * n_frames * (n_frames + 1) // 2)
    return (3 * n_frames * token_flops(cfg) + N_CTX * token_flops(cfg, embed=False)
            + cfg.n_layers * 2 * 2 * cfg.d_model * pairs)


def pass_flops(cfg, work: dict) -> dict:
    """A workload's counted passes -> FLOPs of its steps, first passes and refreshes, and the
    refreshes' rows (rows x windows)."""
    w = cfg.window_frames
    steps = sum(rows * flops_per_frame(cfg, min(int(n) + 1, w))
                for n, rows in work["step_rows"].items())
    return {"step_flops": steps,
            "step_rows": sum(work["step_rows"].values()),
            "first_flops": sum(rows * window_flops(cfg, int(t))
                               for t, rows in work["first"].items()),
            "refresh_flops": sum(rows * window_flops(cfg, int(t))
                                 for t, rows in work["refresh"].items()),
            "refresh_rows": sum(work["refresh"].values())}


def floors(cfg, work: dict, peak_gflops: float) -> dict:
    """Seconds at the matmul peak: all the passes; the refreshes alone; and with the band in
    place of the refreshes (each refreshed row's frame taken as one full-window step)."""
    g = peak_gflops * 1e9
    f = pass_flops(cfg, work)
    total = f["step_flops"] + f["first_flops"] + f["refresh_flops"]
    band = total - f["refresh_flops"] + f["refresh_rows"] * flops_per_frame(
        cfg, cfg.window_frames)
    return {**f, "all_s": total / g, "refresh_s": f["refresh_flops"] / g, "band_s": band / g,
            "refresh_share": f["refresh_flops"] / total}


def bench_floors(threads: int = 2) -> tuple[list[str], dict]:
    from sportsngen.model.export import load_model

    cfg = load_model(BUNDLED)[3]
    peak = _child(_PEAK_CHILD, threads)["gflops"]
    bandwidth = _child(_BANDWIDTH_CHILD, threads)["read_gbps"]
    res = _child(_WORKLOAD_CHILD, threads)
    lines = [
        "## Floors under the rollout targets (issue 19)",
        "",
        f"`python bench/bench_floors.py --threads {threads}`: the end-to-end bench's win "
        "probability and counterfactual, every decoder pass counted (module doc). A floor is "
        f"the passes' FLOPs at this machine's matmul peak ({peak:.1f} GFLOP/s, {threads} "
        f"threads; read bandwidth {bandwidth:.1f} GB/s); sampling and the window passes' heads "
        "left out. One "
        f"object token costs {token_flops(cfg) / 1e6:.2f} MFLOP of projections, a "
        f"full-window pass over one rally {window_flops(cfg, cfg.window_frames) / 1e9:.2f} "
        "GFLOP.",
        "",
        "| run | target s | measured s | steps (of them with at most 8 rallies) | "
        "rally-frames stepped | windows refreshed | floor s | of it refreshes | "
        "floor with the band instead |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name, target in TARGETS_S.items():
        w, band = res[name], res.get(name + "_band")
        f = floors(cfg, w, peak)
        res[name]["floors"] = f
        print(f"{name}: measured {w['wall_s']:.1f} s, target {target} s; floor {f['all_s']:.2f} s "
              f"({100 * f['refresh_share']:.0f} % refreshes: {f['refresh_rows']} windows), "
              f"band {f['band_s']:.2f} s")
        lines.append(f"| {name.replace('_', ' ')} | {target:.1f} | {w['wall_s']:.1f} | "
                     f"{w['steps']:,} ({w['small_steps']:,}) | {f['step_rows']:,} | "
                     f"{f['refresh_rows']:,} | {f['all_s']:.2f} | {f['refresh_s']:.2f} "
                     f"({100 * f['refresh_share']:.0f} %) | {f['band_s']:.2f}"
                     + (f" (measured {band['wall_s']:.1f} s)" if band else "") + " |")
    res.update(peak_gflops=peak, read_gbps=bandwidth)
    return lines, res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    lines, _ = bench_floors(args.threads)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
