"""Score replay of the Grand Slam point-by-point files against the rules of tennis scoring.

Every match of an event (read by `sportsngen.data.slam.read_slam_raw`) is replayed through
`MatchState` from its first server using only the recorded point winners, and the recorded
score before each point (set, games, point score, server) is compared with the replayed one.
A disagreement is a data glitch: it is described, then the replay re-synchronises from the
recorded score and carries on, so one glitch costs one point of agreement, not a match.

`replay_slam_points` / `replay_slam_events` give one row a point (`REPLAY_COLUMNS`);
`glitch_kind` classifies the glitch texts and `replay_summary` aggregates per event or match.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from sportsngen.data.paths import slam_dir
from sportsngen.data.slam import _event_files, list_slam_events, parse_match_id, read_slam_raw
from sportsngen.tennis.scoring import MatchFormat, MatchState

REPLAY_COLUMNS: tuple[str, ...] = (
    "event", "match_id", "point", "rec_set_no", "rec_games_p1", "rec_games_p2", "rec_score_p1",
    "rec_score_p2", "rec_server", "rep_set_no", "rep_games_p1", "rep_games_p2", "rep_score_p1",
    "rep_score_p2", "rep_server", "agrees", "glitch", "match_over",
)
_MAX_GAP_POINTS = 3  # the longest run of missing (or repeated) points a glitch is matched to
_GAME_COUNTS = {"0": 0, "15": 1, "30": 2, "40": 3}

View = tuple  # (set_no, games_p1, games_p2, score_p1, score_p2, server 1/2)


def _view(state) -> View:
    """The replayed score in the file's terms (players 1/2, "AD"/"40", tie-break digits)."""
    a, b = state.point_score_str().split("-")
    return (state.set_no, state.games[0], state.games[1], a, b, state.server + 1)


def _view_str(v: View) -> str:
    v = tuple("?" if x is None else x for x in v)
    return f"set {v[0]} {v[1]}-{v[2]} {v[3]}-{v[4]} P{v[5]} serving"


def _raw_points(s1: str, s2: str, in_tiebreak: bool) -> tuple[int, int]:
    """Recorded point strings -> raw point counts (AD-40 -> (4, 3)); ValueError if invalid."""
    if in_tiebreak:
        if not (s1.isdigit() and s2.isdigit()):
            raise ValueError(f"tie-break score {s1}-{s2} is not two counts")
        return int(s1), int(s2)
    if s1 == "AD" and s2 == "40":
        return 4, 3
    if s1 == "40" and s2 == "AD":
        return 3, 4
    if s1 not in _GAME_COUNTS or s2 not in _GAME_COUNTS:
        raise ValueError(f"game score {s1}-{s2} is not a game score")
    return _GAME_COUNTS[s1], _GAME_COUNTS[s2]


def _set_candidates(state, rec_sets: dict[int, tuple[int, int]], set_no: int) -> list[tuple]:
    """Completed-set scores to try when re-synchronising at set `set_no`, best guess first:
    the recorded set scores, the replay's, then placeholders that keep the sets balanced (a
    set the data never shows the end of, e.g. a recording that starts in set 2)."""
    def filled(use_rec: bool, use_rep: bool) -> tuple:
        sets: list[tuple[int, int]] = []
        for k in range(1, set_no):
            if use_rec and k in rec_sets:
                sets.append(rec_sets[k])
            elif use_rep and k <= len(state.sets):
                sets.append(state.sets[k - 1])
            else:
                won1 = sum(1 for a, b in sets if b > a)
                sets.append((6, 0) if won1 >= len(sets) - won1 else (0, 6))
        return tuple(sets)
    out = [filled(True, True), filled(False, True), filled(False, False)]
    return list(dict.fromkeys(out))


def _resync(fmt, state, rec: View, rec_sets: dict[int, tuple[int, int]]):
    """A MatchState at the recorded score, or the ValueError explaining why there is none."""
    set_no, g1, g2, s1, s2, server = rec
    if s1 is None or s2 is None:
        return ValueError("recorded point score unknown")
    err: ValueError = ValueError("no candidate")
    for sets in _set_candidates(state, rec_sets, set_no):
        try:
            probe = MatchState.from_score(fmt, sets, (g1, g2), (0, 0), server - 1)
            pts = _raw_points(s1, s2, probe.in_tiebreak)
            return MatchState.from_score(fmt, sets, (g1, g2), pts, server - 1)
        except ValueError as e:
            err = e
    return err


