"""The realism report: simulated play against a reference (and real slam figures), as
``report.md``, ``metrics.csv`` (`sportsngen.eval.physical.METRIC_COLUMNS`) and figures.

    from sportsngen.eval.report import load_real_points, write_report
    write_report(sim, ref, "outputs/report", real_points=load_real_points(["Roger Federer"]))

Figures are drawn on Agg canvases (no pyplot state, no display needed).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from sportsngen.data.paths import SHARED_DATA_MISSING, slam_dir
from sportsngen.data.slam import list_slam_events, read_slam_events
from sportsngen.data.tracking import RallyData
from sportsngen.eval.physical import (
    ALL,
    QUANTITIES,
    REAL_QUANTITIES,
    Sample,
    collect,
    compare,
    real_serve_speeds,
)

SOURCES = ("sim", "ref", "real")
COLOURS = {"sim": "C0", "ref": "C1", "real": "C2"}
FIGURES = {"speeds": "figures/speeds.png", "rally_length": "figures/rally_length.png",
           "bounce": "figures/bounce_ratio.png"}
_DIGITS = {"m": 2, "km/h": 1, "ratio": 3}


def load_real_points(players, year: int = 2011, folder: str | Path | None = None
                     ) -> pd.DataFrame:
    """Real slam points of `year` served by any of `players` (against anyone).

    Reads every event of that year in `folder` (default: the shared data, `slam_dir()`).
    Raises FileNotFoundError with `SHARED_DATA_MISSING` when the data is absent, ValueError
    when the year has no events or none of the players serves in them.
    """
    folder = slam_dir() if folder is None else Path(folder)
    if folder is None or not Path(folder).is_dir():
        raise FileNotFoundError(SHARED_DATA_MISSING)
    events = [e for e in list_slam_events(folder) if e.startswith(f"{year}-")]
    if not events:
        raise ValueError(f"no slam events of {year} in {folder}")
    points = read_slam_events(folder, events)
    players = [str(p) for p in players]
    out = points[points["server"].astype(str).isin(players)].reset_index(drop=True)
    if out.empty:
        raise ValueError(f"none of {players} serves in the {year} slam data ({events})")
    return out


# -- figures ----------------------------------------------------------------------------------
def _figure(ncols: int, nrows: int = 1, size=(4.0, 3.2)) -> Figure:
    fig = Figure(figsize=(size[0] * ncols, size[1] * nrows), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _speed_figure(samples: dict[str, pd.DataFrame], names: dict[str, str], path: Path) -> None:
    """Density overlays of each quantity (all players pooled)."""
    fig = _figure(3, 2)
    axes = fig.subplots(2, 3).ravel()
    for ax, q in zip(axes, QUANTITIES):
        vals = {k: s.loc[s["quantity"] == q, "value"].to_numpy(float)
                for k, s in samples.items()}
        vals = {k: v for k, v in vals.items() if len(v)}
        if not vals:
            ax.text(0.5, 0.5, "no samples", ha="center", va="center", transform=ax.transAxes)
        else:
            edges = np.histogram_bin_edges(np.concatenate(list(vals.values())), bins=30)
            for k, v in vals.items():
                ax.hist(v, bins=edges, density=True, histtype="step", lw=1.5,
                        color=COLOURS[k], label=f"{names[k]} (n={len(v)})")
            ax.legend(fontsize=7)
        ax.set_xlabel(f"{q} ({QUANTITIES[q]})")
        ax.set_ylabel("density")
    axes[-1].axis("off")
    fig.savefig(path, dpi=110)


def _rally_figure(metrics: pd.DataFrame, names: dict[str, str], path: Path) -> None:
    """Share of points by rally length (all servers pooled), one bar a source and bin."""
    m = metrics[(metrics["section"] == "rally") & (metrics["group"] == ALL)
                & metrics["statistic"].str.startswith("share_")]
    bins = [s[len("share_"):] for s in m["statistic"]]
    keys = [k for k in names if m[k].notna().any()]
    fig = _figure(1, size=(6.0, 3.6))
    ax = fig.subplots()
    width = 0.8 / max(len(keys), 1)
    x = np.arange(len(bins))
    for i, k in enumerate(keys):
        ax.bar(x + (i - (len(keys) - 1) / 2) * width, m[k].to_numpy(float), width,
               color=COLOURS[k], label=names[k])
    ax.set_xticks(x, bins)
    ax.set_xlabel("rally length (shots in, slam definition)")
    ax.set_ylabel("share of points")
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110)


def _bounce_figure(bounces: dict[str, pd.DataFrame], names: dict[str, str], path: Path) -> None:
    """Box plots of the bounce speed ratio, by surface and source."""
    surfaces = sorted(set().union(*(set(b["surface"].astype(str)) for b in bounces.values())))
    fig = _figure(1, size=(max(4.0, 2.5 * len(surfaces)), 3.6))
    ax = fig.subplots()
    if not surfaces:
        ax.text(0.5, 0.5, "no measurable bounces", ha="center", va="center",
                transform=ax.transAxes)
    width = 0.8 / len(bounces)
    for i, (k, b) in enumerate(bounces.items()):
        data = [b.loc[b["surface"].astype(str) == s, "ratio"].to_numpy(float) for s in surfaces]
        pos = np.arange(len(surfaces)) + (i - (len(bounces) - 1) / 2) * width
        keep = [j for j, d in enumerate(data) if len(d)]
        if keep:
            bp = ax.boxplot([data[j] for j in keep], positions=pos[keep], widths=width * 0.9,
                            patch_artist=True, showfliers=False,
                            medianprops={"color": "black"})
            for box in bp["boxes"]:
                box.set_facecolor(COLOURS[k])
                box.set_alpha(0.6)
        ax.plot([], [], "s", color=COLOURS[k], label=names[k])
    ax.set_xticks(np.arange(len(surfaces)), surfaces)
    ax.set_ylabel("speed after / before bounce")
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110)


# -- markdown ---------------------------------------------------------------------------------
def _fmt(v: float, digits: int, pct: bool = False) -> str:
    if v is None or not np.isfinite(v):
        return "-"
    return f"{100.0 * v:.1f}%" if pct else f"{v:.{digits}f}"


def _table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def _lookup(m: pd.DataFrame) -> dict[tuple[str, str, str, str], pd.Series]:
    """(section, metric, group, statistic) -> the row's source values."""
    keys = zip(m["section"], m["metric"], m["group"], m["statistic"])
    return {k: row for k, (_, row) in zip(keys, m[list(SOURCES)].iterrows())}


