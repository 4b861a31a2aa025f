"""Calibration back-test of the live win probability on every recorded slam match.

Before each point of each finished match of the shared events, the live model
(`sportsngen.report.live`) says P(player 1 wins the match); the outcome is who won. Its
expected calibration error, Brier score and reliability diagram (`sportsngen.eval.calibration`)
stand beside three references: the same model's pre-match probability held all match long
(what the live score adds), the base rate (the share of matches player 1 of the files won,
constant) and 50/50. The points of one match share one outcome, so they are far from
independent: every interval resamples whole matches (`cluster_bootstrap`).

Matches that end unfinished in the recording (retirements, lost recordings) have no outcome
decided by play and are left out (counted). The serve figures come from the 2011 US Open and
Wimbledon: the 2011 events are in-sample, the 2012 ones out-of-sample; both are reported.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from sportsngen.baselines.markov import match_win_probability
from sportsngen.data.slam import _event_files, list_slam_events, read_slam_raw
from sportsngen.eval.calibration import (
    brier_score,
    cluster_bootstrap,
    expected_calibration_error,
    reliability_table,
)
from sportsngen.eval.markdown import markdown_table as table_lines
from sportsngen.report.figures import ATTRIBUTION
from sportsngen.report.live import serve_odds
from sportsngen.report.real import replay_event_matches, slam_folder
from sportsngen.tennis.scoring import MatchState

PREDICTORS = ("live", "pre-match", "base rate", "50/50")
N_BINS = 10


def live_predictions(folder: str | Path | None = None, events=None,
                     progress: bool = True) -> pd.DataFrame:
    """One row a point of every finished recorded match: event, match_id, gender, p_live
    (P(player 1 wins) before the point), p_pre (the same at 0-0), y (1.0 if player 1 won).
    ``attrs["unfinished"]``: match ids left out."""
    folder = slam_folder(folder)
    events = list_slam_events(folder) if events is None else list(events)
    parts, unfinished = [], []
    for event in tqdm(events, desc="events", disable=not progress):
        raw = read_slam_raw(*_event_files(folder, event), repair=True)
        for m in replay_event_matches(raw):
            final = m.final
            if not final.is_over:
                unfinished.append(m.match_id)
                continue
            pa, pb = serve_odds(*m.players, gender=m.gender).p_serve
            live = [match_win_probability(pa, pb, state=s) for s in m.states]
            pre = match_win_probability(pa, pb, state=MatchState.new(m.fmt))
            parts.append(pd.DataFrame({
                "event": event, "match_id": m.match_id, "gender": m.gender,
                "p_live": live, "p_pre": pre, "y": float(final.winner == 0)}))
    out = pd.concat(parts, ignore_index=True)
    out.attrs["unfinished"] = unfinished
    return out


def predictor_values(preds: pd.DataFrame) -> dict[str, np.ndarray]:
    """Each of `PREDICTORS` at every point of `preds`."""
    base = float(preds.groupby("match_id")["y"].first().mean())
    n = len(preds)
    return {"live": preds["p_live"].to_numpy(float), "pre-match": preds["p_pre"].to_numpy(float),
            "base rate": np.full(n, base), "50/50": np.full(n, 0.5)}


def backtest_table(preds: pd.DataFrame, n_boot: int = 1000, seed: int = 0,
                   n_bins: int = N_BINS) -> pd.DataFrame:
    """Per predictor: ECE and Brier with 95 % match-bootstrap intervals, points, matches."""
    values = predictor_values(preds)
    y = preds["y"].to_numpy(float)

    def stat(idx: np.ndarray) -> np.ndarray:
        return np.array([[expected_calibration_error(p[idx], y[idx], n_bins),
                          brier_score(p[idx], y[idx])] for p in values.values()])

    lo, hi = cluster_bootstrap(stat, preds["match_id"].to_numpy(), n_boot, seed)
    point = stat(np.arange(len(preds)))
    rows = [{"predictor": name, "ece": point[k, 0], "ece_lo": lo[k, 0], "ece_hi": hi[k, 0],
             "brier": point[k, 1], "brier_lo": lo[k, 1], "brier_hi": hi[k, 1]}
            for k, name in enumerate(values)]
    out = pd.DataFrame(rows).set_index("predictor")
    out["points"] = len(preds)
    out["matches"] = preds["match_id"].nunique()
    return out


def reliability_with_intervals(pred: np.ndarray, preds: pd.DataFrame, n_boot: int = 1000,
                               seed: int = 0, n_bins: int = N_BINS) -> pd.DataFrame:
    """`reliability_table` of `pred` against `preds.y`, with 95 % match-bootstrap intervals
    of each bin's observed frequency."""
    y = preds["y"].to_numpy(float)
    table = reliability_table(pred, y, n_bins)
    lo, hi = cluster_bootstrap(lambda i: reliability_table(pred[i], y[i], n_bins)["observed"],
                               preds["match_id"].to_numpy(), n_boot, seed)
    table["observed_lo"], table["observed_hi"] = lo, hi
    return table


