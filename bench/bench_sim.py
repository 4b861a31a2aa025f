"""Simulation speed of the learned engine (decoder f rollouts) with the bundled model.

    .venv/bin/python bench/bench_sim.py [--quick] [--model PATH] [--threads N]

Each measurement runs in a fresh subprocess (its own peak RSS):

- decoder step at a full 6 s window (150 frames at 25 Hz, 454 tokens): the ring cache
  (`forward_step`, one new frame) against recomputing the window (`forward` on the last 150
  frames, the naive rolling window) and against recomputing the whole rally so far with the band
  mask (`forward` on every frame, what the cache equals exactly), for B = 1 and 64;
- rollouts (`sportsngen.sim.rollout.rollout`, sampling included, no rally-end rules so every
  rally runs the same number of frames) from real serve starts: simulated frames per second for
  B = 1, 64 and 256 parallel rallies (B = 1 is the one-rally-at-a-time baseline);
- end to end with the rally-end rules, event labels and tables (`Simulator`): 100 rollouts of
  one serve (the cost of a 100-rollout win probability), and one best-of-3 match.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BUNDLED = ROOT / "sportsngen" / "model" / "bundled" / "sportsngen-small.pt"

_COMMON = """
import json, resource, sys, time
import numpy as np, torch
from sportsngen.model.export import load_model, read_extra
from sportsngen.data.serve_starts import InitialConditions
from sportsngen.sim.rollout import RolloutInputs, cpu_threads, rollout
from sportsngen.model.inputs import object_features
torch.set_num_threads(int(sys.argv[2]))
path = sys.argv[1]
model, ec, vocab, cfg = load_model(path)
ic = InitialConditions.from_dict(read_extra(path)["initial_conditions"])

def inputs(b, t0=None):
    rng = np.random.default_rng(0)
    idx = rng.integers(0, len(ic), b)
    pos = ic.pos_m[idx] if t0 is None else ic.pos_m[idx][:, :t0]
    return RolloutInputs(pos, np.tile([[2, 3, 0]], (b, 1)), np.zeros(b, np.int64),
                         np.zeros(b, np.int64), np.zeros(b, np.int64),
                         np.zeros((b, 7), np.float32))

def peak_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
"""

_STEP_CHILD = _COMMON + textwrap.dedent("""
    b, reps = int(sys.argv[3]), int(sys.argv[4])
    w = cfg.window_frames
    # A real rally prefix of w + 10 frames, simulated once.
    hist = rollout(model, inputs(b), w + 10, seed=0).pos_m
    pos = torch.from_numpy(hist)
    prev = torch.cat([pos[:, :1], pos[:, :-1]], dim=1)
    t = (torch.arange(pos.shape[1]) / cfg.fps).expand(b, -1)
    feats = object_features(pos, (pos - prev) * cfg.fps, t)
    ident = torch.tensor([[2, 3, 0]] * b)
    z = torch.zeros(b, dtype=torch.long)
    ctx = model.context_tokens(z, z, z, torch.zeros(b, 7))
    n = w + 5
    out = {"b": b, "window_frames": w}
    with torch.inference_mode():
        _, cache0 = model(feats[:, :n], ident, ctx, return_cache=True)
        def run(kind):
            best = float("inf")
            for _ in range(reps):
                cache = cache0.select(torch.arange(b))
                t0 = time.perf_counter()
                for k in range(5):
                    if kind == "cache":
                        model.forward_step(feats[:, n + k], cache)
                    elif kind == "window":
                        model(feats[:, n + k + 1 - w:n + k + 1], ident, ctx)
                    else:
                        model(feats[:, :n + k + 1], ident, ctx)
                best = min(best, (time.perf_counter() - t0) / 5)
            return best
        for kind in ("cache", "window", "recompute"):
            out[kind + "_ms"] = 1000 * run(kind)
        with cpu_threads(1):   # what a rollout of a few rallies uses (SINGLE_THREAD_ROWS)
            out["cache_1t_ms"] = 1000 * run("cache")
        # Both paths compiled (torch.compile; the first runs compile), each at the thread
        # count a rollout gives it: the cache at one thread up to 8 rows, the window at all.
        model.compile_step()
        with cpu_threads(1 if b <= 8 else None):
            run("cache")
            out["cache_compiled_ms"] = 1000 * run("cache")
        window = model
        model = torch.compile(window)
        run("window")
        out["window_compiled_ms"] = 1000 * run("window")
        model = window.compile_step(False)
        # The cached state equals the band recomputation on the same frames.
        cache = cache0.select(torch.arange(b))
        h_c, _ = model.forward_step(feats[:, n], cache)
        h_r = model(feats[:, :n + 1], ident, ctx)[:, -1]
        out["max_abs_diff"] = float((h_c - h_r).abs().max())
        lg_c = model.ball_head.dim_logits(h_c[:, 2], torch.zeros(b, 3, dtype=torch.long), 0)
        lg_r = model.ball_head.dim_logits(h_r[:, 2], torch.zeros(b, 3, dtype=torch.long), 0)
        out["max_abs_logit_diff"] = float((lg_c - lg_r).abs().max())
    out["peak_rss_mb"] = peak_mb()
    print(json.dumps(out))