def _distribution_table(m: pd.DataFrame, section: str, keys: list[str], names: dict[str, str],
                        metrics_groups: list[tuple[str, str, str]]) -> str:
    """Rows (metric, group, unit): median [IQR] (n) per source, then Wasserstein distances."""
    header = ["quantity", "group"] + [f"{names[k]}: median [IQR] (n)" for k in keys]
    header += [f"W({names['sim']}, {names[k]})" for k in keys if k != "sim"]
    at = _lookup(m)
    nan = pd.Series(np.nan, index=list(SOURCES))
    rows = []
    for metric, group, unit in metrics_groups:
        d = _DIGITS[unit]
        n, med, iqr, w = (at.get((section, metric, group, st), nan)
                          for st in ("n", "median", "iqr", "wasserstein"))
        cells = ["-" if not np.isfinite(n[k]) or n[k] == 0 else
                 f"{_fmt(med[k], d)} [{_fmt(iqr[k], d)}] ({int(n[k])})" for k in keys]
        cells += [_fmt(w[k], d) for k in keys if k != "sim"]
        rows.append([metric, group] + cells)
    return _table(header, rows)


def _values_table(m: pd.DataFrame, section: str, keys: list[str], names: dict[str, str],
                  pct: set[str], digits: dict[str, int]) -> str:
    """Rows (group, metric, statistic), one column a source."""
    sub = m[m["section"] == section]
    header = ["group", "statistic"] + [names[k] for k in keys]
    rows = []
    for r in sub.itertuples(index=False):
        label = r.metric if r.statistic == "value" else f"{r.metric} {r.statistic}"
        is_pct = r.metric in pct or r.statistic.startswith("share_")
        d = digits.get(r.metric, digits.get(r.statistic, 2))
        rows.append([r.group, label] + [_fmt(getattr(r, k), d, is_pct) for k in keys])
    return _table(header, rows)


