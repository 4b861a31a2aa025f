"""The points table: the project's common currency for serving and rally statistics.

One row a point, whether the point is real (a Grand Slam point-by-point file), synthetic (the
generator) or simulated (the model). Every statistic in `sportsngen.eval.stats` reads this table
and nothing else, so the three sources are compared with the same code.

Columns (pandas nullable dtypes so a field an event lacks is missing, never a fake zero):

- ``match_id`` (str), ``point`` (int, 1-based order within the match)
- ``server``, ``receiver``, ``winner`` (str player names)
- ``surface`` (str: hard, clay, grass), ``event`` (str, e.g. "2011-usopen"; "" when none)
- ``serve_number`` (Int64: 1 or 2 for the serve the point was played on; NA where unknown)
- ``first_serve_in`` (boolean; NA where the source has no serve flags)
- ``ace``, ``double_fault`` (boolean; NA where unknown)
- ``serve_kmh`` (float: speed of the serve that started the rally; NaN where not recorded)
- ``rally`` (Int64, slam definition: 0 on a double fault, 1 on an ace or unreturned serve)
- the score before the point, from the server's side: ``set_no`` (Int64, 1-based),
  ``server_games``, ``receiver_games`` (Int64), ``server_score``, ``receiver_score``
  (str: "0", "15", "30", "40", "AD", or the tie-break count as digits)
"""

from __future__ import annotations

import pandas as pd

from sportsngen.tennis.scoring import MatchState

POINTS_DTYPES: dict[str, str] = {
    "match_id": "string",
    "point": "int64",
    "server": "string",
    "receiver": "string",
    "winner": "string",
    "surface": "string",
    "event": "string",
    "serve_number": "Int64",
    "first_serve_in": "boolean",
    "ace": "boolean",
    "double_fault": "boolean",
    "serve_kmh": "float64",
    "rally": "Int64",
    "set_no": "Int64",
    "server_games": "Int64",
    "receiver_games": "Int64",
    "server_score": "string",
    "receiver_score": "string",
}
POINTS_COLUMNS: tuple[str, ...] = tuple(POINTS_DTYPES)


def empty_points() -> pd.DataFrame:
    """An empty points table with the right columns and dtypes."""
    return pd.DataFrame({c: pd.Series(dtype=d) for c, d in POINTS_DTYPES.items()})


def as_points_table(df: pd.DataFrame) -> pd.DataFrame:
    """Return `df` with exactly the points columns, in order, cast to their dtypes.

    Raises ValueError naming the missing columns.
    """
    missing = [c for c in POINTS_COLUMNS if c not in df.columns]
    if missing:
        raise ValueError(f"points table is missing columns {missing}")
    out = df.loc[:, list(POINTS_COLUMNS)].copy()
    for col, dtype in POINTS_DTYPES.items():
        out[col] = out[col].astype(dtype)
    return out.reset_index(drop=True)


def score_row(state: MatchState, server: int) -> dict:
    """The score columns of a rallies-table row, from the server's view."""
    receiver = 1 - server
    sets = state.sets_won
    return {"set_no": state.set_no, "server_sets": sets[server], "receiver_sets": sets[receiver],
            "server_games": state.games[server], "receiver_games": state.games[receiver],
            "server_points": state.points[server], "receiver_points": state.points[receiver],
            "in_tiebreak": state.in_tiebreak, "score": state.score_str()}
