"""Serving, returning and rally statistics on a hand-built points table (hand-computed answers)."""

import math

import numpy as np
import pandas as pd
import pytest

from sportsngen.data.points import as_points_table
from sportsngen.eval.stats import (
    SERVE_STATS_COLUMNS,
    rally_distribution,
    rally_hazards,
    return_stats,
    serve_stats,
    serve_stats_table,
)

NA = pd.NA
# Player A serves 6 points with full flags; B serves 2 points the way a 2012 slam file does
# (no serve flags, no speed, no rally length).
#        server receiver winner  fsi    ace    df     kmh     rally
ROWS = [("A", "B", "A", True, True, False, 200.0, 1),
        ("A", "B", "B", True, False, False, 190.0, 5),
        ("A", "B", "B", False, False, True, np.nan, 0),  # double fault: no speed
        ("A", "B", "A", False, False, False, 150.0, 3),
        ("A", "B", "A", True, False, False, 180.0, 2),
        ("A", "B", "B", False, False, False, 160.0, 9),
        ("B", "A", "B", NA, NA, NA, np.nan, NA),
        ("B", "A", "A", NA, NA, NA, np.nan, NA)]


def _table(rows=ROWS) -> pd.DataFrame:
    cols = ["server", "receiver", "winner", "first_serve_in", "ace", "double_fault",
            "serve_kmh", "rally"]
    df = pd.DataFrame(rows, columns=cols)
    df["match_id"], df["point"] = "m1", np.arange(1, len(df) + 1)
    df["surface"], df["event"] = "hard", ""
    df["serve_number"] = df["first_serve_in"].map({True: 1, False: 2})
    for c in ("set_no", "server_games", "receiver_games"):
        df[c] = 1 if c == "set_no" else 0
    df["server_score"], df["receiver_score"] = "0", "0"
    return as_points_table(df)


def test_serve_stats_exact():
    st = serve_stats(_table())
    assert list(st.columns) == list(SERVE_STATS_COLUMNS)
    a = st.loc["A"]
    assert a["n_points"] == 6
    assert a["first_serve_in"] == pytest.approx(3 / 6)
    assert a["ace"] == pytest.approx(1 / 6)
    assert a["double_fault"] == pytest.approx(1 / 6)
    assert a["first_serve_won"] == pytest.approx(2 / 3)  # points 1, 5 of 1, 2, 5
    assert a["second_serve_won"] == pytest.approx(1 / 3)  # point 4 of 3 (DF), 4, 6
    assert a["serve_points_won"] == pytest.approx(3 / 6)
    assert a["first_serve_kmh_median"] == pytest.approx(190.0)
    assert a["first_serve_kmh_iqr"] == pytest.approx(195.0 - 185.0)
    assert a["second_serve_kmh_median"] == pytest.approx(155.0)  # the DF's NaN is excluded
    assert a["second_serve_kmh_iqr"] == pytest.approx(157.5 - 152.5)
    assert a["rally_mean"] == pytest.approx(20 / 6)


def test_serve_stats_nan_where_fields_missing():
    b = serve_stats(_table()).loc["B"]
    assert b["n_points"] == 2
    assert b["serve_points_won"] == pytest.approx(0.5)
    for col in SERVE_STATS_COLUMNS:
        if col not in ("n_points", "serve_points_won"):
            assert math.isnan(b[col]), col


def test_serve_stats_without_optional_columns():
    df = _table().drop(columns=["serve_kmh", "rally", "ace"])
    a = serve_stats(df).loc["A"]
    assert math.isnan(a["first_serve_kmh_median"]) and math.isnan(a["rally_mean"])
    assert math.isnan(a["ace"])
    assert a["first_serve_won"] == pytest.approx(2 / 3)


def test_serve_stats_missing_required_column():
    with pytest.raises(ValueError, match="winner"):
        serve_stats(_table().drop(columns=["winner"]))


def test_return_stats_exact():
    r = return_stats(_table())
    b = r.loc["B"]  # B returned A's six serves
    assert b["n_return_points"] == 6
    assert b["return_points_won"] == pytest.approx(0.5)
    assert b["return_first_won"] == pytest.approx(1 / 3)
    assert b["return_second_won"] == pytest.approx(2 / 3)
    a = r.loc["A"]
    assert a["return_points_won"] == pytest.approx(0.5) and math.isnan(a["return_first_won"])


def test_rally_distribution_bins_exact():
    rd = rally_distribution(_table())
    assert list(rd.columns) == ["0", "1", "2", "3-4", "5-8", "9+"]
    np.testing.assert_allclose(rd.loc["A"].to_numpy(), np.full(6, 1 / 6))
    assert rd.loc["B"].isna().all()  # no rally length known
    overall = rally_distribution(_table(), by=None)
    assert list(overall.index) == ["all"]
    np.testing.assert_allclose(overall.loc["all"].to_numpy(), np.full(6, 1 / 6))


def test_rally_distribution_custom_bins_and_errors():
    rd = rally_distribution(_table(), bins=((0, 1), (2, 4), (5, None)), by=None)
    assert list(rd.columns) == ["0-1", "2-4", "5+"]
    np.testing.assert_allclose(rd.loc["all"].to_numpy(), [2 / 6, 2 / 6, 2 / 6])
    with pytest.raises(ValueError, match="bad bin"):
        rally_distribution(_table(), bins=((3, 1),))
    with pytest.raises(ValueError, match="group by"):
        rally_distribution(_table(), by="nope")


def test_rally_hazards_exact():
    h = rally_hazards([1, 1, 2, 3, 3, 3, np.nan, 0], max_length=4)
    assert h["reached"].tolist() == [6, 4, 3, 0] and h["ended"].tolist() == [2, 1, 3, 0]
    np.testing.assert_allclose(h["hazard"].to_numpy()[:3], [2 / 6, 1 / 4, 1.0])
    assert np.isnan(h["hazard"].iat[3])
    with pytest.raises(ValueError, match="max_length"):
        rally_hazards([1], max_length=0)


def test_serve_stats_table_text():
    text = serve_stats_table(serve_stats(_table()))
    lines = text.splitlines()
    a_line = next(line for line in lines if line.startswith("A "))
    assert "50.0" in a_line and "16.7" in a_line and "66.7" in a_line and "190" in a_line
    b_line = next(line for line in lines if line.startswith("B "))
    # missing figures print as '-', not 'nan'
    assert b_line.split() == ["B", "2", "-", "-", "-", "-", "-", "50.0", "-", "-", "-"]
    assert "nan" not in text