def _reachable(start, target: View, max_points: int = _MAX_GAP_POINTS) -> int:
    """Fewest points (1..max_points) after which `start` can show `target`, else 0."""
    frontier = [start]
    for k in range(1, max_points + 1):
        nxt = []
        for s in frontier:
            if s.is_over:
                continue
            for by in (0, 1):
                t = s.point_won(by)
                if _view(t) == target:
                    return k
                nxt.append(t)
        frontier = nxt
    return 0


def _describe(state, rep: View, rec: View, synced, prev_point: int | None, point: int) -> str:
    """One-line description of why the recorded score `rec` is not the replayed `rep`.

    The text before the first ':' is the glitch's kind (see `glitch_kind`).
    """
    frm, to = _view_str(rep), _view_str(rec)
    if prev_point is None:
        return f"recording starts mid-match: first recorded point is #{point}, at {to}"
    note = " (PointNumber not increasing)" if point <= prev_point else ""
    if point > prev_point + 1:
        return (f"points missing: PointNumber jumps from {prev_point} to {point}, recorded score "
                f"from {frm} to {to}")
    if state.is_over:
        return f"point after match end: replay finished {state.score_str()}, recorded {to}{note}"
    k = _reachable(state, rec)
    if k:
        return (f"points missing: {k} point{'s' if k > 1 else ''}, recorded score jumps from "
                f"{frm} to {to}{note}")
    if isinstance(synced, MatchState):
        k = _reachable(synced, rep)
        if k:
            return (f"score goes back: {k} point{'s' if k > 1 else ''} (row repeated or out of "
                    f"order), replay {frm}, recorded {to}{note}")
    if rep[:5] == rec[:5]:
        return f"server mismatch: recorded P{rec[5]}, replay P{rep[5]} at {to}{note}"
    return f"score mismatch: replay {frm}, recorded {to}{note}"


def _replay_match(match_id: str, recs: list[View], winners: list[int], set_end: list[bool],
                  games_after: list[tuple[int, int]], points: list[int], out: dict) -> None:
    """Replay one match's rows (file order), appending to the lists in `out`."""
    year, slam, _, gender = parse_match_id(match_id)
    fmt = MatchFormat.for_slam(slam, year, gender)
    rec_sets: dict[int, tuple[int, int]] = {}  # recorded games of each completed set
    state = MatchState.new(fmt, first_server=int(recs[0][5]) - 1)
    for i, rec in enumerate(recs):
        rep = _view(state)
        glitch = ""
        if rec != rep:
            synced = _resync(fmt, state, rec, rec_sets)
            prev_point = points[i - 1] if i > 0 else None
            glitch = _describe(state, rep, rec, synced, prev_point, points[i])
            if isinstance(synced, MatchState):
                state = synced
            else:
                glitch += f" (cannot re-synchronise: {synced})"
        if set_end[i]:
            rec_sets[rec[0]] = games_after[i]
        out["state"].append(state)
        if not state.is_over:
            state = state.point_won(winners[i] - 1)
        out["rep"].append(rep)
        out["agrees"].append(rec == rep)
        out["glitch"].append(glitch)
        out["match_over"].append(state.is_over)


def _as_list(col: pd.Series) -> list:
    """Python values, None where missing (so tuples of them compare with plain ==)."""
    return [None if pd.isna(v) else v for v in col.astype(object).tolist()]


def replay_slam_points(points_csv: str | Path, matches_csv: str | Path) -> pd.DataFrame:
    """Replay every match of one event through `MatchState`; one row a point (REPLAY_COLUMNS).

    Uses only the recorded point winners and each match's first server (format from
    `MatchFormat.for_slam`: 1xxx men best of 5, 2xxx women best of 3). ``rec_*`` is the
    recorded score before the point (players 1/2 as in the file), ``rep_*`` the replayed one;
    ``agrees`` compares set, games, point score and server. Every disagreement has a non-empty
    ``glitch`` (missing points, repeated or out-of-order rows, server mismatch, points after
    the match end, a recording that starts mid-match); the replay then re-synchronises from
    the recorded score. ``match_over``: the replayed match is over after this point (a match
    that ends without it retired, or its recording stopped: not a glitch). Rows the reader
    had to drop (bad values) are listed in ``df.attrs["dropped"]``.
    """
    return replay_raw(read_slam_raw(points_csv, matches_csv, repair=True))