def plot_backtest(preds: pd.DataFrame, reliability: pd.DataFrame, table: pd.DataFrame,
                  path: str | Path, title: str = "") -> Path:
    """Reliability diagram of the live model (95 % match-bootstrap intervals) with the
    pre-match model, the base rate and 50/50, above the histogram of live predictions."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    values = predictor_values(preds)
    y = preds["y"].to_numpy(float)
    fig, (ax, hx) = plt.subplots(2, 1, figsize=(6.2, 7.6), height_ratios=(3, 1.2))
    ax.plot([0, 1], [0, 1], color="grey", ls="--", lw=1, label="perfect calibration")
    r = reliability[reliability["count"] > 0]
    err = np.vstack([r["observed"] - r["observed_lo"], r["observed_hi"] - r["observed"]])
    row = table.loc["live"]
    ax.errorbar(r["mean_pred"], r["observed"], yerr=err, marker="o", color="tab:red", capsize=3,
                zorder=3, label=f"live (ECE {row.ece:.3f}, Brier {row.brier:.3f}; 95 % "
                                "intervals resampling matches)")
    styles = {"pre-match": ("tab:blue", "s"), "base rate": ("tab:green", "D"),
              "50/50": ("black", "^")}
    for name, (colour, marker) in styles.items():
        t = reliability_table(values[name], y, N_BINS)
        t = t[t["count"] > 0]
        row = table.loc[name]
        ax.plot(t["mean_pred"], t["observed"], marker=marker, color=colour, lw=1, ms=5,
                label=f"{name} (ECE {row.ece:.3f}, Brier {row.brier:.3f})")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_xlabel("predicted P(player 1 wins the match), before each point")
    ax.set_ylabel("share of those points whose match player 1 won")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="upper left")
    hx.hist(values["live"], bins=np.linspace(0, 1, 41), color="tab:red", alpha=0.7)
    hx.set_xlabel("live prediction")
    hx.set_ylabel("points")
    fig.text(0.01, 0.005, f"Data: {ATTRIBUTION}", fontsize=6, color="0.4")
    fig.tight_layout(rect=(0, 0.015, 1, 1))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def markdown_table(tables: dict[str, pd.DataFrame]) -> str:
    """The back-test figures as a Markdown table, one block of rows per subset."""
    rows = [(subset, name, f"{r.ece:.3f} ({r.ece_lo:.3f}-{r.ece_hi:.3f})",
             f"{r.brier:.3f} ({r.brier_lo:.3f}-{r.brier_hi:.3f})", int(r.points), int(r.matches))
            for subset, t in tables.items() for name, r in t.iterrows()]
    return "\n".join(table_lines(["subset", "predictor", "ECE (95 % CI)", "Brier (95 % CI)",
                                   "points", "matches"], rows))


def run_backtest(out_dir: str | Path, folder: str | Path | None = None, events=None,
                 n_boot: int = 1000, seed: int = 0, progress: bool = True) -> dict:
    """The whole back-test: figures for all events, 2011 (in-sample serve figures) and 2012
    (out-of-sample), the reliability diagram of all events; written to `out_dir` as
    backtest.md, backtest.json and backtest_reliability.png. Returns the tables."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    preds = live_predictions(folder, events, progress)
    year = preds["event"].str[:4]
    subsets = {"all events": preds}
    for y in sorted(year.unique()):
        subsets[f"{y} events"] = preds[year == y].reset_index(drop=True)
    tables = {name: backtest_table(p, n_boot, seed) for name, p in
              tqdm(subsets.items(), desc="bootstrap", disable=not progress)}
    reliability = reliability_with_intervals(preds["p_live"].to_numpy(float), preds, n_boot,
                                             seed)
    events_txt = ", ".join(sorted(preds["event"].unique()))
    plot_backtest(preds, reliability, tables["all events"], out_dir / "backtest_reliability.png",
                  title=f"Live win probability before each point\n{events_txt}\n"
                        f"{preds['match_id'].nunique()} finished matches, {len(preds)} points")
    md = markdown_table(tables)
    unfinished = preds.attrs.get("unfinished", [])
    (out_dir / "backtest.md").write_text(
        f"Events: {events_txt}. Unfinished matches left out: {len(unfinished)}. Intervals: "
        f"{n_boot} match-bootstrap resamples. Data: {ATTRIBUTION}.\n\n{md}\n")
    doc = {"events": sorted(preds["event"].unique()), "n_boot": n_boot,
           "unfinished": unfinished, "attribution": ATTRIBUTION,
           "tables": {k: t.reset_index().to_dict(orient="records") for k, t in tables.items()},
           "reliability_live": reliability.to_dict(orient="records")}
    (out_dir / "backtest.json").write_text(json.dumps(doc, indent=1))
    return {"tables": tables, "reliability": reliability, "markdown": md,
            "n_unfinished": len(unfinished)}