""")

_ROLLOUT_CHILD = _COMMON + textwrap.dedent("""
    b, n_frames, compiled = int(sys.argv[3]), int(sys.argv[4]), sys.argv[5] == "1"
    if compiled:
        model.compile_step()
        rollout(model, inputs(b), n_frames, seed=0)           # compiles
    rollout(model, inputs(min(b, 4)), 20, seed=0)          # warm-up
    wall = float("inf")
    for _ in range(3):      # best of 3: one-thread B = 1 runs vary by ~15 % between runs
        t0 = time.perf_counter()
        r = rollout(model, inputs(b), n_frames, seed=1)
        wall = min(wall, time.perf_counter() - t0)
    print(json.dumps({"b": b, "compiled": compiled, "frames": r.frames_simulated, "wall_s": wall,
                      "frames_per_s": r.frames_simulated / wall,
                      "ms_per_step": 1000 * wall / r.n_steps, "peak_rss_mb": peak_mb()}))
""")

_SIM_CHILD = _COMMON + textwrap.dedent("""
    from sportsngen.sim import Simulator
    from sportsngen.synth.generate import generate_matches
    sim = Simulator.from_pretrained(path)
    t0 = time.perf_counter()
    d = sim.simulate_points("Roger Federer", "Rafael Nadal", "hard", 100, seed=0,
                            serve_number=1)
    t_100 = time.perf_counter() - t0
    real = generate_matches([("Roger Federer", "Rafael Nadal")], "hard", 30, seed=3)
    shots = real.shots[real.shots["shot_index"] == 2]
    rid = int(shots["rally_id"].iat[0])
    t0 = time.perf_counter()
    wp = sim.rally_win_probability(real, rid, int(shots["frame"].iat[0]) - 10, n=100)
    t_wp = time.perf_counter() - t0
    t0 = time.perf_counter()
    cf = sim.counterfactual(real, rid, 2, n=100)
    t_cf = time.perf_counter() - t0
    t0 = time.perf_counter()
    m = sim.simulate_match("Roger Federer", "Rafael Nadal", "hard", seed=0, progress=False)
    t_match = time.perf_counter() - t0
    n_rallies = len(m.rallies) + m.n_discarded
    print(json.dumps({"rollouts_100_s": t_100, "match_s": t_match, "score": m.score_line,
                      "win_prob_100_s": t_wp, "counterfactual_2x100_s": t_cf,
                      "points": len(m.points), "rallies_simulated": n_rallies,
                      "discarded": m.n_discarded, "forced": m.forced_decisions,
                      "realistic_100": float(d.rallies["realistic"].mean()),
                      "peak_rss_mb": peak_mb()}))
