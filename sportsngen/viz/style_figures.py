"""Style graphs (SkillVis style) and placement / recovery heatmaps (Vid2Player style) of
simulated play against the ground truth: `scripts/render_style_graphs.py` is the command line.

Ground truth: synthetic tracking of four named players (`generate_matches`). Simulated: the
shot-cycle model fitted on that ground truth plays the same matchups (`simulate_points`), or
any given `RallyData`. A second ground-truth sample (another seed) gives the similarity a
finite sample of the same players reaches: the ceiling to read the simulated scores against.
"""

from __future__ import annotations

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
from sportsngen.eval.style_graph import compare_style_graphs, shot_cycles  # noqa: E402
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


def render_style_graphs(out: Path, n_points: int = 400, sim_points: int | None = None,
                        seed: int = 0, surface: str = "hard", threshold_m: float = 1.5,
                        simulated: Path | None = None) -> dict:
    """Write ``style_graphs.png`` (ground truth above, simulated below on the ground truth's
    nodes), ``heatmaps_<who>_<player>.png`` for two players and ``summary.json`` (skill
    indices, similarity scores, timings) into `out`, print the scores; -> the summary.
    `n_points` and `sim_points` (default `n_points`, so that skill indices compare like with
    like) are per matchup; `simulated` a `RallyData` folder to compare instead of the
    shot-cycle model."""
    out.mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}

    t0 = time.perf_counter()
    sim_points = sim_points or n_points
    truth = ground_truth(surface, n_points, seed)
    truth2 = ground_truth(surface, n_points, seed + 1)
    timings["generate_ground_truth_2x_s"] = time.perf_counter() - t0

    if simulated is not None:
        t0 = time.perf_counter()
        sim = RallyData.load(simulated, validate=False)
        sim_label = f"simulated ({simulated.name})"
        timings["load_simulated_s"] = time.perf_counter() - t0
    else:
        t0 = time.perf_counter()
        model = fit_shot_cycle(truth)
        timings["fit_shot_cycle_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        sim = simulate_matchups(model, surface, sim_points, seed)
        timings["simulate_shot_cycle_s"] = time.perf_counter() - t0
        timings["simulate_shot_cycle_per_point_ms"] = \
            1000 * timings["simulate_shot_cycle_s"] / (sim_points * len(MATCHUPS))
        sim_label = "shot-cycle model"

    t0 = time.perf_counter()
    tables = {k: shot_table(d) for k, d in (("truth", truth), ("truth2", truth2), ("sim", sim))}
    cycles = {k: shot_cycles(t) for k, t in tables.items()}
    rows, ref_graphs, sim_graphs = compare_style_graphs(cycles, PLAYERS, threshold_m, seed)
    layouts = [g.layout() for g in ref_graphs]
    timings["style_graphs_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    titles = [[f"{r['player']}\nground truth: skill index {r['skill_index_truth']:.2f}"
               for r in rows],
              [f"{r['player']}\n{sim_label}: SI {r['skill_index_sim']:.2f}, "
               f"similarity {r['similarity_sim']:.2f}" for r in rows]]
    plot_style_graphs([ref_graphs, sim_graphs], titles, [[None] * 4, layouts],
                      path=out / "style_graphs.png", dpi=80)
    for p in HEATMAP_PLAYERS:
        for who, key in (("truth", "truth"), ("sim", "sim")):
            plot_player_heatmaps(tables[key], p, path=out / f"heatmaps_{who}_{slug(p)}.png",
                                 surface=surface, dpi=70)
    timings["figures_s"] = time.perf_counter() - t0

    serve = {k: serve_stats(d.points()).round(3).reset_index().to_dict(orient="records")
             for k, d in (("truth", truth), ("sim", sim))}
    summary = {"players": rows, "threshold_m": threshold_m, "seed": seed,
               "surface": surface, "points_truth_per_matchup": n_points,
               "simulated": sim_label, "points_sim": int(len(sim.points())),
               "serve_stats": serve, "timings_s": {k: round(v, 2) for k, v in timings.items()}}
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(f"{'player':<16} {'nodes':>5} {'SI truth':>8} {'SI truth2':>9} {'SI sim':>7} "
          f"{'sim vs truth':>12} {'truth2 vs truth':>15}")
    for r in rows:
        print(f"{r['player']:<16} {r['nodes']:>5} {r['skill_index_truth']:>8.2f} "
              f"{r['skill_index_truth2']:>9.2f} {r['skill_index_sim']:>7.2f} "
              f"{r['similarity_sim']:>12.3f} {r['similarity_truth2']:>15.3f}")
    print(json.dumps(summary["timings_s"], indent=2))
    return summary
