"""Benchmarks: print figures and rewrite docs/benchmarks.md.

    .venv/bin/python bench/run.py            # every benchmark
    .venv/bin/python bench/run.py --quick    # smaller sizes, for a smoke run
    .venv/bin/python bench/run.py --only simulation   # one section; the others are kept

Each measurement runs in a fresh subprocess so that peak memory (ru_maxrss) belongs to it
alone. Speed and memory targets live here, not in the test suite.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import textwrap
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "benchmarks.md"
ALL_SECTIONS = ("generator", "training", "precision", "simulation", "floors", "analysis")

# One generator run in a child process: wall time, points, frames, peak RSS of the process and
# of its worker processes (the per-worker figure is the one that must stay flat).
_GENERATOR_CHILD = textwrap.dedent("""
    import json, resource, sys, time
    from sportsngen.synth.generate import generate_matches
    from sportsngen.synth.profiles import named_profiles
    n_points, workers = int(sys.argv[1]), int(sys.argv[2])
    players = sorted(named_profiles())
    t0 = time.perf_counter()
    data = generate_matches(players, surface=["hard", "clay", "grass"], n_points=n_points,
                            seed=0, workers=workers)
    wall = time.perf_counter() - t0
    n = int(data.rallies.groupby(["match_id", "point"]).ngroups)
    print(json.dumps({
        "n_points": n, "workers": workers, "wall_s": wall, "frame_rows": len(data.frames),
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "worker_peak_rss_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024,
    }))
""")


def _child(code: str, *args: object) -> dict:
    out = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True,
                         text=True, check=True, cwd=ROOT)
    return json.loads(out.stdout.strip().splitlines()[-1])


def bench_generator(quick: bool) -> tuple[list[str], list[dict]]:
    """Synthetic generator: points per second by worker count and size; memory per worker."""
    runs = [(500, 1), (500, 2)] if quick else [(2000, 1), (2000, 2), (10000, 2)]
    rows = []
    for n_points, workers in runs:
        r = _child(_GENERATOR_CHILD, n_points, workers)
        r["points_per_s"] = r["n_points"] / r["wall_s"]
        r["points_per_s_per_core"] = r["points_per_s"] / workers
        rows.append(r)
        print(f"generator: {r['n_points']} points, {workers} worker(s): {r['wall_s']:.1f} s, "
              f"{r['points_per_s']:.1f} points/s ({r['points_per_s_per_core']:.1f} per core), "
              f"peak RSS {r['peak_rss_mb']:.0f} MB (workers {r['worker_peak_rss_mb']:.0f} MB)")
    lines = [
        "## Synthetic generator",
        "",
        "`generate_matches(<the 7 named players, round robin>, surface=[hard, clay, grass], "
        "n_points, seed=0, workers)`; peak RSS of the calling process (which holds the whole "
        "result) and of the worker processes.",
        "",
        "| points | workers | wall s | points/s | points/s per core | frame rows | "
        "peak RSS MB | worker peak RSS MB |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['n_points']} | {r['workers']} | {r['wall_s']:.1f} | "
                     f"{r['points_per_s']:.1f} | {r['points_per_s_per_core']:.1f} | "
                     f"{r['frame_rows']} | {r['peak_rss_mb']:.0f} | "
                     f"{r['worker_peak_rss_mb']:.0f} |")
    return lines, rows


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = ""
    try:
        kb = int(Path("/proc/meminfo").read_text().split()[1])
        mem = f", {kb / 1024 ** 2:.0f} GiB RAM"
    except (OSError, ValueError, IndexError):
        pass
    return (f"{cpu}, {os.cpu_count()} cores{mem}; Python {platform.python_version()}, "
            f"{platform.system()} {platform.release()}")


def _old_sections() -> dict[str, list[str]]:
    """The "## " sections of the current docs/benchmarks.md, by title (to keep those not
    re-run by --only)."""
    if not DOC.exists():
        return {}
    out: dict[str, list[str]] = {}
    title = None
    for line in DOC.read_text().splitlines():
        if line.startswith("## "):
            title = line
            out[title] = [line]
        elif title is not None:
            out[title].append(line)
    return {k: v[:-1] if v and v[-1] == "" else v for k, v in out.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke run)")
    parser.add_argument("--only", default=",".join(ALL_SECTIONS),
                        help="comma list of generator, training, precision, simulation, "
                             "floors, analysis (the other sections of docs/benchmarks.md are "
                             "kept as they are)")
    parser.add_argument("--threads", type=int, default=2,
                        help="torch threads (simulation, precision)")
    args = parser.parse_args()
    only = set(args.only.split(","))
    sections = _old_sections()
    if "generator" in only:
        lines, _ = bench_generator(args.quick)
        sections[lines[0]] = lines
    # The model benchmarks import torch; keep it out of the generator's child processes.
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    if "training" in only:
        from bench_model import bench_training

        lines, _ = bench_training(args.quick)
        sections[lines[0]] = lines
    if "precision" in only:
        from bench_model import bench_precision

        lines, _ = bench_precision(args.quick, threads=args.threads)
        sections[lines[0]] = lines
    if "simulation" in only:
        from bench_sim import bench_simulation

        lines, _ = bench_simulation(args.quick, threads=args.threads)
        sections[lines[0]] = lines
    if "floors" in only:
        from bench_floors import bench_floors

        lines, _ = bench_floors(threads=args.threads)
        sections[lines[0]] = lines
    if "analysis" in only:
        from bench_analysis import bench_analysis

        lines, _ = bench_analysis(args.quick)
        sections[lines[0]] = lines
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    body: list[str] = []
    for lines in sections.values():
        body += [*lines, ""]
    doc = [
        "# Benchmarks",
        "",
        f"Written by `python bench/run.py{' --quick' if args.quick else ''}"
        f"{'' if only == set(ALL_SECTIONS) else ' --only ' + args.only}`"
        f" on {stamp} (sections not re-run are kept from before).",
        "",
        f"Machine: {machine()}.",
        "",
        *body,
    ]
    DOC.parent.mkdir(parents=True, exist_ok=True)
    DOC.write_text("\n".join(doc))
    print(f"wrote {DOC}")


if __name__ == "__main__":
    main()
