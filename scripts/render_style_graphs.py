"""Render style graphs (SkillVis style) and placement / recovery heatmaps (Vid2Player style).

Ground truth: synthetic tracking of four named players (`generate_matches`). Simulated: the
shot-cycle model fitted on that ground truth plays the same matchups (`simulate_points`), or
any `RallyData` folder given with ``--simulated`` (e.g. the SportsNGEN simulator's output, once
it exists). A second ground-truth sample (another seed) gives the similarity a finite sample of
the same players reaches: the ceiling to read the simulated scores against.

Writes into ``--out`` (default docs/figures/style/): ``style_graphs.png`` (ground truth above,
simulated below on the ground truth's nodes), ``heatmaps_<who>_<player>.png`` for two players,
and ``summary.json`` (skill indices, similarity scores, timings). Usage:

    .venv/bin/python scripts/render_style_graphs.py [--points 400] [--sim-points N]
        [--seed 0] [--surface hard] [--threshold 1.5] [--simulated FOLDER] [--out DIR]

(points are per matchup; about 3 minutes on one CPU core with the defaults)
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

from sportsngen.baselines.shot_cycle import fit_shot_cycle  # noqa: E402
from sportsngen.baselines.shot_cycle_sim import simulate_points  # noqa: E402
from sportsngen.baselines.shot_cycle_table import shot_table  # noqa: E402
from sportsngen.data.tracking import RallyData  # noqa: E402
from sportsngen.eval.stats import serve_stats  # noqa: E402
from sportsngen.eval.style_graph import (  # noqa: E402
    build_style_graph,
    edge_overlap,
    graph_on_nodes,
    shot_cycles,
)
from sportsngen.synth.generate import generate_matches  # noqa: E402
from sportsngen.viz.heatmaps import plot_player_heatmaps  # noqa: E402
from sportsngen.viz.style_graph_plot import plot_style_graphs  # noqa: E402

PLAYERS = ("Roger Federer", "Rafael Nadal", "Novak Djokovic", "Serena Williams")
MATCHUPS = (("Roger Federer", "Rafael Nadal"), ("Novak Djokovic", "Roger Federer"),
            ("Rafael Nadal", "Novak Djokovic"), ("Serena Williams", "Maria Sharapova"))
HEATMAP_PLAYERS = ("Roger Federer", "Rafael Nadal")


def per_matchup(play) -> RallyData:
    """`play(i, a, b)` for every matchup, concatenated with unique rally and match ids."""
    return RallyData.concat([play(i, a, b) for i, (a, b) in enumerate(MATCHUPS)],
                            renumber=True)


def ground_truth(surface: str, n_points: int, seed: int) -> RallyData:
    return per_matchup(lambda i, a, b: generate_matches([(a, b)], surface, n_points,
                                                        seed * 1000 + i, workers=1))


def simulate_matchups(model, surface: str, n_points: int, seed: int) -> RallyData:
    return per_matchup(lambda i, a, b: simulate_points(model, a, b, surface, n_points,
                                                       seed * 1000 + 100 + i))


def slug(name: str) -> str:
    return name.lower().replace(" ", "_")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--points", type=int, default=400, help="ground-truth points a matchup")
    ap.add_argument("--sim-points", type=int, default=None,
                    help="simulated points a matchup (default: --points, so that skill indices "
                         "compare like with like)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--surface", default="hard")
    ap.add_argument("--threshold", type=float, default=1.5, help="node distance threshold, m")
    ap.add_argument("--simulated", type=Path, default=None, help="RallyData folder to compare")
    ap.add_argument("--out", type=Path, default=Path("docs/figures/style"))
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}

    t0 = time.perf_counter()
    sim_points = args.sim_points or args.points
    truth = ground_truth(args.surface, args.points, args.seed)
    truth2 = ground_truth(args.surface, args.points, args.seed + 1)
    timings["generate_ground_truth_2x_s"] = time.perf_counter() - t0

    if args.simulated is not None:
        t0 = time.perf_counter()
        sim = RallyData.load(args.simulated, validate=False)
        sim_label = f"simulated ({args.simulated.name})"
        timings["load_simulated_s"] = time.perf_counter() - t0
    else:
        t0 = time.perf_counter()
        model = fit_shot_cycle(truth)
        timings["fit_shot_cycle_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        sim = simulate_matchups(model, args.surface, sim_points, args.seed)
        timings["simulate_shot_cycle_s"] = time.perf_counter() - t0
        timings["simulate_shot_cycle_per_point_ms"] = \
            1000 * timings["simulate_shot_cycle_s"] / (sim_points * len(MATCHUPS))
        sim_label = "shot-cycle model"

    t0 = time.perf_counter()
    tables = {k: shot_table(d) for k, d in (("truth", truth), ("truth2", truth2), ("sim", sim))}
    cycles = {k: shot_cycles(t) for k, t in tables.items()}
    rows: list[dict] = []
    ref_graphs, sim_graphs, layouts = [], [], []
    for p in PLAYERS:
        g = build_style_graph(cycles["truth"], p, args.threshold, args.seed)
        g_own = build_style_graph(cycles["sim"], p, args.threshold, args.seed)
        g_on = graph_on_nodes(g, cycles["sim"])
        g2 = graph_on_nodes(g, cycles["truth2"])
        rows.append({"player": p, "nodes": g.n_nodes, "skill_index_truth": g.skill_index,
                     "skill_index_truth2": build_style_graph(cycles["truth2"], p,
                                                             args.threshold,
                                                             args.seed).skill_index,
                     "skill_index_sim": g_own.skill_index, "nodes_sim": g_own.n_nodes,
                     "similarity_sim": edge_overlap(g, g_on),
                     "similarity_truth2": edge_overlap(g, g2),
                     "cycles_truth": int(g.node_counts.sum()),
                     "cycles_sim": int(g_on.node_counts.sum())})
        ref_graphs.append(g)
        sim_graphs.append(g_on)
        layouts.append(g.layout())
    timings["style_graphs_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    titles = [[f"{r['player']}\nground truth: skill index {r['skill_index_truth']:.2f}"
               for r in rows],
              [f"{r['player']}\n{sim_label}: SI {r['skill_index_sim']:.2f}, "
               f"similarity {r['similarity_sim']:.2f}" for r in rows]]
    plot_style_graphs([ref_graphs, sim_graphs], titles, [[None] * 4, layouts],
                      path=args.out / "style_graphs.png", dpi=80)
    for p in HEATMAP_PLAYERS:
        for who, key in (("truth", "truth"), ("sim", "sim")):
            plot_player_heatmaps(tables[key], p, path=args.out / f"heatmaps_{who}_{slug(p)}.png",
                                 surface=args.surface, dpi=70)
    timings["figures_s"] = time.perf_counter() - t0

    serve = {k: serve_stats(d.points()).round(3).reset_index().to_dict(orient="records")
             for k, d in (("truth", truth), ("sim", sim))}
    summary = {"players": rows, "threshold_m": args.threshold, "seed": args.seed,
               "surface": args.surface, "points_truth_per_matchup": args.points,
               "simulated": sim_label, "points_sim": int(len(sim.points())),
               "serve_stats": serve, "timings_s": {k: round(v, 2) for k, v in timings.items()}}
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(f"{'player':<16} {'nodes':>5} {'SI truth':>8} {'SI truth2':>9} {'SI sim':>7} "
          f"{'sim vs truth':>12} {'truth2 vs truth':>15}")
    for r in rows:
        print(f"{r['player']:<16} {r['nodes']:>5} {r['skill_index_truth']:>8.2f} "
              f"{r['skill_index_truth2']:>9.2f} {r['skill_index_sim']:>7.2f} "
              f"{r['similarity_sim']:>12.3f} {r['similarity_truth2']:>15.3f}")
    print(json.dumps(summary["timings_s"], indent=2))


if __name__ == "__main__":
    main()