def _markdown(m: pd.DataFrame, sim: RallyData, ref: RallyData, names: dict[str, str],
              keys: list[str], real_points: pd.DataFrame | None) -> str:
    groups = list(dict.fromkeys(m.loc[m["section"] == "physical", "group"]))
    surfaces = list(dict.fromkeys(m.loc[m["section"] == "bounce", "group"]))
    phys = [(q, g, QUANTITIES[q]) for q in QUANTITIES for g in groups]
    bounce = [("bounce_speed_ratio", s, "ratio") for s in surfaces]
    sources = [f"- **{names['sim']}**: {sim!r}", f"- **{names['ref']}**: {ref!r}"]
    if real_points is not None:
        events = ", ".join(sorted(real_points["event"].astype(str).unique()))
        sources.append(f"- **{names['real']}**: {len(real_points)} points ({events}) served by "
                       "the same players, against anyone")
    serve_pct = {"first_serve_in", "ace", "double_fault", "first_serve_won",
                 "second_serve_won", "serve_points_won"}
    digits = {"n_points": 0, "n_rallies": 0, "n_points_counted": 0, "rally_mean": 2, "mean": 2}
    realism_pct = {"non_realistic_share", "undecided_share"}
    return "\n\n".join([
        f"# Realism report: {names['sim']} against {names['ref']}",
        "\n".join(sources),
        "## Realism\n\n" + _values_table(m, "realism", keys, names, realism_pct, digits),
        "## Physical quantities\n\nMedian [IQR] (n) per source; W: Wasserstein distance from "
        f"the {names['sim']} distribution (same unit).\n\n"
        + _distribution_table(m, "physical", keys, names, phys)
        + f"\n\n![speeds and toss heights]({FIGURES['speeds']})",
        "## Bounce speed ratio by surface\n\n"
        + _distribution_table(m, "bounce", [k for k in keys if k != "real"], names, bounce)
        + f"\n\n![bounce speed ratio]({FIGURES['bounce']})",
        "## Serving statistics\n\n" + _values_table(m, "serve", keys, names, serve_pct, digits),
        "## Rally length\n\n" + _values_table(m, "rally", keys, names, set(), digits)
        + f"\n\n![rally length]({FIGURES['rally_length']})",
        "## Definitions\n\n" + "\n".join([
            "- Simulated rallies count when realistic and decided; points when all their rallies "
            "count. Physical quantities use counted rallies, statistics counted points.",
            "- Speeds are measured from the ball track over one to two frame times after the "
            "contact, wherever it fell between frames (the same way for every tracking "
            "source); serves include faults.",
            "- Real serve speeds are the slams' radar speeds of serves that went in (no fault "
            "is recorded), so the real column of the serve speed rows is not quite like for "
            "like; the serving statistics' speeds come from each points table (generator: "
            "launch speed; simulator: track speed; real: radar).",
            "- Bounce speed ratio: ball speed over (f+1, f+2) over that over (f-2, f-1) around "
            "each bounce frame f found by the rally rules (sportsngen.tennis.rally).",
            "- Rally length: slam definition (0 double fault, 1 ace or unreturned serve).",
        ]),
    ]) + "\n"


def write_report(sim: RallyData, ref: RallyData, out_dir: str | Path,
                 real_points: pd.DataFrame | None = None,
                 labels: tuple[str, str] = ("simulated", "synthetic truth"),
                 sim_sample: Sample | None = None, ref_sample: Sample | None = None) -> Path:
    """Write ``report.md``, ``metrics.csv`` and ``figures/*.png`` comparing `sim` with `ref`
    (and with `real_points`, a real slam points table, where the statistic exists) into
    `out_dir`; returns the path of ``report.md``. `sim_sample` / `ref_sample`: `collect`ed
    samples to reuse. Raises ValueError when either data set has no rallies."""
    for name, data in (("simulated", sim), ("reference", ref)):
        if len(data.rallies) == 0:
            raise ValueError(f"the {name} data has no rallies")
    if len(labels) != 2:
        raise ValueError(f"labels must be two names (simulated, reference), got {labels!r}")
    out = Path(out_dir)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    s = sim_sample if sim_sample is not None else collect(sim)
    r = ref_sample if ref_sample is not None else collect(ref)
    metrics = compare(s, r, real_points)
    metrics.to_csv(out / "metrics.csv", index=False)

    names = {"sim": str(labels[0]), "ref": str(labels[1]), "real": "real"}
    keys = ["sim", "ref"] + (["real"] if real_points is not None else [])
    speeds = {"sim": s.shots, "ref": r.shots}
    if real_points is not None:
        players = set(s.shots["hitter"].astype(str)) | set(r.shots["hitter"].astype(str))
        real = real_serve_speeds(real_points[real_points["server"].astype(str).isin(players)])
        speeds["real"] = real[real["quantity"].isin(REAL_QUANTITIES)]
    _speed_figure(speeds, names, out / FIGURES["speeds"])
    _rally_figure(metrics, {k: names[k] for k in keys}, out / FIGURES["rally_length"])
    _bounce_figure({"sim": s.bounces, "ref": r.bounces}, names, out / FIGURES["bounce"])
    path = out / "report.md"
    path.write_text(_markdown(metrics, sim, ref, names, keys, real_points), encoding="utf-8")
    return path
