"""What `python simulate.py` does: play matches with the chosen engine, print and save them.

Engines:
- ``markov``: the i.i.d.-point baseline (`sportsngen.baselines.markov`), one serve model
  (`sportsngen.baselines.serve_model`) per player derived from the real 2011 Grand Slam data
  (bundled as derived figures, so it runs on a clone without ../shared/data).
- ``sportsngen`` (default): the learned engine (`sportsngen.sim.Simulator`) with the bundled
  model or `model_file=<file>`: prints the score line and the statistics table and writes the points
  table and the rallies (Parquet) and a few rally plots; with `extras=true` also an animated GIF
  of one point and the report's what-if shots.

Both write the match report of the first match, `report.html` (`sportsngen.report`), unless
`report=false`.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import pandas as pd
from omegaconf import DictConfig, OmegaConf

from sportsngen.baselines.markov_match import (
    play_markov_matches,
    serve_points_won,
    win_probability_path,
)
from sportsngen.data.tracking import SURFACES
from sportsngen.errors import check_choice, check_int, check_players
from sportsngen.eval.stats import serve_stats, serve_stats_table
from sportsngen.sim.lookahead import lookahead_workers
from sportsngen.sim.match import winner_view
from sportsngen.tennis.scoring import MatchFormat
from sportsngen.viz.match_figures import plot_win_probability, rally_figures

log = logging.getLogger(__name__)

ENGINES = ("markov", "sportsngen")


def run_markov(cfg: DictConfig, fmt: MatchFormat, out_dir: Path) -> pd.DataFrame:
    """Play `cfg.n_matches` matches with the Markov engine; print, plot, return the points."""
    names = (str(cfg.player1), str(cfg.player2))
    tables = []
    matches = play_markov_matches(names, fmt, str(cfg.surface), int(cfg.n_matches),
                                  int(cfg.seed), int(cfg.first_server))
    for i, (points, final) in enumerate(matches):
        tables.append(points)
        print(f"match {i + 1}: {names[final.winner]} d. {names[1 - final.winner]}  "
              f"{winner_view(final)}  ({len(points)} points)")
        if i == 0:
            probs = win_probability_path(points, *serve_points_won(names), fmt, names[0],
                                         int(cfg.first_server))
            plot_win_probability(probs, names, f"{names[0]} v {names[1]}: "
                                 f"{final.score_str()}", out_dir / "win_probability.png")
            if cfg.get("report", True):
                from sportsngen.report.simulated import markov_match_report

                line = f"{names[final.winner]} d. {names[1 - final.winner]} {winner_view(final)}"
                path = markov_match_report(points, names, fmt, line, str(cfg.surface),
                                           out_dir / "report.html")
                print(f"report: {path}")
    return pd.concat(tables, ignore_index=True)


def run_simulation(cfg: DictConfig) -> pd.DataFrame:
    """Entry point of `simulate.py`: returns the points table of every simulated match."""
    if cfg.engine not in ENGINES:
        raise ValueError(f"engine must be one of {ENGINES}, got {cfg.engine!r}")
    check_int("n_matches", cfg.n_matches, 1)
    check_int("seed", cfg.seed, 0)
    check_choice("surface", cfg.surface, SURFACES)
    check_players(cfg.player1, cfg.player2, ("player1", "player2"))
    fmt = MatchFormat(**OmegaConf.to_container(cfg.format, resolve=True))
    out_dir = Path(str(cfg.output_dir))
    out_dir.mkdir(parents=True, exist_ok=True)
    print(f"{cfg.player1} v {cfg.player2}, {cfg.surface}, best of {fmt.best_of}, "
          f"engine={cfg.engine}, seed={cfg.seed}")
    points = run_markov(cfg, fmt, out_dir) if cfg.engine == "markov" else \
        run_learned(cfg, fmt, out_dir)
    print()
    print(serve_stats_table(serve_stats(points)))
    points.to_parquet(out_dir / "points.parquet", index=False)
    print(f"\nwrote {out_dir}/: points.parquet"
          + (", win_probability.png" if cfg.engine == "markov" else
             ", rallies/, rally_*.png"
             + (", point.gif" if _gif_frames(cfg) else ""))
          + (", report.html" if cfg.get("report", True) else ""))
    return points


def run_learned(cfg: DictConfig, fmt: MatchFormat, out_dir: Path) -> pd.DataFrame:
    """Play `cfg.n_matches` matches (batched together) with the learned engine."""
    from sportsngen.sim.simulator import SAMPLING_OPTIONS, Simulator

    kw = {k: kind(cfg[k]) for k, kind in SAMPLING_OPTIONS.items() if cfg.get(k) is not None}
    if cfg.get("top_p") is not None:     # one nucleus for both, over their own
        kw.update(top_p_player=float(cfg.top_p), top_p_ball=float(cfg.top_p))
    lookahead = lookahead_workers(cfg.get("lookahead", 0), int(cfg.n_matches))
    sim = Simulator.from_pretrained(cfg.get("model_file"), **kw)
    names = (str(cfg.player1), str(cfg.player2))
    results = sim.simulate_matches([names] * int(cfg.n_matches), str(cfg.surface), fmt=fmt,
                                   seed=int(cfg.seed), first_server=int(cfg.first_server),
                                   lookahead=lookahead)
    for i, res in enumerate(results):
        print(f"match {i + 1}: {res.score_line}  ({len(res.points)} points, "
              f"{res.n_discarded} rallies set aside as non-realistic or undecided, "
              f"{res.forced_decisions} counted without a realistic replay)")
    first = results[0]
    first.rallies.save(out_dir / "rallies")
    if first.discarded is not None:       # set-aside rallies are kept, for the record
        first.discarded.save(out_dir / "discarded")
    rally_figures(first, out_dir, max_gif_frames=_gif_frames(cfg))
    if cfg.get("report", True):
        from sportsngen.report.simulated import learned_match_report

        t0 = time.perf_counter()
        path = learned_match_report(
            first, out_dir / "report.html", sim=sim,
            whatif_shots=_extra(cfg, "report_whatif_shots", 2),
            whatif_rollouts=int(cfg.get("report_whatif_rollouts", 24)), seed=int(cfg.seed),
            model_name=str(cfg.get("model_file") or "bundled sportsngen-small"))
        print(f"report: {path} ({time.perf_counter() - t0:.1f} s)")
    return pd.concat([r.points for r in results], ignore_index=True)


def _extra(cfg: DictConfig, key: str, full: int) -> int:
    """An extra's setting: `cfg[key]` where given, else `full` with `extras=true` and 0
    (none) without: the GIF and the what-if shots are most of the demo's time after the
    match (a 150-frame GIF ~8 s, two what-if shots ~30 s on 2 cores)."""
    value = cfg.get(key)
    if value is None:
        return full if cfg.get("extras", False) else 0
    return check_int(key, value, 0)


def _gif_frames(cfg: DictConfig) -> int:
    """`animation_max_frames`: point.gif's most frames (0: no GIF)."""
    return _extra(cfg, "animation_max_frames", 150)
