"""Analysis benchmarks: the rally-end rules over recorded tracks, the reach tables, a saved
dataset's validated read, the real slam reader and the table fits' shift solver, each on fixed
inputs (wall seconds, best of `REPEATS`). These are the library's paths that a check, a report
or a table fit runs over thousands of rallies; the figures keep them from slowing down unseen."""

from __future__ import annotations

import tempfile
import time

REPEATS = 2


def _best(fn, repeats: int = REPEATS) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def bench_analysis(quick: bool) -> tuple[list[str], list[dict]]:
    """Rules, reach, slam reading and the shift solver on fixed inputs."""
    import torch

    from sportsngen.data.paths import slam_dir
    from sportsngen.data.slam import list_slam_events, read_slam_events
    from sportsngen.data.tracking import RallyData
    from sportsngen.eval.reach import contact_rows, reach_rows
    from sportsngen.eval.rules import analyse_rally_data
    from sportsngen.synth import generate_matches
    from sportsngen.train.serve_bias import solve_shift

    n_points = 150 if quick else 1000
    data = generate_matches([("Roger Federer", "Rafael Nadal")], "hard", n_points, seed=0,
                            workers=2)
    n_rallies, n_frames = len(data.rallies), len(data.frames)
    rows = []

    def add(what: str, size: str, wall_s: float, per: float, unit: str) -> None:
        rows.append({"what": what, "size": size, "wall_s": wall_s, "rate": per, "unit": unit})
        print(f"analysis: {what} ({size}): {wall_s:.2f} s, {per:,.0f} {unit}")

    size = f"{n_rallies} rallies, {n_frames} frame rows"
    t, _ = _best(lambda: analyse_rally_data(data))
    add("rally-end rules, `eval.rules.analyse_rally_data`", size, t, n_rallies / t, "rallies/s")
    t, _ = _best(lambda: reach_rows(data))
    add("`eval.reach.reach_rows`", size, t, n_rallies / t, "rallies/s")
    t, _ = _best(lambda: contact_rows(data))
    add("`eval.reach.contact_rows`", size, t, n_rallies / t, "rallies/s")
    with tempfile.TemporaryDirectory() as folder:
        data.save(folder)   # read back and validated: the schema, the order check, the tracks
        t, _ = _best(lambda: RallyData.load(folder))
    add("a saved dataset read and validated, `data.tracking.RallyData.load`", size, t,
        n_rallies / t, "rallies/s")

    events = list_slam_events()[: 2 if quick else None] if slam_dir() is not None else []
    if events:
        # repair=True: a few rows of the 2012 files break the rules and are dropped, as users do
        t, pts = _best(lambda: read_slam_events(events=events, repair=True), repeats=1)
        add("real slam reader, `data.slam.read_slam_events(repair=True)`",
            f"{len(events)} events, {len(pts)} points", t, len(pts) / t, "points/s")

    g = torch.Generator().manual_seed(0)
    n_rows, n_bins, n_solves = (2000, 40, 20) if quick else (20000, 64, 20)
    logits = torch.randn(n_rows, n_bins, generator=g) * 2.0
    mask = (torch.arange(n_bins) % 3 == 0).expand(n_rows, -1)
    weight = mask.to(logits.dtype)
    t, _ = _best(lambda: [solve_shift(logits, mask, weight, 0.3 + 0.01 * k)
                          for k in range(n_solves)])
    add("table fits' shift, `train.serve_bias.solve_shift` (a 0 / 1 mask)",
        f"{n_solves} solves of {n_rows} x {n_bins} logits", t, n_solves / t, "solves/s")

    lines = [
        "## Analysis (rules, reach, slam reader, table fits)",
        "",
        f"`bench_analysis` in `bench/bench_analysis.py`: {n_points} generated points of Federer v "
        "Nadal on hard (seed 0), the real slam files of `../shared/data/slam_pointbypoint/` "
        "where present, and random logits for the shift solver; wall seconds, the best of "
        f"{REPEATS} runs (the slam files: one).",
        "",
        "| what | size | wall s | rate |",
        "|---|---|---:|---|",
    ]
    for r in rows:
        lines.append(f"| {r['what']} | {r['size']} | {r['wall_s']:.2f} | "
                     f"{r['rate']:,.0f} {r['unit']} |")
    if not events:
        lines += ["", "The slam reader was not timed: no data folder was found."]
    return lines, rows