def replay_raw(raw: pd.DataFrame, states: bool = False) -> pd.DataFrame:
    """`replay_slam_points` of rows `read_slam_raw` gave (any subset of whole matches, in file
    order). With `states`, a column ``state``: the `MatchState` the point was played from
    (the replayed score, re-synchronised to the recorded one where they disagree)."""
    rec_cols = ("set_no", "p1_games", "p2_games", "p1_score", "p2_score", "server")
    recs = list(zip(*(_as_list(raw[c]) for c in rec_cols)))
    winners, points = raw["winner"].tolist(), raw["point"].tolist()
    set_end = (raw["set_winner"] != 0).tolist()
    games_after = list(zip(raw["p1_games_after"].tolist(), raw["p2_games_after"].tolist()))
    ids = raw["match_id"].to_numpy()
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]]) if len(ids) else np.array([0])
    bounds = np.r_[starts, len(ids)]
    out: dict[str, list] = {"rep": [], "agrees": [], "glitch": [], "match_over": [],
                            "state": []}
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b > a:
            _replay_match(str(ids[a]), recs[a:b], winners[a:b], set_end[a:b],
                          games_after[a:b], points[a:b], out)
    rep = pd.DataFrame(out["rep"], columns=[f"rep_{c}" for c in (
        "set_no", "games_p1", "games_p2", "score_p1", "score_p2", "server")], dtype=object)
    table = pd.DataFrame({
        "event": raw["event"], "match_id": raw["match_id"], "point": raw["point"],
        "rec_set_no": raw["set_no"], "rec_games_p1": raw["p1_games"],
        "rec_games_p2": raw["p2_games"], "rec_score_p1": raw["p1_score"],
        "rec_score_p2": raw["p2_score"], "rec_server": raw["server"],
        "agrees": np.array(out["agrees"], dtype=bool), "glitch": out["glitch"],
        "match_over": np.array(out["match_over"], dtype=bool),
    })
    for c in rep.columns:
        is_score = "score" in c
        table[c] = rep[c].astype(str if is_score else np.int64).to_numpy()
    table = table.loc[:, list(REPLAY_COLUMNS)]
    if states:
        table["state"] = pd.Series(out["state"], index=table.index, dtype=object)
    table.attrs["dropped"] = list(raw.attrs.get("dropped", []))
    return table


def replay_slam_events(
    folder: str | Path | None = None, events: list[str] | tuple[str, ...] | None = None
) -> pd.DataFrame:
    """`replay_slam_points` over several events (default: every event in `slam_dir()`)."""
    folder = slam_dir() if folder is None else Path(folder)
    if folder is None:
        raise ValueError("no slam data folder given and none found (see sportsngen.data.paths)")
    events = list_slam_events(folder) if events is None else list(events)
    parts = [replay_slam_points(*_event_files(Path(folder), e)) for e in events]
    out = pd.concat(parts, ignore_index=True)
    out.attrs["dropped"] = [m for p in parts for m in p.attrs.get("dropped", [])]
    return out


def glitch_kind(glitch: pd.Series) -> pd.Series:
    """The kind of each glitch: its text before the first ':' ("" where none)."""
    return glitch.astype(str).str.split(":", n=1).str[0]


def replay_summary(replay: pd.DataFrame, by: str = "event") -> pd.DataFrame:
    """Per `by` (event or match_id): matches, points, agreeing points, agreement %, glitches,
    replayed matches not finished at their last recorded point (retired, or the recording
    stopped), rows the reader dropped (by event only), and glitch counts by kind."""
    if by not in replay.columns:
        raise ValueError(f"replay_summary: no column {by!r} in the replay table")
    g = replay.groupby(by, sort=True)
    last = replay.groupby("match_id", sort=False).tail(1)
    out = pd.DataFrame({
        "matches": g["match_id"].nunique(),
        "points": g.size(),
        "agree": g["agrees"].sum(),
        "agreement_pct": 100.0 * g["agrees"].mean(),
        "glitches": g["glitch"].agg(lambda s: int((s != "").sum())),
        "unfinished": (~last["match_over"]).groupby(last[by]).sum(),
    })
    if by == "event":  # rows the reader dropped (bad values) never reach the replay
        dropped = pd.Series([m.split("-points.csv:", 1)[0]
                             for m in replay.attrs.get("dropped", [])], dtype=object)
        out["dropped_rows"] = dropped.value_counts().reindex(out.index).fillna(0)
    kinds = glitch_kind(replay["glitch"])
    has = kinds != ""
    if has.any():
        counts = pd.crosstab(replay.loc[has, by], kinds[has])
        out = out.join(counts).fillna(0)
    return out.astype({c: "int64" for c in out.columns if c != "agreement_pct"})
