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
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd
from omegaconf import DictConfig, OmegaConf
from tqdm.auto import tqdm

from sportsngen.baselines.markov import match_win_probability
from sportsngen.baselines.serve_model import serve_model, simulate_match_points
from sportsngen.data.tracking import SURFACES
from sportsngen.errors import check_choice, check_int, check_players
from sportsngen.eval.stats import serve_stats, serve_stats_table
from sportsngen.sim.match import winner_view
from sportsngen.tennis.scoring import MatchFormat, MatchState

log = logging.getLogger(__name__)

ENGINES = ("markov", "sportsngen")


def win_probability_path(points: pd.DataFrame, pa: float, pb: float, fmt: MatchFormat,
                         player1: str, first_server: int) -> np.ndarray:
    """Player 1's match-win probability before each point and after the last (Markov, exact)."""
    state = MatchState.new(fmt, first_server=first_server)
    probs = [match_win_probability(pa, pb, fmt, state)]
    for winner in points["winner"]:
        state = state.point_won(0 if winner == player1 else 1)
        probs.append(1.0 if state.is_over and state.winner == 0 else
                     0.0 if state.is_over else match_win_probability(pa, pb, fmt, state))
    return np.asarray(probs)


def _plot_win_probability(probs: np.ndarray, names: tuple[str, str], title: str,
                          path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 3.5))
    ax.plot(np.arange(len(probs)), probs, color="tab:blue", lw=1.5)
    ax.axhline(0.5, color="grey", lw=0.8, ls="--")
    ax.set_ylim(0, 1)
    ax.set_xlabel("point")
    ax.set_ylabel(f"P({names[0]} wins)")
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run_markov(cfg: DictConfig, fmt: MatchFormat, out_dir: Path) -> pd.DataFrame:
    """Play `cfg.n_matches` matches with the Markov engine; print, plot, return the points."""
    names = (str(cfg.player1), str(cfg.player2))
    models = (serve_model(names[0]), serve_model(names[1]))
    pa = models[0].adjusted_against(models[1]).serve_points_won
    pb = models[1].adjusted_against(models[0]).serve_points_won
    tables = []
    for i in tqdm(range(int(cfg.n_matches)), desc="matches", disable=cfg.n_matches < 2):
        points, final = simulate_match_points(
            models[0], models[1], names=names, fmt=fmt, surface=str(cfg.surface),
            seed=int(cfg.seed) + i, match_id=f"sim-{i + 1}", first_server=int(cfg.first_server))
        tables.append(points)
        print(f"match {i + 1}: {names[final.winner]} d. {names[1 - final.winner]}  "
              f"{winner_view(final)}  ({len(points)} points)")
        if i == 0:
            probs = win_probability_path(points, pa, pb, fmt, names[0], int(cfg.first_server))
            _plot_win_probability(probs, names, f"{names[0]} v {names[1]}: "
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
    _rally_figures(first, out_dir, max_gif_frames=_gif_frames(cfg))
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


def lookahead_workers(setting, n_matches: int, cores: int | None = None) -> int:
    """`simulate.py`'s `lookahead` -> worker processes for `sim.lookahead`: a count, or "auto":
    one where a single match is played on a machine with 2 or more cores (`cores`, default
    the cores this process may run on), else none. On 2 cores a best-of-3 took 54.0 s
    without and 50.0 s with one worker, the same match (docs/benchmarks.md); several matches
    already play their rallies together."""
    if setting != "auto":
        workers = check_int("lookahead", setting, 0, 64)
    else:
        if cores is None:
            cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") \
                else (os.cpu_count() or 1)
        workers = 1 if cores >= 2 else 0
    return workers if n_matches == 1 else 0


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


def _rally_figures(res, out_dir: Path, n_plots: int = 3, max_gif_frames: int = 150) -> None:
    """Plots of the longest rallies of the match and an animation of the longest one, of at
    most `max_gif_frames` frames (so that a long rally does not take minutes to render; 0: no
    animation)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sportsngen.viz.court_plot import animate_rally, plot_rally

    r = res.rallies.rallies.sort_values("rally_length", ascending=False, kind="stable")
    for k, rid in enumerate(r["rally_id"].head(n_plots)):
        fig = plot_rally(res.rallies, int(rid), out_dir / f"rally_{k + 1}.png")
        plt.close(fig)
    if len(r) and max_gif_frames > 0:
        rid = int(r["rally_id"].iat[0])
        n = int((res.rallies.frames["rally_id"] == rid).sum() // 3)
        every = max(2, -(-n // max_gif_frames))
        animate_rally(res.rallies, rid, out_dir / "point.gif", every=every)
