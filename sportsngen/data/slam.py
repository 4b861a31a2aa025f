"""Reader for Grand Slam point-by-point files (Jeff Sackmann / Tennis Abstract,
tennis_slam_pointbypoint, CC BY-NC-SA 4.0) into the points table of `sportsngen.data.points`.

One event is two files: ``<year>-<slam>-points.csv`` (one row a point) and
``<year>-<slam>-matches.csv`` (player names). What the point columns mean, checked against the
2011 US Open / Wimbledon and 2012 Australian / French Open files:

- ``PointNumber``: 1-based order of the point in the match. A leading placeholder row with
  ``PointNumber`` 0 (and ``PointServer``/``PointWinner`` 0) starts each 2011 match: dropped.
  Rows with every point field blank (no server, winner, set or score; 2012 French Open, where a
  tracker lost points) hold no point: dropped too; the replay
  (`sportsngen.data.slam_replay`) reports the gap they leave.
- ``SetNo``, ``GameNo``: the set and the game (1-based within the set) the point is played in.
- ``P1Score``/``P2Score``: the point score AFTER the point ("0", "15", "30", "40", "AD", or the
  tie-break count); "0"/"0" after a game-ending point.
- ``P1GamesWon``/``P2GamesWon``: games in the current set AFTER the point (the final games of
  the set, e.g. 4-6, on a set-ending row; 0-0 again from the next set's first point).
- ``GameWinner``/``SetWinner``: 1 or 2 on the point that ended a game / set, else 0.
- ``PointServer``/``PointWinner``: 1 or 2 (player1 / player2 of the matches file).
- 2011 flags ``P{n}FirstSrvIn``/``P{n}SecondSrvIn``/``P{n}DoubleFault``/``P{n}Ace`` are set
  for the server only; every service point has exactly one of FirstSrvIn, SecondSrvIn,
  DoubleFault. 2012 files leave FirstSrvIn/SecondSrvIn blank but do fill Ace and DoubleFault,
  so 2012 points keep ``ace``/``double_fault`` and have ``first_serve_in``/``serve_number`` NA.
- ``Speed_KMH``: speed of the serve that started the rally, 0 when not recorded (always on a
  double fault) -> NaN. ``Rally`` (2011): 0 on a double fault, 1 on an ace; blank in 2012.

The points table wants the score BEFORE the point, from the server's side. Games before =
games after minus the game just won (``GameWinner``); the point score before = the previous
row's score after (0-0 on the first point). Where a match's first row is not point 1, the score
before is worked back from the row's own score and winner where that is unambiguous, else NA.

Rows keep the file's order. Bad values raise ValueError naming the file, column and row (data
row 1 is the line after the header); `repair=True` drops such rows instead and lists them in
``df.attrs["dropped"]``.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from sportsngen.data.paths import slam_dir
from sportsngen.data.points import as_points_table

log = logging.getLogger(__name__)

SLAM_SURFACES: dict[str, str] = {
    "ausopen": "hard", "usopen": "hard", "wimbledon": "grass", "frenchopen": "clay",
}
REQUIRED_POINT_COLUMNS: tuple[str, ...] = (
    "match_id", "SetNo", "P1GamesWon", "P2GamesWon", "SetWinner", "GameNo", "GameWinner",
    "PointNumber", "PointWinner", "PointServer", "Speed_KMH", "P1Score", "P2Score",
)
OPTIONAL_POINT_COLUMNS: tuple[str, ...] = (
    "Rally", "P1FirstSrvIn", "P2FirstSrvIn", "P1Ace", "P2Ace", "P1DoubleFault", "P2DoubleFault",
)
REQUIRED_MATCH_COLUMNS: tuple[str, ...] = ("match_id", "player1", "player2")
MATCH_ID_RE = re.compile(r"^(\d{4})-([a-z]+)-(\d+)$")
_GAME_SCORES = ("0", "15", "30", "40", "AD")
_BACK_ONE = {"15": "0", "30": "15", "40": "30"}  # regular-game score before the winner's point


def parse_match_id(match_id: str) -> tuple[int, str, str, str]:
    """``"2011-usopen-1101"`` -> (2011, "usopen", "2011-usopen", "men").

    Match numbers 1xxx are men's singles, 2xxx women's singles. ValueError otherwise.
    """
    m = MATCH_ID_RE.match(str(match_id))
    if m is None or m.group(2) not in SLAM_SURFACES:
        raise ValueError(f"bad slam match_id {match_id!r}: want '<year>-<slam>-<number>' with "
                         f"slam in {sorted(SLAM_SURFACES)}")
    first_digit = m.group(3)[0]
    if len(m.group(3)) != 4 or first_digit not in "12":
        raise ValueError(f"match_id {match_id!r}: number must be 1xxx (men) or 2xxx (women)")
    gender = "men" if first_digit == "1" else "women"
    return int(m.group(1)), m.group(2), f"{m.group(1)}-{m.group(2)}", gender


def _valid_match_id(match_id: str) -> bool:
    try:
        parse_match_id(match_id)
    except ValueError:
        return False
    return True


def list_slam_events(folder: str | Path | None = None) -> list[str]:
    """Events with both files in `folder` (default `slam_dir()`), e.g. ["2011-usopen", ...]."""
    folder = slam_dir() if folder is None else Path(folder)
    if folder is None or not Path(folder).is_dir():
        raise ValueError(f"slam data folder not found: {folder}")
    events = [p.name[: -len("-points.csv")] for p in Path(folder).glob("*-points.csv")]
    return sorted(e for e in events if (Path(folder) / f"{e}-matches.csv").is_file())


class _BadRows:
    """Collects bad cells: raises on the first unless repairing, else remembers the rows."""

    def __init__(self, path: Path, repair: bool) -> None:
        self.path, self.repair = path, repair
        self.rows: dict[int, str] = {}

    def check(self, df: pd.DataFrame, bad: np.ndarray, col: str, why: str) -> None:
        idx = np.flatnonzero(bad)
        if len(idx) == 0:
            return
        for i in idx if self.repair else idx[:1]:
            row = int(df.index[i])
            msg = (f"column {col!r}, data row {row + 1} "
                   f"(match {df['match_id'].iloc[i]}, PointNumber {df['PointNumber'].iloc[i]}): "
                   f"value {df[col].iloc[i]!r} {why}")
            if not self.repair:
                raise ValueError(f"{self.path}: {msg}; pass repair=True to drop bad rows")
            self.rows.setdefault(row, f"{self.path.name}: {msg}")


def _ints(df: pd.DataFrame, col: str) -> np.ndarray:
    """Column as float (NaN where blank or not a number); integrality is checked by callers.
    Arrow's cast reads a column of numbers (blanks as missing) far faster than `pd.to_numeric`
    on these text columns (every event's raw table: 6.2 -> 3.1 s), which remains the reading
    wherever a value is not a number."""
    values = pa.array(df[col], type=pa.string())
    try:
        blank = pc.equal(values, "")
        return pc.cast(pc.if_else(blank, pa.scalar(None, pa.string()), values),
                       pa.float64()).to_numpy(zero_copy_only=False)
    except pa.ArrowInvalid:
        return pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=float)


def _read_matches(matches_csv: Path) -> pd.DataFrame:
    matches = pd.read_csv(matches_csv, dtype=str, keep_default_na=False)
    missing = [c for c in REQUIRED_MATCH_COLUMNS if c not in matches.columns]
    if missing:
        raise ValueError(f"{matches_csv}: missing columns {missing}")
    for col in REQUIRED_MATCH_COLUMNS:
        empty = (matches[col].str.strip() == "").to_numpy()
        if empty.any():
            raise ValueError(f"{matches_csv}: column {col!r}, data row "
                             f"{int(np.flatnonzero(empty)[0]) + 1}: empty value")
    dup = matches["match_id"].duplicated().to_numpy()
    if dup.any():
        raise ValueError(f"{matches_csv}: column 'match_id', data row "
                         f"{int(np.flatnonzero(dup)[0]) + 1}: duplicate match_id")
    return matches.set_index("match_id")


def read_slam_raw(
    points_csv: str | Path, matches_csv: str | Path, repair: bool = False
) -> pd.DataFrame:
    """The validated point rows of one event, players as 1/2 (the file's own orientation).

    Columns: match_id, event, slam, year, gender, player1, player2, point, set_no, game_no,
    p1_games, p2_games, p1_score, p2_score (the score BEFORE the point), p1_games_after,
    p2_games_after, p1_score_after, p2_score_after, set_winner, game_winner, server, winner
    (1/2), first_serve_in, ace, double_fault (boolean, NA where unknown), serve_kmh, rally.
    This is what `read_slam_event` and the score replay are built on.
    """
    points_csv, matches_csv = Path(points_csv), Path(matches_csv)
    wanted = set(REQUIRED_POINT_COLUMNS + OPTIONAL_POINT_COLUMNS)
    raw = pd.read_csv(points_csv, dtype=str, keep_default_na=False, usecols=wanted.__contains__)
    missing = [c for c in REQUIRED_POINT_COLUMNS if c not in raw.columns]
    if missing:
        raise ValueError(f"{points_csv}: missing columns {missing}")
    raw = raw.apply(lambda s: s.str.strip())
    matches = _read_matches(matches_csv)
    bad = _BadRows(points_csv, repair)

    # Placeholders hold no point: the PointNumber-0 row, and rows with every point field blank.
    pn = _ints(raw, "PointNumber")
    blank = np.ones(len(raw), dtype=bool)
    for col in ("SetNo", "PointServer", "PointWinner", "P1Score", "P2Score"):
        blank &= (raw[col] == "").to_numpy()
    keep = (pn != 0) & ~blank
    n_placeholder, n_blank = int((pn == 0).sum()), int(blank.sum())
    df = raw.loc[keep]

    ids = df["match_id"].to_numpy()
    valid_ids = {m for m in set(ids) if _valid_match_id(m)}
    bad.check(df, ~pd.Series(ids).isin(valid_ids).to_numpy(), "match_id",
              "is not '<year>-<slam>-<1xxx|2xxx>' with a known slam")
    bad.check(df, ~pd.Series(ids).isin(matches.index).to_numpy(), "match_id",
              f"is not in {matches_csv.name}")
    num = {c: _ints(df, c) for c in ("PointNumber", "SetNo", "GameNo", "P1GamesWon",
                                     "P2GamesWon", "SetWinner", "GameWinner", "PointServer",
                                     "PointWinner")}
    for col in ("PointNumber", "SetNo", "GameNo"):
        v = num[col]
        bad.check(df, ~((v >= 1) & (v == np.floor(v))), col, "is not an int >= 1")
    for col in ("P1GamesWon", "P2GamesWon"):
        v = num[col]
        bad.check(df, ~((v >= 0) & (v == np.floor(v))), col, "is not an int >= 0")
    for col in ("PointServer", "PointWinner"):
        bad.check(df, ~np.isin(num[col], (1, 2)), col, "not in {1, 2}")
    for col in ("SetWinner", "GameWinner"):
        bad.check(df, ~np.isin(num[col], (0, 1, 2)), col, "not in {0, 1, 2}")
    gw, g1, g2 = num["GameWinner"], num["P1GamesWon"], num["P2GamesWon"]
    bad.check(df, ((gw == 1) & ~(g1 >= 1)) | ((gw == 2) & ~(g2 >= 1)), "GameWinner",
              "names a game winner who has 0 games after the point")
    for col in ("P1Score", "P2Score"):
        s = df[col]
        ok = s.isin(_GAME_SCORES) | s.str.fullmatch(r"\d{1,2}")
        bad.check(df, ~ok.to_numpy(), col, "is not a point score (0/15/30/40/AD or digits)")
    kmh = _ints(df, "Speed_KMH")
    bad.check(df, ~((df["Speed_KMH"] == "").to_numpy() | (kmh >= 0)), "Speed_KMH",
              "is not a number >= 0")
    if "Rally" in df.columns:
        r = _ints(df, "Rally")
        bad.check(df, ~((df["Rally"] == "").to_numpy() | ((r >= 0) & (r == np.floor(r)))),
                  "Rally", "is not an int >= 0")
    for col in OPTIONAL_POINT_COLUMNS[1:]:
        if col in df.columns:
            bad.check(df, ~df[col].isin(("", "0", "1")).to_numpy(), col, "not in {0, 1, blank}")

    if bad.rows:
        drop = df.index.isin(list(bad.rows))
        for msg in bad.rows.values():
            log.warning("dropping bad row: %s", msg)
        df = df.loc[~drop]
        num = {c: v[~drop] for c, v in num.items()}
        kmh = kmh[~drop]
    if n_placeholder or n_blank:
        log.info("%s: dropped %d PointNumber-0 placeholder rows and %d blank rows",
                 points_csv.name, n_placeholder, n_blank)
    out = _assemble(df, num, kmh, matches)
    out.attrs["dropped"] = list(bad.rows.values())
    return out


def _server_flag(df: pd.DataFrame, server: np.ndarray, name: str) -> pd.Series:
    """The server's own ``P{n}<name>`` flag as boolean, NA where blank or absent."""
    cols = [f"P1{name}", f"P2{name}"]
    if not all(c in df.columns for c in cols):
        return pd.Series(pd.NA, index=df.index, dtype="boolean")
    val = np.where(server == 1, df[cols[0]].to_numpy(), df[cols[1]].to_numpy())
    return pd.Series(val, index=df.index).map({"1": True, "0": False}).astype("boolean")


def _assemble(df: pd.DataFrame, num: dict[str, np.ndarray], kmh: np.ndarray,
              matches: pd.DataFrame) -> pd.DataFrame:
    """Typed columns plus the score before each point (see the module docstring)."""
    ids = df["match_id"].astype(str)
    parsed = {m: parse_match_id(m) for m in ids.unique()}
    server = num["PointServer"].astype(np.int64)
    gw = num["GameWinner"].astype(np.int64)
    g1_after = num["P1GamesWon"].astype(np.int64)
    g2_after = num["P2GamesWon"].astype(np.int64)
    s1_after, s2_after = df["P1Score"].to_numpy(), df["P2Score"].to_numpy()
    point = num["PointNumber"].astype(np.int64)
    winner = num["PointWinner"].astype(np.int64)

    first = (ids != ids.shift()).to_numpy()
    s1 = np.where(first, "0", np.roll(s1_after, 1)).astype(object)
    s2 = np.where(first, "0", np.roll(s2_after, 1)).astype(object)
    for i in np.flatnonzero(first & (point != 1)):  # a recording that starts mid-match
        s1[i], s2[i] = _score_before(s1_after[i], s2_after[i], winner[i], gw[i] != 0)

    out = pd.DataFrame({
        "match_id": ids.to_numpy(),
        "event": [parsed[m][2] for m in ids],
        "slam": [parsed[m][1] for m in ids],
        "year": [parsed[m][0] for m in ids],
        "gender": [parsed[m][3] for m in ids],
        "player1": matches.loc[ids, "player1"].to_numpy(),
        "player2": matches.loc[ids, "player2"].to_numpy(),
        "point": point,
        "set_no": num["SetNo"].astype(np.int64),
        "game_no": num["GameNo"].astype(np.int64),
        "p1_games": g1_after - (gw == 1),
        "p2_games": g2_after - (gw == 2),
        "p1_score": pd.array(s1, dtype="string"),
        "p2_score": pd.array(s2, dtype="string"),
        "p1_games_after": g1_after,
        "p2_games_after": g2_after,
        "p1_score_after": s1_after,
        "p2_score_after": s2_after,
        "set_winner": num["SetWinner"].astype(np.int64),
        "game_winner": gw,
        "server": server,
        "winner": winner,
        "first_serve_in": _server_flag(df, server, "FirstSrvIn").to_numpy(),
        "ace": _server_flag(df, server, "Ace").to_numpy(),
        "double_fault": _server_flag(df, server, "DoubleFault").to_numpy(),
        "serve_kmh": np.where(kmh > 0, kmh, np.nan),
        "rally": (pd.to_numeric(df["Rally"], errors="coerce").astype("Int64").to_numpy()
                  if "Rally" in df.columns else pd.array([pd.NA] * len(df), dtype="Int64")),
    })
    return out


def _score_before(a1: str, a2: str, winner: int, game_ended: bool) -> tuple[object, object]:
    """Point score before a point from the score after it, where unambiguous (else NA)."""
    if game_ended:
        return pd.NA, pd.NA  # the game's last score (40-15? AD-40?) is not in the row
    after = [a1, a2]
    w = winner - 1
    if after[w].isdigit() and after[w] not in _BACK_ONE and after[w] != "0":
        after[w] = str(int(after[w]) - 1)  # a tie-break count
    elif after[w] in _BACK_ONE and not (after[w] == "40" and after[1 - w] == "40"):
        after[w] = _BACK_ONE[after[w]]  # 40-40 could come from 30-40 or 40-AD: ambiguous
    elif after[w] == "AD":
        after[w] = "40"
    else:
        return pd.NA, pd.NA
    return after[0], after[1]


def read_slam_event(
    points_csv: str | Path, matches_csv: str | Path, repair: bool = False
) -> pd.DataFrame:
    """One event's points as the points table (see `sportsngen.data.points`).

    Scores are before the point, from the server's side; names come from the matches file;
    surface from the slam (ausopen/usopen hard, wimbledon grass, frenchopen clay).
    """
    raw = read_slam_raw(points_csv, matches_csv, repair=repair)
    return points_from_raw(raw)


def points_from_raw(raw: pd.DataFrame) -> pd.DataFrame:
    """The points table (`sportsngen.data.points`) of rows `read_slam_raw` gave."""
    p1 = raw["server"].to_numpy() == 1
    name1, name2 = raw["player1"].to_numpy(), raw["player2"].to_numpy()
    fsi = raw["first_serve_in"].astype("boolean")
    serve_number = pd.Series(np.where(fsi.fillna(True), 1, 2), index=raw.index).astype("Int64")
    serve_number[fsi.isna()] = pd.NA
    table = pd.DataFrame({
        "match_id": raw["match_id"],
        "point": raw["point"],
        "server": np.where(p1, name1, name2),
        "receiver": np.where(p1, name2, name1),
        "winner": np.where(raw["winner"].to_numpy() == 1, name1, name2),
        "surface": raw["slam"].map(SLAM_SURFACES),
        "event": raw["event"],
        "serve_number": serve_number,
        "first_serve_in": fsi,
        "ace": raw["ace"],
        "double_fault": raw["double_fault"],
        "serve_kmh": raw["serve_kmh"],
        "rally": raw["rally"],
        "set_no": raw["set_no"],
        "server_games": np.where(p1, raw["p1_games"], raw["p2_games"]),
        "receiver_games": np.where(p1, raw["p2_games"], raw["p1_games"]),
        "server_score": raw["p1_score"].where(p1, raw["p2_score"]),
        "receiver_score": raw["p2_score"].where(p1, raw["p1_score"]),
    })
    out = as_points_table(table)
    out.attrs["dropped"] = list(raw.attrs.get("dropped", []))
    return out


def _event_files(folder: Path, event: str) -> tuple[Path, Path]:
    pts, mts = folder / f"{event}-points.csv", folder / f"{event}-matches.csv"
    if not pts.is_file() or not mts.is_file():
        raise ValueError(f"event {event!r}: {pts.name} or {mts.name} not found in {folder}")
    return pts, mts


def read_slam_events(
    folder: str | Path | None = None,
    events: list[str] | tuple[str, ...] | None = None,
    repair: bool = False,
) -> pd.DataFrame:
    """Several events' points tables concatenated (default: every event in `folder`).

    `folder` defaults to `slam_dir()`. ``df.attrs["dropped"]`` lists rows dropped by `repair`.
    """
    folder = slam_dir() if folder is None else Path(folder)
    if folder is None:
        raise ValueError("no slam data folder given and none found (see sportsngen.data.paths)")
    events = list_slam_events(folder) if events is None else list(events)
    if not events:
        raise ValueError(f"no slam events found in {folder}")
    tables = [read_slam_event(*_event_files(Path(folder), e), repair=repair) for e in events]
    dropped = [msg for t in tables for msg in t.attrs.get("dropped", [])]
    out = pd.concat(tables, ignore_index=True)
    out.attrs["dropped"] = dropped
    return out
