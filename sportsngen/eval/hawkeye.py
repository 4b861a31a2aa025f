"""Hawk-Eye ball-level statistics, from any strikes table, against the real figures.

The statistics and their definitions are those of ``../shared/data/hawkeye/README.md`` (real
values from Hawk-Eye keypoints of AO 2020 and RG 2019-2020 via CourtVision, in
``ball_targets_2019_2020.csv``); every one is computed here, once, from the strikes table of
`sportsngen.eval.hawkeye_strikes` (`strike_keypoints` for tracking, `keypoint_strikes` for real
keypoint files), in the aligned frame (hitter at x < 0 hitting toward +x):

- serve (strike 1, per server): radar speed of first / second serves in; contact height and
  ``|x| - 11.885`` of all attempts; net height and depth ``6.40 - x_bounce`` of serves in; first
  serves in by the third of the box width they land in (``|y|`` >= 2.743 wide, >= 1.372 body,
  else T);
- return (strike 2 after a serve in, per returner): ``|x| - 11.885`` (all, against first,
  against second serves); net height (median, 10 % and 90 % quantiles) of returns that cleared
  the net; depth ``11.885 - x_bounce`` of returns landing in the singles court;
- rally groundstrokes (strike >= 3, ``|x_hit|`` >= 9.0 m, below 2.0 m, after the incoming ball
  bounced): contact ``|x| - 11.885`` and height; net height quantiles of those that cleared the
  net; peak height of those that cleared the net (the real figures' counts say that Hawk-Eye
  gives a peak keypoint only to balls that crossed the net: in every group the peak's n is
  within 0.5 % of the net height's, while 7-10 % more strikes have a contact height; counted
  over every strike, the generator's balls into the net pulled its medians 0.07-0.09 m low);
  depth of those landing in and the share of those within 3.0 m of the baseline;
- rally length per service point (per server; slam definition: strikes in play in the point's
  last rally, serve included, 0 on a double fault; points cut short after a first-serve fault
  are left out), shares of 0, 1, 2, 3-4, 5-8 and 9+ and the mean.

``n`` is the number of serves / strikes / points a statistic was taken over (for shares, the
denominator). Quantiles: numpy's linear interpolation.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from sportsngen.data.paths import HAWKEYE_TARGETS_MISSING, hawkeye_targets_path
from sportsngen.eval.hawkeye_strikes import (
    STRIKE_COLUMNS,
    keypoint_strikes,
    profile_tours,
    strike_keypoints,
)
from sportsngen.eval.markdown import markdown_table
from sportsngen.tennis.court import BASELINE_X_M, SERVICE_LINE_X_M, serve_zone

__all__ = ["STATISTICS", "STRIKE_COLUMNS", "TOLERANCES", "compare", "comparison_markdown",
           "hawkeye_stats", "keypoint_strikes", "load_targets", "strike_keypoints"]

RALLY_MIN_BEHIND_NET_M = 9.0    # rally groundstrokes: struck at least this far from the net
RALLY_MAX_CONTACT_Z_M = 2.0     # ... and below this height (no overheads)
DEEP_WITHIN_M = 3.0             # a deep ball lands within this distance of the baseline
RALLY_LEN_BINS: tuple[tuple[str, int, int | None], ...] = (
    ("0", 0, 0), ("1", 1, 1), ("2", 2, 2), ("3-4", 3, 4), ("5-8", 5, 8), ("9+", 9, None),
)
TARGET_COLUMNS = ("player", "surface", "statistic", "value", "n")

# name -> (strike selection, value column, aggregate); the selections are defined in `_measures`
_SPECS: dict[str, tuple[str, str, str]] = {
    "serve1_kmh_median": ("serve1_in", "serve_kmh", "median"),
    "serve2_kmh_median": ("serve2_in", "serve_kmh", "median"),
    "serve_contact_z_median": ("serve", "hit_z_m", "median"),
    "serve_contact_behind_m_median": ("serve", "behind_m", "median"),
    "serve1_net_z_median": ("serve1_in", "net_z_m", "median"),
    "serve2_net_z_median": ("serve2_in", "net_z_m", "median"),
    "serve1_depth_m_median": ("serve1_in", "serve_depth_m", "median"),
    "serve2_depth_m_median": ("serve2_in", "serve_depth_m", "median"),
    "serve1_wide_share": ("serve1_in", "wide", "share"),
    "serve1_body_share": ("serve1_in", "body", "share"),
    "serve1_t_share": ("serve1_in", "t", "share"),
    "return_contact_behind_m_median": ("return", "behind_m", "median"),
    "return1_contact_behind_m_median": ("return1", "behind_m", "median"),
    "return2_contact_behind_m_median": ("return2", "behind_m", "median"),
    "return_net_z_median": ("return", "net_z_m", "median"),
    "return_net_z_p10": ("return", "net_z_m", "p10"),
    "return_net_z_p90": ("return", "net_z_m", "p90"),
    "return_depth_m_median": ("return_in", "depth_m", "median"),
    "rally_contact_behind_m_median": ("rally", "behind_m", "median"),
    "rally_contact_z_median": ("rally", "hit_z_m", "median"),
    "rally_net_z_median": ("rally", "net_z_m", "median"),
    "rally_net_z_p10": ("rally", "net_z_m", "p10"),
    "rally_net_z_p90": ("rally", "net_z_m", "p90"),
    "rally_peak_z_median": ("rally_over", "peak_z_m", "median"),
    "rally_depth_m_median": ("rally_in", "depth_m", "median"),
    "rally_deep_share": ("rally_in", "deep", "share"),
}
_RALLY_LEN_STATS = tuple(f"rally_len_{name}_share" for name, _, _ in RALLY_LEN_BINS) + \
    ("rally_len_mean",)
STATISTICS: tuple[str, ...] = tuple(_SPECS) + _RALLY_LEN_STATS

# The README's tolerances for a generated player against these figures. rally_len_mean has
# none there: 0.5 shots is this module's choice (3-4 standard errors of a named player's mean
# over his ~650 real service points; rally lengths spread with a standard deviation near 3.5).
_KIND_TOLERANCE = {"kmh": 8.0, "z": 0.15, "z_quantile": 0.25, "depth": 0.75, "position": 1.0,
                   "share": 0.08, "mean": 0.5}


def statistic_kind(name: str) -> str:
    """What a statistic measures: kmh, z, z_quantile, depth, position, share or mean."""
    if name.endswith("_share"):
        return "share"
    if name == "rally_len_mean":
        return "mean"
    if "_kmh_" in name:
        return "kmh"
    if "_behind_m_" in name:
        return "position"
    if "_depth_m_" in name:
        return "depth"
    if name.endswith(("_p10", "_p90")):
        return "z_quantile"
    return "z"


TOLERANCES: dict[str, float] = {s: _KIND_TOLERANCE[statistic_kind(s)] for s in STATISTICS}
TOLERANCES["return_net_z_median"] = 0.20


def _measures(strikes: pd.DataFrame) -> pd.DataFrame:
    """Per strike: the selections (booleans) and values every statistic is a group aggregate
    of."""
    s = strikes
    missing = [c for c in STRIKE_COLUMNS if c not in s.columns]
    if missing:
        raise ValueError(f"strikes table is missing columns {missing}")
    strike = s["strike"].to_numpy()
    serve = strike == 1
    serve_in = serve & s["landed_in"].to_numpy(bool)
    first = s["serve_number"].to_numpy() == 1
    # Returns: strike 2 of a rally whose serve went in.
    rally_serve_in = pd.Series(serve_in, index=s.index).groupby(s["rally_id"]).transform("max")
    ret = (strike == 2) & rally_serve_in.to_numpy(bool)
    abs_x = np.abs(s["hit_x_m"].to_numpy(float))
    rally = (strike >= 3) & (abs_x >= RALLY_MIN_BEHIND_NET_M) & \
        (s["hit_z_m"].to_numpy(float) < RALLY_MAX_CONTACT_Z_M) & \
        s["incoming_bounced"].to_numpy(bool)
    landed = s["landed_in"].to_numpy(bool)
    bx, by = s["bounce_x_m"].to_numpy(float), s["bounce_y_m"].to_numpy(float)
    depth = BASELINE_X_M - bx
    zone = np.asarray(serve_zone(by))
    return pd.DataFrame({
        "serve": serve, "serve1_in": serve_in & first, "serve2_in": serve_in & ~first,
        "return": ret, "return1": ret & first, "return2": ret & ~first,
        "return_in": ret & landed, "rally": rally, "rally_in": rally & landed,
        "rally_over": rally & np.isfinite(s["net_z_m"].to_numpy(float)),
        "serve_kmh": s["serve_kmh"].to_numpy(float), "hit_z_m": s["hit_z_m"].to_numpy(float),
        "behind_m": abs_x - BASELINE_X_M, "net_z_m": s["net_z_m"].to_numpy(float),
        "peak_z_m": s["peak_z_m"].to_numpy(float),
        "serve_depth_m": SERVICE_LINE_X_M - bx, "depth_m": depth,
        "wide": (zone == "wide").astype(float), "body": (zone == "body").astype(float),
        "t": (zone == "T").astype(float),
        "deep": (depth <= DEEP_WITHIN_M).astype(float),
    }, index=s.index)


def point_rally_lengths(strikes: pd.DataFrame) -> pd.DataFrame:
    """Per service point: server, surface, rally length (strikes in play in the point's last
    rally); points whose last rally is a first serve that did not go in are left out (the
    point's second serve is missing)."""
    s = strikes
    per_rally = s.groupby("rally_id", sort=False).agg(
        match_id=("match_id", "first"), point=("point", "first"),
        serve_number=("serve_number", "first"), server=("server", "first"),
        surface=("surface", "first"), length=("in_play", "sum"),
        serve_in=("landed_in", "first"))
    last = per_rally.sort_values(["match_id", "point", "serve_number"], kind="stable") \
        .groupby(["match_id", "point"], sort=False).tail(1)
    complete = (last["serve_number"] == 2) | last["serve_in"]
    return last.loc[complete, ["match_id", "point", "server", "surface", "length"]] \
        .reset_index(drop=True)


def _aggregate(values: pd.Series, how: str) -> tuple[float, int]:
    v = values.dropna()
    if len(v) == 0:
        return float("nan"), 0
    if how == "median":
        return float(v.median()), len(v)
    if how in ("p10", "p90"):
        return float(np.quantile(v.to_numpy(), 0.1 if how == "p10" else 0.9)), len(v)
    return float(v.mean()), len(v)  # share / mean


def _group_stats(m: pd.DataFrame, lengths: pd.Series) -> list[tuple[str, float, int]]:
    out = []
    for name, (sel, col, how) in _SPECS.items():
        out.append((name, *_aggregate(m.loc[m[sel], col], how)))
    for (_, lo, hi), stat in zip(RALLY_LEN_BINS, _RALLY_LEN_STATS):
        inside = (lengths >= lo) & ((lengths <= hi) if hi is not None else True)
        out.append((stat, *_aggregate(inside.astype(float), "share")))
    out.append(("rally_len_mean", *_aggregate(lengths.astype(float), "mean")))
    return out


def hawkeye_stats(strikes: pd.DataFrame, tours: Mapping[str, str] | None = None,
                  pooled: bool = True) -> pd.DataFrame:
    """Every statistic of `STATISTICS`, per (player, surface) and, with `pooled`, per (tour,
    surface) over the players of each tour: a long table with the real CSV's columns
    ``player, surface, statistic, value, n`` (value NaN and n 0 where nothing qualified).

    `tours`: player -> "ATP"/"WTA"; default the strikes' ``tour`` column, then the named
    profiles (men ATP, women WTA). Players with no tour appear only in their own rows.
    """
    m = _measures(strikes)
    players = strikes["player"].astype(str)
    if tours is None:
        known = strikes.dropna(subset=["tour"]).drop_duplicates("player")
        tours = {**profile_tours(players.unique()),
                 **dict(zip(known["player"].astype(str), known["tour"].astype(str)))}
    lengths = point_rally_lengths(strikes)
    rows: list[tuple[str, str, str, float, int]] = []
    groups = [(p, p) for p in sorted(players.unique())]
    if pooled:
        groups += [(t, None) for t in sorted(set(tours.values()))]
    for label, player in groups:
        if player is not None:
            member_s, member_p = players == player, lengths["server"].astype(str) == player
        else:
            in_tour = [p for p, t in tours.items() if t == label]
            member_s, member_p = players.isin(in_tour), lengths["server"].astype(str).isin(in_tour)
        for surface in sorted(strikes.loc[member_s, "surface"].astype(str).unique()):
            on = member_s & (strikes["surface"].astype(str) == surface)
            on_p = member_p & (lengths["surface"].astype(str) == surface)
            for stat, value, n in _group_stats(m[on.to_numpy()],
                                               lengths.loc[on_p, "length"]):
                rows.append((label, surface, stat, value, n))
    out = pd.DataFrame(rows, columns=list(TARGET_COLUMNS))
    return out.astype({"player": "string", "surface": "string", "statistic": "string",
                       "value": "float64", "n": "int64"})


def load_targets(path: str | Path | None = None) -> pd.DataFrame:
    """The real figures (``ball_targets_2019_2020.csv``; default: the shared data folder), as
    a long table ``player, surface, statistic, value, n``. FileNotFoundError when absent;
    ValueError naming the file and column when the layout or a statistic is unknown."""
    if path is None:
        path = hawkeye_targets_path()
        if path is None:
            raise FileNotFoundError(HAWKEYE_TARGETS_MISSING)
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no Hawk-Eye targets file at {path}")
    df = pd.read_csv(path)
    missing = [c for c in TARGET_COLUMNS if c not in df.columns]
    if missing:
        raise ValueError(f"{path}: missing columns {missing}")
    unknown = sorted(set(df["statistic"]) - set(STATISTICS))
    if unknown:
        raise ValueError(f"{path}: column 'statistic' has unknown statistics {unknown[:5]}")
    return df.loc[:, list(TARGET_COLUMNS)].astype(
        {"player": "string", "surface": "string", "statistic": "string", "value": "float64",
         "n": "int64"})


def compare(generated: pd.DataFrame, targets: pd.DataFrame,
            groups: Iterable[tuple[str, str]]) -> pd.DataFrame:
    """Generated against real statistics for each (player or tour, surface) of `groups`, in
    `STATISTICS` order: ``generated, real, difference`` (generated - real), ``tolerance``,
    ``within`` (|difference| <= tolerance; NA where a side has no value), ``n_generated``,
    ``n_real``."""
    groups = [(str(p), str(s)) for p, s in groups]
    frame = pd.DataFrame([(p, s, st) for p, s in groups for st in STATISTICS],
                         columns=["player", "surface", "statistic"])
    key = ["player", "surface", "statistic"]

    def side(df: pd.DataFrame, name: str) -> pd.DataFrame:
        d = df.astype({"player": str, "surface": str, "statistic": str})
        return d.rename(columns={"value": name, "n": f"n_{name}"}).loc[:, key + [name,
                                                                                 f"n_{name}"]]

    out = frame.merge(side(generated, "generated"), on=key, how="left") \
        .merge(side(targets, "real"), on=key, how="left")
    out["difference"] = out["generated"] - out["real"]
    out["tolerance"] = out["statistic"].map(TOLERANCES)
    within = (out["difference"].abs() <= out["tolerance"]).astype("boolean")
    out["within"] = within.where(out["difference"].notna(), pd.NA)
    for c in ("n_generated", "n_real"):
        out[c] = out[c].fillna(0).astype("int64")
    return out.loc[:, key + ["generated", "real", "difference", "tolerance", "within",
                             "n_generated", "n_real"]]


def _fmt(value: float, kind: str) -> str:
    if not np.isfinite(value):
        return "-"
    if kind == "share":
        return f"{100 * value:.0f}"
    if kind == "kmh":
        return f"{value:.0f}"
    if kind == "mean":
        return f"{value:.1f}"
    return f"{value:.2f}"


def _short(player: str) -> str:
    return player if player in ("ATP", "WTA") else player.split()[-1]


def comparison_markdown(cmp: pd.DataFrame, title: str | None = None,
                        before: pd.DataFrame | None = None) -> str:
    """A markdown table of `compare`'s output: one row a statistic, one column a (player,
    surface) group, cells "generated / real", in bold when outside the tolerance; shares in
    percent, speeds in km/h, heights and distances in metres. With `before` (an earlier
    `compare` of the same groups, e.g. another generator version) cells read "generated / real
    (before)", the earlier figure in italics when it was outside. A last row counts the
    statistics within tolerance per group (before -> now)."""
    groups = list(dict.fromkeys(zip(cmp["player"], cmp["surface"])))
    by = cmp.set_index(["player", "surface", "statistic"])
    old = before.set_index(["player", "surface", "statistic"]) if before is not None else None
    heads = group_labels(groups)
    lines = [f"### {title}", ""] if title else []
    rows = []
    for stat in dict.fromkeys(cmp["statistic"]):
        kind = statistic_kind(stat)
        tol = TOLERANCES[stat]
        cells = []
        for p, s in groups:
            row = by.loc[(p, s, stat)]
            cell = f"{_fmt(row['generated'], kind)} / {_fmt(row['real'], kind)}"
            outside = row["within"] is not pd.NA and not row["within"]
            cell = f"**{cell}**" if outside else cell
            if old is not None and (p, s, stat) in old.index:
                prev = old.loc[(p, s, stat)]
                text = _fmt(prev["generated"], kind)
                was_out = prev["within"] is not pd.NA and not prev["within"]
                cell += f" ({'*' + text + '*' if was_out else text})"
            cells.append(cell)
        tol_s = f"{100 * tol:.0f} pp" if kind == "share" else (
            f"{tol:.0f}" if kind == "kmh" else f"{tol:.2f}")
        rows.append([stat, tol_s, *cells])
    lines += markdown_table(["statistic", "tol.", *heads], rows)
    def within(c: pd.DataFrame, p: str, s: str) -> str:
        w = c.loc[(c["player"] == p) & (c["surface"] == s), "within"]
        return f"{int((w == True).sum())}/{int(w.notna().sum())}"  # noqa: E712

    counts = [(f"{within(before, p, s)} -> " if before is not None else "") + within(cmp, p, s)
              for p, s in groups]
    lines.append("| within tolerance | | " + " | ".join(counts) + " |")
    return "\n".join(lines) + "\n"


def group_labels(groups: Sequence[tuple[str, str]]) -> list[str]:
    """Short column labels ("Federer hard") of (player, surface) groups."""
    return [f"{_short(p)} {s}" for p, s in groups]
