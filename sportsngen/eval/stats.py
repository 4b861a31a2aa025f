"""Serving, returning and rally-length statistics from a points table.

Every function here reads the points table of `sportsngen.data.points` (real slam points,
synthetic points or simulated points alike), so the three are compared with the same code.
Fractions are in [0, 1]; speeds in km/h (the unit the slams publish). A field the source lacks
(2012 slam files have no first/second serve flags, a simulated table may have no speeds) comes
out as NaN rather than raising or pretending to be zero.

Definitions (per server, over that server's service points):

- ``first_serve_in``: share of points whose first serve went in.
- ``ace``, ``double_fault``: share of service points.
- ``first_serve_won``: share of first-serve-in points won by the server.
- ``second_serve_won``: share of points played on a second serve (double faults included: the
  point was played on a second serve and lost) won by the server.
- ``serve_points_won``: share of all service points won.
- serve speeds: ``serve_kmh`` of first-serve-in points is a first-serve speed, of the other
  points a second-serve speed (double faults have no recorded speed: NaN, excluded).
- ``rally_mean``: mean ``rally`` (slam definition: 0 on a double fault, 1 on an ace).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

SERVE_STATS_COLUMNS: tuple[str, ...] = (
    "n_points", "first_serve_in", "ace", "double_fault", "first_serve_won", "second_serve_won",
    "serve_points_won", "first_serve_kmh_median", "second_serve_kmh_median",
    "first_serve_kmh_iqr", "second_serve_kmh_iqr", "rally_mean",
)
RETURN_STATS_COLUMNS: tuple[str, ...] = (
    "n_return_points", "return_points_won", "return_first_won", "return_second_won",
)
DEFAULT_RALLY_BINS: tuple[tuple[int, int | None], ...] = (
    (0, 0), (1, 1), (2, 2), (3, 4), (5, 8), (9, None),
)


def _float_col(points: pd.DataFrame, col: str) -> pd.Series:
    """Column `col` as float64 with NaN for missing; all-NaN when the table lacks the column."""
    if col not in points.columns:
        return pd.Series(np.nan, index=points.index, dtype="float64")
    return pd.to_numeric(points[col], errors="raise").astype("Float64").astype("float64")


def _require(points: pd.DataFrame, cols: tuple[str, ...], who: str) -> None:
    missing = [c for c in cols if c not in points.columns]
    if missing:
        raise ValueError(f"{who}: points table is missing columns {missing}")


# serve_stats' columns that are a server's mean (or median) of one `per_point_frame` column.
PER_POINT_MEANS = {"first_serve_in": "fsi", "ace": "ace", "double_fault": "df",
                   "first_serve_won": "won_first", "second_serve_won": "won_second",
                   "serve_points_won": "won", "rally_mean": "rally"}
PER_POINT_MEDIANS = {"first_serve_kmh_median": "kmh_first",
                     "second_serve_kmh_median": "kmh_second"}


def per_point_frame(points: pd.DataFrame) -> pd.DataFrame:
    """Per-point numeric columns (NaN where unknown) from which every statistic is a group mean.

    Conditional quantities (won on first serve, first-serve speed, ...) are NaN outside their
    condition, so a plain NaN-skipping mean or median over a group is the conditional statistic.
    """
    fsi = _float_col(points, "first_serve_in")
    won = (points["winner"].astype("string") == points["server"].astype("string")).astype(float)
    won[points["winner"].isna()] = np.nan
    kmh = _float_col(points, "serve_kmh")
    first, second = fsi == 1.0, fsi == 0.0  # both False where fsi is NaN
    return pd.DataFrame({
        "fsi": fsi,
        "ace": _float_col(points, "ace"),
        "df": _float_col(points, "double_fault"),
        "won": won,
        "won_first": won.where(first),
        "won_second": won.where(second),
        "kmh_first": kmh.where(first),
        "kmh_second": kmh.where(second),
        "rally": _float_col(points, "rally"),
    }, index=points.index)


def serve_stats(points: pd.DataFrame) -> pd.DataFrame:
    """Serving statistics, one row per server (index: server name), columns SERVE_STATS_COLUMNS.

    Needs columns ``server`` and ``winner``; ``first_serve_in``, ``ace``, ``double_fault``,
    ``serve_kmh`` and ``rally`` are optional (absent or all-missing -> NaN in the result).
    """
    _require(points, ("server", "winner"), "serve_stats")
    per = per_point_frame(points)
    per["server"] = points["server"].astype("string")
    g = per.groupby("server", sort=True)
    out = pd.DataFrame({
        "n_points": g.size().astype("int64"),
        **{c: g[f].mean() for c, f in PER_POINT_MEANS.items()},
        **{c: g[f].median() for c, f in PER_POINT_MEDIANS.items()},
        "first_serve_kmh_iqr": g["kmh_first"].quantile(0.75) - g["kmh_first"].quantile(0.25),
        "second_serve_kmh_iqr": g["kmh_second"].quantile(0.75) - g["kmh_second"].quantile(0.25),
    })
    out.index.name = "server"
    return out.loc[:, list(SERVE_STATS_COLUMNS)]


def return_stats(points: pd.DataFrame) -> pd.DataFrame:
    """Returning statistics, one row per receiver (index: receiver name).

    Columns: ``n_return_points``; ``return_points_won`` (share of return points won);
    ``return_first_won`` / ``return_second_won`` (share won when the server's first serve went
    in / when the point was played on a second serve, double faults included). NaN where the
    source has no serve flags.
    """
    _require(points, ("server", "receiver", "winner"), "return_stats")
    per = per_point_frame(points)
    per["receiver"] = points["receiver"].astype("string")
    g = per.groupby("receiver", sort=True)
    out = pd.DataFrame({
        "n_return_points": g.size().astype("int64"),
        "return_points_won": 1.0 - g["won"].mean(),
        "return_first_won": 1.0 - g["won_first"].mean(),
        "return_second_won": 1.0 - g["won_second"].mean(),
    })
    out.index.name = "receiver"
    return out.loc[:, list(RETURN_STATS_COLUMNS)]


def _bin_label(lo: int, hi: int | None) -> str:
    if hi is None:
        return f"{lo}+"
    return str(lo) if lo == hi else f"{lo}-{hi}"


def _check_bins(bins: tuple[tuple[int, int | None], ...]) -> None:
    if len(bins) == 0:
        raise ValueError("rally_distribution: bins is empty")
    for b in bins:
        if len(b) != 2 or not isinstance(b[0], (int, np.integer)) or b[0] < 0:
            raise ValueError(f"rally_distribution: bad bin {b!r}: want (lo, hi) with int lo >= 0")
        if b[1] is not None and (not isinstance(b[1], (int, np.integer)) or b[1] < b[0]):
            raise ValueError(f"rally_distribution: bad bin {b!r}: want hi None or int >= lo")


def rally_distribution(
    points: pd.DataFrame,
    bins: tuple[tuple[int, int | None], ...] = DEFAULT_RALLY_BINS,
    by: str | None = "server",
) -> pd.DataFrame:
    """Share of points whose ``rally`` falls in each bin, per value of column `by`.

    Bins are inclusive ``(lo, hi)`` pairs, ``hi=None`` meaning open-ended; columns are labelled
    "0", "1", "2", "3-4", "5-8", "9+" for the default bins. Shares are over points with a known
    rally length (a row of NaN where none is known). With ``by=None`` one row, index "all".
    """
    _check_bins(bins)
    if "rally" not in points.columns:
        raise ValueError("rally_distribution: points table is missing column 'rally'")
    if by is not None and by not in points.columns:
        raise ValueError(f"rally_distribution: points table has no column {by!r} to group by")
    rally = _float_col(points, "rally")
    known = rally.notna().astype(float)
    cols = {}
    for lo, hi in bins:  # a loop over the few bins, not over points
        inside = rally >= lo
        if hi is not None:
            inside &= rally <= hi
        cols[_bin_label(lo, hi)] = inside.astype(float)
    frame = pd.DataFrame(cols, index=points.index)
    keys = (pd.Series("all", index=points.index) if by is None
            else points[by].astype("string"))
    counts = frame.groupby(keys, sort=True).sum()
    n_known = known.groupby(keys, sort=True).sum()
    out = counts.div(n_known.where(n_known > 0), axis=0)
    out.index.name = by if by is not None else "group"
    return out


def rally_hazards(rally, max_length: int = 10) -> pd.DataFrame:
    """Per rally length L (1 .. `max_length`): how many points reached L shots (``reached``),
    how many ended there (``ended``) and the share that did (``hazard``; NaN where none
    reached it). `rally` is the points' rally lengths (NaN unknown, left out).

    With the 2011 convention (1 an ace or unreturned serve, 2 a return winner or the server's
    error on the third ball, ...) odd lengths end with the server winning, even ones with the
    receiver: the hazard at each length tells who the rally favours shot by shot, which the
    binned shares of `rally_distribution` average away."""
    r = pd.to_numeric(pd.Series(rally), errors="coerce").dropna().to_numpy(dtype=float)
    if max_length < 1:
        raise ValueError(f"rally_hazards: max_length must be >= 1, got {max_length}")
    lengths = np.arange(1, max_length + 1)
    reached = (r[None, :] >= lengths[:, None]).sum(axis=1)
    ended = (r[None, :] == lengths[:, None]).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        hazard = np.where(reached > 0, ended / np.maximum(reached, 1), np.nan)
    return pd.DataFrame({"reached": reached, "ended": ended, "hazard": hazard},
                        index=pd.Index(lengths, name="rally"))


def serve_stats_table(stats: pd.DataFrame) -> str:
    """A readable fixed-width table of `serve_stats` output: percentages and km/h."""
    pct = [("first_serve_in", "1st in"), ("ace", "ace"), ("double_fault", "DF"),
           ("first_serve_won", "1st won"), ("second_serve_won", "2nd won"),
           ("serve_points_won", "srv won")]
    kmh = [("first_serve_kmh_median", "1st km/h"), ("second_serve_kmh_median", "2nd km/h")]
    names = [str(i) for i in stats.index]
    width = max([len("server")] + [len(n) for n in names])
    head = f"{'server':<{width}} {'points':>6} " + " ".join(f"{h:>8}" for _, h in pct + kmh)
    head += f" {'rally':>6}"
    lines = [head, "-" * len(head)]

    def fmt(v: float, scale: float, digits: int) -> str:
        return f"{'-':>8}" if pd.isna(v) else f"{v * scale:>8.{digits}f}"

    for name, (_, row) in zip(names, stats.iterrows()):
        cells = [fmt(row[c], 100.0, 1) for c, _ in pct] + [fmt(row[c], 1.0, 0) for c, _ in kmh]
        rally = "-" if pd.isna(row["rally_mean"]) else f"{row['rally_mean']:.2f}"
        lines.append(f"{name:<{width}} {int(row['n_points']):>6} " + " ".join(cells)
                     + f" {rally:>6}")
    lines.append("(% of service points; 1st/2nd won: % of those points won; km/h: median)")
    return "\n".join(lines)
