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

FLOPs (multiply-add = 2) are read off the model's own layers (the child's `TOKEN`,
`step_flops` and `window_flops`): every linear layer of the object embedding and the blocks a
token passes, and attention over the pairs the mask lets a token see. A full-window pass after
the first step is counted as a refresh (a rollout's later batches would be miscounted as
refreshes if their initial frames were exactly a window; these workloads' are not). Heads,
sampling, layer norms and GELUs are left out, so the floors are low. Each floor is those FLOPs
at this machine's matmul peak, as if every pass ran at the speed of one large 1024^2 float32
product.
"""

from __future__ import annotations

import argparse
import textwrap

from bench_sim import _BANDWIDTH_CHILD, _PEAK_CHILD, _child

TARGETS_S = {"win_probability": 1.0, "counterfactual": 3.0}

_WORKLOAD_CHILD = textwrap.dedent("""
    import json, sys, time
    import torch
    from torch import nn
    from sportsngen.model import decoder
    from sportsngen.sim import Simulator
    from sportsngen.synth.generate import generate_matches
    torch.set_num_threads(int(sys.argv[1]))
    sim = Simulator.from_pretrained()
    model = sim.model
    cfg = model.cfg
    d, layers, w = cfg.d_model, cfg.n_layers, cfg.window_frames

    def linear_flops(module):
        return sum(2 * m.in_features * m.out_features for m in module.modules()
                   if isinstance(m, nn.Linear))

    # One object token through the embedding and every block's projections.
    TOKEN = linear_flops(model.embed) + linear_flops(model.blocks)
    BLOCKS = linear_flops(model.blocks)     # context tokens skip the object embedding
    N_CTX = 4

    def step_flops(n_cached):
        keys = N_CTX + 3 * min(n_cached + 1, w)
        return 3 * (TOKEN + layers * 2 * 2 * d * keys)

    def window_flops(t):
        mask = decoder.baller2vec_mask(N_CTX, t, 3, window_frames=w)
        pairs = int(mask[N_CTX:].sum())          # object queries; the context's are cached
        return 3 * t * TOKEN + N_CTX * BLOCKS + layers * 2 * 2 * d * pairs

    log = {"steps": 0, "step_rows": 0, "step_flops": 0.0, "small_steps": 0,
           "first_rows": 0, "first_flops": 0.0, "refresh_rows": 0, "refresh_flops": 0.0,
           "full_window_step_flops": float(step_flops(w))}
    forward, forward_step = decoder.SportsNGEN.forward, decoder.SportsNGEN.forward_step

    def counted_forward(self, feats, *a, **k):
        b, t = feats.shape[:2]
        kind = "refresh" if t == w and log["steps"] else "first"
        log[kind + "_rows"] += b
        log[kind + "_flops"] += b * window_flops(t)
        return forward(self, feats, *a, **k)

    def counted_step(self, feats, cache):
        b = feats.shape[0]
        log["steps"] += 1
        log["step_rows"] += b
        log["small_steps"] += b <= 8
        log["step_flops"] += b * step_flops(cache.n_frames)
        return forward_step(self, feats, cache)

    real = generate_matches([("Roger Federer", "Rafael Nadal")], "hard", 30, seed=3)
    shots = real.shots[real.shots["shot_index"] == 2]
    rid, frame = int(shots["rally_id"].iat[0]), int(shots["frame"].iat[0])
    sim.rally_win_probability(real, rid, frame - 10, n=4)          # warm the kernels
    runs = {"win_probability": lambda: sim.rally_win_probability(real, rid, frame - 10, n=100),
            "counterfactual": lambda: sim.counterfactual(real, rid, 2, n=100),
            "win_probability_band": lambda: sim.rally_win_probability(real, rid, frame - 10,
                                                                      n=100)}
    out = {"token_flops": TOKEN, "window_flops": window_flops(w)}
    decoder.SportsNGEN.forward, decoder.SportsNGEN.forward_step = counted_forward, counted_step
    for name, run in runs.items():
        if name.endswith("_band"):
            sim.refresh_frames = None       # the band: no refreshes
        for key in log:
            if key != "full_window_step_flops":
                log[key] = 0
        t0 = time.perf_counter()
        run()
        out[name] = {"wall_s": time.perf_counter() - t0, **log}
    print(json.dumps(out))
""")


def floors(work: dict, peak_gflops: float) -> dict:
    """Seconds at the matmul peak: all the passes; the refreshes alone; and with the band in
    place of the refreshes (each refreshed row's frame taken as one full-window step)."""
    g = peak_gflops * 1e9
    total = work["step_flops"] + work["first_flops"] + work["refresh_flops"]
    band = total - work["refresh_flops"] + work["refresh_rows"] * work["full_window_step_flops"]
    return {"all_s": total / g, "refresh_s": work["refresh_flops"] / g, "band_s": band / g,
            "refresh_share": work["refresh_flops"] / total}


def bench_floors(threads: int = 2) -> tuple[list[str], dict]:
    peak = _child(_PEAK_CHILD, threads)["gflops"]
    bandwidth = _child(_BANDWIDTH_CHILD, threads)["read_gbps"]
    res = _child(_WORKLOAD_CHILD, threads)
    lines = [
        "## Floors under the rollout targets (issue 19)",
        "",
        f"`python bench/bench_floors.py --threads {threads}`: the end-to-end bench's win "
        "probability and counterfactual, every decoder pass counted (module doc). A floor is "
        f"the passes' FLOPs at this machine's matmul peak ({peak:.1f} GFLOP/s, {threads} "
        f"threads; read bandwidth {bandwidth:.1f} GB/s); heads and sampling left out. One "
        f"object token costs {res['token_flops'] / 1e6:.2f} MFLOP of projections, a "
        f"full-window pass over one rally {res['window_flops'] / 1e9:.2f} GFLOP.",
        "",
        "| run | target s | measured s | steps (of them with at most 8 rallies) | "
        "rally-frames stepped | windows refreshed | floor s | of it refreshes | "
        "floor with the band instead |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name, target in TARGETS_S.items():
        w, band = res[name], res.get(name + "_band")
        f = floors(w, peak)
        res[name]["floors"] = f
        print(f"{name}: measured {w['wall_s']:.1f} s, target {target} s; floor {f['all_s']:.2f} s "
              f"({100 * f['refresh_share']:.0f} % refreshes: {w['refresh_rows']} windows), "
              f"band {f['band_s']:.2f} s")
        lines.append(f"| {name.replace('_', ' ')} | {target:.1f} | {w['wall_s']:.1f} | "
                     f"{w['steps']:,} ({w['small_steps']:,}) | {w['step_rows']:,} | "
                     f"{w['refresh_rows']:,} | {f['all_s']:.2f} | {f['refresh_s']:.2f} "
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