""")


_PEAK_CHILD = textwrap.dedent("""
    import json, sys, time, torch
    torch.set_num_threads(int(sys.argv[1]))
    n = 1024
    a, b = torch.randn(n, n), torch.randn(n, n)
    for _ in range(3):
        a @ b
    best = float("inf")
    for _ in range(10):
        t0 = time.perf_counter()
        a @ b
        best = min(best, time.perf_counter() - t0)
    print(json.dumps({"gflops": 2 * n ** 3 / best / 1e9}))
""")


_BANDWIDTH_CHILD = textwrap.dedent("""
    import json, sys, time, torch
    torch.set_num_threads(int(sys.argv[1]))
    a = torch.randn(64 * 2 ** 20)          # 256 MB, far beyond the caches
    b = torch.empty_like(a)
    best = float("inf")
    for _ in range(6):
        t0 = time.perf_counter()
        a.sum()
        best = min(best, time.perf_counter() - t0)
    print(json.dumps({"read_gbps": a.numel() * 4 / best / 1e9}))
""")


def kv_bytes_per_frame(cfg, n_frames_cached: int) -> float:
    """Bytes of cached keys and values one simulated frame of one rally reads (float32, every
    layer). With 3 queries per rally against hundreds of keys attention does ~1.5 FLOP a byte,
    so its roofline is memory bandwidth, not matmul throughput; the table reports how much of
    the measured bandwidth the rollout's key/value reads use."""
    n_keys = 4 + 3 * n_frames_cached
    return float(cfg.n_layers * 2 * n_keys * cfg.d_model * 4)


def token_flops(cfg, embed: bool = True) -> float:
    """Floating-point operations (multiply-add = 2) of one token through the object embedding
    (`embed`; context tokens skip it) and every block's projections, attention left out."""
    d = cfg.d_model
    sizes = [8 + cfg.id_dim, *cfg.embed_hidden, d]
    mlp = sum(2 * a * b for a, b in zip(sizes[:-1], sizes[1:])) if embed else 0
    return float(mlp + cfg.n_layers * (2 * d * 3 * d + 2 * d * d + 2 * 2 * d * cfg.ff_mult * d))


def flops_per_frame(cfg, n_frames_cached: int) -> float:
    """Floating-point operations (multiply-add = 2) of one simulated frame of one rally with
    the cache holding `n_frames_cached` frames: object embedding, the blocks' projections and
    attention over the cached keys, the factorised heads. LayerNorm, GELU and softmax left out.
    """
    d, k = cfg.d_model, 3
    n_keys = 4 + 3 * n_frames_cached
    nb, hid, emb = cfg.n_bins, cfg.head_hidden, 32

    def head(dims: int) -> int:
        return 2 * d * nb + sum(2 * (d + j * emb) * hid + 2 * hid * nb
                                for j in range(1, dims))
    return float(k * (token_flops(cfg) + cfg.n_layers * 2 * 2 * d * n_keys)
                 + 2 * head(2) + head(3))


