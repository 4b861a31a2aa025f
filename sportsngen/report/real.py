"""Recorded slam matches: the score replayed point by point with its live win probability.

A match of the slam point-by-point files (`sportsngen.data.slam`, Jeff Sackmann / Tennis
Abstract, CC BY-NC-SA 4.0) is replayed through `MatchState` by `sportsngen.data.slam_replay`,
which re-synchronises to the recorded score wherever the recording disagrees with the rules;
rows after the end of the match are dropped. The win probability before each point is the
serve-level model of `sportsngen.report.live` (the players' own 2011 serve figures where the
bundled models know them: for a 2011 match these include the match itself).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from sportsngen.data.paths import SHARED_DATA_MISSING, slam_dir
from sportsngen.data.slam import (
    SLAM_SURFACES,
    _event_files,
    parse_match_id,
    points_from_raw,
    read_slam_raw,
)
from sportsngen.data.slam_replay import replay_raw
from sportsngen.report.document import match_document, write_report
from sportsngen.report.figures import ATTRIBUTION
from sportsngen.report.live import serve_odds, timeline
from sportsngen.tennis.scoring import MatchFormat, MatchState

SLAM_NAMES = {"ausopen": "Australian Open", "frenchopen": "French Open",
              "wimbledon": "Wimbledon", "usopen": "US Open"}


@dataclass
class RecordedMatch:
    """One recorded match, replayed: the points before the match's end and their states."""

    match_id: str
    players: tuple[str, str]
    fmt: MatchFormat
    gender: str
    surface: str
    points: pd.DataFrame          # points table (`sportsngen.data.points`) of the kept rows
    states: list[MatchState]      # the score each kept point was played from
    winners: np.ndarray           # 0 / 1: player 1 / player 2 won the point
    n_glitches: int               # kept rows whose recorded score the replay disagreed with
    n_after_end: int              # rows recorded after the replayed match was over

    @property
    def final(self) -> MatchState:
        return self.states[-1].point_won(int(self.winners[-1]))


def slam_folder(folder: str | Path | None) -> Path:
    """`folder`, or the shared slam data folder; ValueError when there is none."""
    found = slam_dir() if folder is None else Path(folder)
    if found is None or not found.is_dir():
        raise ValueError(SHARED_DATA_MISSING if folder is None else
                         f"slam data folder not found: {folder}")
    return found


def replay_event_matches(raw: pd.DataFrame) -> list[RecordedMatch]:
    """Every match of `read_slam_raw` rows, replayed (in file order)."""
    rep = replay_raw(raw, states=True)
    out = []
    for match_id, idx in rep.groupby("match_id", sort=False).indices.items():
        rows, r = raw.iloc[idx], rep.iloc[idx]
        keep = np.array([not s.is_over for s in r["state"]])
        year, slam, _, gender = parse_match_id(match_id)
        out.append(RecordedMatch(
            match_id=str(match_id), players=(str(rows["player1"].iat[0]),
                                             str(rows["player2"].iat[0])),
            fmt=MatchFormat.for_slam(slam, year, gender), gender=gender,
            surface=SLAM_SURFACES[slam],
            points=points_from_raw(rows[keep]).reset_index(drop=True),
            states=list(r["state"][keep]), winners=rows["winner"].to_numpy()[keep] - 1,
            n_glitches=int((r["glitch"][keep] != "").sum()), n_after_end=int((~keep).sum())))
    return out


def load_recorded_match(match_id: str, folder: str | Path | None = None) -> RecordedMatch:
    """The match `match_id` (e.g. "2011-usopen-1208") from the slam files in `folder`."""
    _, slam, event, _ = parse_match_id(match_id)
    raw = read_slam_raw(*_event_files(slam_folder(folder), event), repair=True)
    rows = raw[raw["match_id"] == match_id]
    if not len(rows):
        known = sorted(raw["match_id"].unique())
        raise ValueError(f"match {match_id!r} is not in the {event} files; its matches: "
                         f"{', '.join(known[:8])}{' ...' if len(known) > 8 else ''}")
    return replay_event_matches(rows)[0]


def score_line(m: RecordedMatch) -> str:
    final = m.final
    sets = " ".join(final.score_str().split()[:len(final.sets)]) or "-"
    if final.is_over:
        return f"{m.players[0]} v {m.players[1]}: {sets}, won by {m.players[final.winner]}"
    return (f"{m.players[0]} v {m.players[1]}: {final.score_str()}, unfinished in the recording "
            "(retirement, or the recording stops)")


def recorded_match_report(match_id: str, path: str | Path,
                          folder: str | Path | None = None) -> Path:
    """Write the report of a recorded match (no rallies) to `path`."""
    m = load_recorded_match(match_id, folder)
    odds = serve_odds(*m.players, gender=m.gender)
    year, slam, _, gender = parse_match_id(match_id)
    fmt = m.fmt
    final = {"tiebreak7": "final-set tie-break", "advantage": "advantage final set",
             "tiebreak10": "10-point final-set tie-break",
             "tiebreak7_at_12": "final-set tie-break at 12-12"}[fmt.final_set]
    notes = [f"Recorded match {match_id}: {len(m.points)} points replayed through the rules of "
             f"scoring; {m.n_glitches} recorded scores disagreed with the replay, which then "
             "re-synchronised to the recording"
             + (f"; {m.n_after_end} rows after the end of the match dropped" if m.n_after_end
                else "") + "."]
    if year == 2011 and any(odds.own_figures):
        notes.append("The players' serve figures come from the 2011 US Open and Wimbledon, "
                     "this match included: in-sample.")
    doc = match_document(
        players=m.players, title=f"{m.players[0]} v {m.players[1]}",
        subtitle=(f"{year} {SLAM_NAMES[slam]}, {gender}'s singles, {m.surface}, best of "
                  f"{fmt.best_of}, {final}"),
        score_line=score_line(m), points=m.points,
        tl=timeline(m.states, m.winners, odds), odds=odds, kind="recorded",
        surface=m.surface, notes=notes,
        attribution=f"Point-by-point data: {ATTRIBUTION} (tennis_slam_pointbypoint).")
    return write_report(doc, path)