def _child(code: str, *args: object) -> dict:
    out = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True,
                         text=True, cwd=ROOT)
    if out.returncode:
        raise RuntimeError(f"benchmark child failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def bench_simulation(quick: bool, model: Path = BUNDLED, threads: int = 2,
                     end_to_end: bool = True) -> tuple[list[str], dict]:
    steps = [_child(_STEP_CHILD, model, threads, b, 2 if quick else 5) for b in (1, 64)]
    for s in steps:
        print(f"decoder step at a full window, B={s['b']}: cache {s['cache_ms']:.2f} ms "
              f"(1 thread {s['cache_1t_ms']:.2f} ms), "
              f"window {s['window_ms']:.1f} ms ({s['window_ms'] / s['cache_ms']:.0f}x), "
              f"recompute {s['recompute_ms']:.1f} ms ({s['recompute_ms'] / s['cache_ms']:.0f}x)"
              f"; compiled: cache {s['cache_compiled_ms']:.2f} ms, "
              f"window {s['window_compiled_ms']:.1f} ms"
              f"; cache vs recompute max |diff| {s['max_abs_diff']:.1e}")
    n_frames = 100 if quick else 200
    rolls = [_child(_ROLLOUT_CHILD, model, threads, b, n_frames, 0) for b in (1, 64, 256)]
    compiled_roll = _child(_ROLLOUT_CHILD, model, threads, 1, n_frames, 1)
    for r in rolls + [compiled_roll]:
        print(f"rollout B={r['b']}{' compiled' if r['compiled'] else ''}: "
              f"{r['frames_per_s']:.0f} frames/s "
              f"({r['ms_per_step']:.2f} ms a step), peak RSS {r['peak_rss_mb']:.0f} MB")
    e2e = _child(_SIM_CHILD, model, threads) if end_to_end else None
    from sportsngen.model.export import load_model

    cfg = load_model(model)[3]
    peak = _child(_PEAK_CHILD, threads)["gflops"]
    bandwidth = _child(_BANDWIDTH_CHILD, threads)["read_gbps"]
    fpf = flops_per_frame(cfg, cfg.window_frames)
    # The rollouts start 10 frames in: average the cost over the frames they sampled.
    avg = sum(flops_per_frame(cfg, min(n + 1, cfg.window_frames))
              for n in range(10, n_frames)) / (n_frames - 10)
    kv_full = kv_bytes_per_frame(cfg, cfg.window_frames)
    avg_kv = sum(kv_bytes_per_frame(cfg, min(n + 1, cfg.window_frames))
                 for n in range(10, n_frames)) / (n_frames - 10)
    for r in rolls:
        r["share_of_peak"] = avg * r["frames_per_s"] / (peak * 1e9)
        r["kv_gbps"] = avg_kv * r["frames_per_s"] / 1e9
    print(f"{fpf / 1e6:.2f} MFLOP a simulated frame (full window); matmul peak {peak:.1f} "
          f"GFLOP/s; achieved share " + ", ".join(f"B={r['b']}: {100 * r['share_of_peak']:.1f} %"
                                                for r in rolls))
    if e2e:
        print(f"100 rollouts of a serve: {e2e['rollouts_100_s']:.1f} s; best-of-3 match: "
              f"{e2e['match_s']:.1f} s ({e2e['points']} points, {e2e['rallies_simulated']} "
              f"rallies simulated, {e2e['discarded']} set aside)")
    lines = [
        "## Simulation (learned engine)",
        "",
        f"Bundled model `{model.name}`, {threads} torch threads, `bench/bench_sim.py`.",
        "",
        "Decoder step at a full 6 s window (150 frames, 454 tokens), best of repeated runs of "
        "5 steps: the ring cache against recomputing the last 150 frames (naive window) and "
        "against recomputing the whole rally with the band mask (the computation the cache "
        "equals).",
        "",
        f"Cache ms is at {threads} threads; cache 1t at one thread, which is what a rollout of "
        "up to 8 rallies uses (`SINGLE_THREAD_ROWS`); the speed-ups are window (recompute) "
        "at its own thread count over the cache as a rollout runs it. Compiled: both paths "
        "through `torch.compile` (`SportsNGEN.compile_step` for the cache, each at the thread "
        "count a rollout gives it), timed after their compilation.",
        "",
        "| B | cache ms | cache 1t ms | window ms | speed-up | recompute ms | speed-up | "
        "compiled cache ms | compiled window ms | speed-up compiled | "
        "max abs diff (hidden) | max abs diff (logits) | peak RSS MB |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for s in steps:
        used = s["cache_1t_ms"] if s["b"] <= 8 else s["cache_ms"]
        lines.append(f"| {s['b']} | {s['cache_ms']:.2f} | {s['cache_1t_ms']:.2f} | "
                     f"{s['window_ms']:.1f} | {s['window_ms'] / used:.0f}x | "
                     f"{s['recompute_ms']:.1f} | {s['recompute_ms'] / used:.0f}x | "
                     f"{s['cache_compiled_ms']:.2f} | {s['window_compiled_ms']:.1f} | "
                     f"{s['window_compiled_ms'] / s['cache_compiled_ms']:.0f}x | "
                     f"{s['max_abs_diff']:.1e} | {s['max_abs_logit_diff']:.1e} | "
                     f"{s['peak_rss_mb']:.0f} |")
    base = rolls[0]["frames_per_s"]
    lines += ["", f"Rollouts of {n_frames} frames from real serve starts (sampling included, "
              "no rally-end rules), B rallies in parallel, best of 3 runs; B = 1 is one rally "
              "at a time.", "",
              f"FLOPs of one simulated frame at a full window: {fpf / 1e6:.2f} MFLOP "
              f"(`flops_per_frame`; {avg / 1e6:.2f} MFLOP on average over these rollouts, "
              f"which the shares below use); this machine's matmul peak ({threads} threads, 1024^2 "
              f"float32): {peak:.1f} GFLOP/s. Attention reads every cached key and value of "
              f"every layer for 3 queries a rally: {kv_full / 1e6:.2f} MB a frame at a full "
              f"window ({avg_kv / 1e6:.2f} MB on average here, `kv_bytes_per_frame`), "
              f"against this machine's read bandwidth ({threads} threads, 256 MB sum): "
              f"{bandwidth:.1f} GB/s, which bounds a full-window rollout at "
              f"{bandwidth * 1e9 / kv_full:.0f} frames/s "
              "however large the batch.", "",
              "| B | frames/s | x B=1 | ms a step | share of matmul peak | key/value reads GB/s "
              "| peak RSS MB |",
              "|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rolls:
        lines.append(f"| {r['b']} | {r['frames_per_s']:.0f} | {r['frames_per_s'] / base:.1f} | "
                     f"{r['ms_per_step']:.2f} | {100 * r['share_of_peak']:.1f} % | "
                     f"{r['kv_gbps']:.1f} | {r['peak_rss_mb']:.0f} |")
    lines += ["", f"With the compiled step (`compile_step`, timed after a compiling run), B = 1: "
              f"{compiled_roll['frames_per_s']:.0f} frames/s "
              f"({compiled_roll['ms_per_step']:.2f} ms a step); the decoder step is about "
              "half of a B = 1 frame here, sampling and the per-frame bookkeeping the rest."]
    if e2e:
        lines += ["", "End to end (`Simulator`: rollouts, rally-end rules, event labels, tables), "
                  "Roger Federer v Rafael Nadal on hard, seed 0:", "",
                  f"- 100 rollouts of a first serve: {e2e['rollouts_100_s']:.1f} s "
                  f"({100 * e2e['realistic_100']:.0f} % realistic)",
                  f"- a 100-rollout rally win probability (branching a generated rally 10 "
                  f"frames before its third shot): {e2e['win_prob_100_s']:.1f} s",
                  f"- a 2-option counterfactual of that shot, 100 rollouts an option: "
                  f"{e2e['counterfactual_2x100_s']:.1f} s",
                  f"- one best-of-3 match: {e2e['match_s']:.1f} s, {e2e['score']}, "
                  f"{e2e['points']} points, {e2e['rallies_simulated']} rallies simulated "
                  f"({e2e['discarded']} set aside as non-realistic or undecided, "
                  f"{e2e['forced']} counted without a realistic replay); peak RSS "
                  f"{e2e['peak_rss_mb']:.0f} MB"]
    return lines, {"steps": steps, "rollouts": rolls, "compiled_rollout": compiled_roll,
                   "end_to_end": e2e, "peak_gflops": peak,
                   "flops_per_frame": fpf, "read_gbps": bandwidth}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--model", type=Path, default=BUNDLED)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--no-end-to-end", action="store_true")
    args = ap.parse_args()
    lines, _ = bench_simulation(args.quick, args.model, args.threads, not args.no_end_to_end)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
