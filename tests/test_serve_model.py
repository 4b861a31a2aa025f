"""The serve-level point model: estimation, Barnett-Clarke adjustment, serve-by-serve sim."""

import math

import numpy as np
import pandas as pd
import pytest

from sportsngen.baselines.serve_model import (
    ServeModel,
    matchup_point_probability,
    simulate_match_points,
)
from sportsngen.data.paths import SHARED_DATA_MISSING, slam_dir
from sportsngen.data.points import POINTS_COLUMNS, POINTS_DTYPES
from sportsngen.tennis.scoring import MatchFormat, MatchState

BO3 = MatchFormat()
BO5_ADV = MatchFormat(best_of=5, final_set="advantage")


MODEL_A = ServeModel(first_serve_in=0.62, ace_first=0.12, first_serve_won=0.76,
                     double_fault=0.08, ace_second=0.03, second_serve_won=0.52,
                     first_serve_kmh_median=190.0, first_serve_kmh_iqr=15.0,
                     second_serve_kmh_median=150.0, second_serve_kmh_iqr=14.0,
                     rally_won_pmf=(0.0, 0.4, 0.0, 0.35, 0.0, 0.25),
                     rally_lost_pmf=(0.0, 0.0, 0.5, 0.0, 0.3, 0.0, 0.2),
                     return_won=0.36, tour_return_won=0.36)
MODEL_B = ServeModel(first_serve_in=0.68, ace_first=0.05, first_serve_won=0.72,
                     double_fault=0.04, ace_second=0.01, second_serve_won=0.55,
                     first_serve_kmh_median=175.0, first_serve_kmh_iqr=12.0,
                     second_serve_kmh_median=140.0, second_serve_kmh_iqr=10.0)


def _replay_check(table, fmt, first_server, names):
    """The score columns must be exactly what MatchState says before each point."""
    state = MatchState.new(fmt, first_server)
    for row in table.itertuples(index=False):
        srv = state.server
        assert row.server == names[srv] and row.receiver == names[1 - srv]
        assert (row.set_no, row.server_games, row.receiver_games) == (
            state.set_no, state.games[srv], state.games[1 - srv])
        a, b = state.points[srv], state.points[1 - srv]
        if state.in_tiebreak:
            assert (row.server_score, row.receiver_score) == (str(a), str(b))
        elif min(a, b) >= 3:
            want = {0: ("40", "40"), 1: ("AD", "40"), -1: ("40", "AD")}[np.sign(a - b)]
            assert (row.server_score, row.receiver_score) == want
        else:
            names15 = ("0", "15", "30", "40")
            assert (row.server_score, row.receiver_score) == (names15[a], names15[b])
        state = state.point_won(names.index(row.winner))
    return state


def test_simulate_match_points_table_and_score_progression():
    names = ("Ann", "Bea")
    table, final = simulate_match_points(MODEL_A, MODEL_B, names, BO5_ADV, "grass", seed=5,
                                         match_id="m1", event="sim-2024")
    assert tuple(table.columns) == POINTS_COLUMNS
    assert {c: str(t) for c, t in table.dtypes.items()} == POINTS_DTYPES
    assert list(table["point"]) == list(range(1, len(table) + 1))
    assert final.is_over and table["winner"].iloc[-1] == names[final.winner]
    assert _replay_check(table, BO5_ADV, 0, names) == final
    assert (table["surface"] == "grass").all() and (table["match_id"] == "m1").all()
    # Serve-level consistency inside each row.
    df = table["double_fault"].to_numpy(bool)
    ace = table["ace"].to_numpy(bool)
    assert np.isnan(table["serve_kmh"].to_numpy(float)[df]).all()
    assert not np.isnan(table["serve_kmh"].to_numpy(float)[~df]).any()
    assert (table["rally"][df] == 0).all() and (table["rally"][ace] == 1).all()
    assert (table["serve_number"][~table["first_serve_in"]] == 2).all()
    served_by_b = table["server"] == "Bea"
    assert table.loc[served_by_b & ~table["ace"] & ~table["double_fault"], "rally"].isna().all()
    # Rally parity follows the slam convention (odd: the server won), as in the given pmfs.
    a_rallies = table[~served_by_b & ~table["ace"] & ~table["double_fault"]]
    assert ((a_rallies["rally"] % 2 == 1) == (a_rallies["winner"] == "Ann")).all()


def test_simulate_match_points_deterministic_and_seed_dependent():
    t1, _ = simulate_match_points(MODEL_A, MODEL_B, ("A", "B"), BO3, "hard", seed=1)
    t2, _ = simulate_match_points(MODEL_A, MODEL_B, ("A", "B"), BO3, "hard", seed=1)
    t3, _ = simulate_match_points(MODEL_A, MODEL_B, ("A", "B"), BO3, "hard", seed=2)
    pd.testing.assert_frame_equal(t1, t2)
    assert not t1.equals(t3)
    with pytest.raises(ValueError, match="surface"):
        simulate_match_points(MODEL_A, MODEL_B, ("A", "B"), BO3, "carpet", seed=1)


def test_simulated_rates_match_the_model():
    """Re-estimate the serve model from simulated matches (~2,000 points by player A)."""
    tables = [simulate_match_points(MODEL_A, MODEL_B, ("A", "B"), BO5_ADV, "hard", seed=s,
                                    opponent_adjust=False)[0] for s in range(14)]
    est = ServeModel.from_points(pd.concat(tables), "A")
    n = sum((t["server"] == "A").sum() for t in tables)
    assert n > 1500
    n1 = n * MODEL_A.first_serve_in
    n2 = n - n1
    for name, count in (("first_serve_in", n), ("ace_first", n1), ("first_serve_won", n1),
                        ("double_fault", n2), ("second_serve_won", n2)):
        p = getattr(MODEL_A, name)
        assert abs(getattr(est, name) - p) < 4 * math.sqrt(p * (1 - p) / count), name
    assert est.first_serve_kmh_median == pytest.approx(190.0, abs=1.5)
    assert est.second_serve_kmh_median == pytest.approx(150.0, abs=2.5)
    assert est.first_serve_kmh_iqr == pytest.approx(15.0, abs=2.5)
    assert est.rally_won_pmf[1] == pytest.approx(0.4, abs=0.06)


def _hand_table():
    """Ann serves 10 points against Bea, Bea serves 10 against Ann, known counts."""
    rows = []
    # Ann: 6 first serves in (2 aces, 5 won), 4 second serves (1 DF, 1 ace, 2 won in total).
    ann = [(True, True, False, True, 1), (True, True, False, True, 1),
           (True, False, False, True, 3), (True, False, False, True, 5),
           (True, False, False, True, 3), (True, False, False, False, 2),
           (False, False, True, False, 0), (False, True, False, True, 1),
           (False, False, False, True, 3), (False, False, False, False, 4)]
    # Bea: 5 first serves in (0 aces, 3 won), 5 second serves (0 DF, 0 aces, 2 won).
    bea = [(True, False, False, w, 3 if w else 2) for w in (True, True, True, False, False)]
    bea += [(False, False, False, w, 1 if w else 4) for w in (True, True, False, False, False)]
    for srv, rcv, pts in (("Ann", "Bea", ann), ("Bea", "Ann", bea)):
        for fsi, ace, dfl, won, rally in pts:
            rows.append({"match_id": "h", "point": len(rows) + 1, "server": srv,
                         "receiver": rcv, "winner": srv if won else rcv, "surface": "hard",
                         "event": "", "serve_number": 1 if fsi else 2, "first_serve_in": fsi,
                         "ace": ace, "double_fault": dfl,
                         "serve_kmh": np.nan if dfl else (200.0 if fsi else 150.0) + len(rows),
                         "rally": rally, "set_no": 1, "server_games": 0, "receiver_games": 0,
                         "server_score": "0", "receiver_score": "0"})
    return pd.DataFrame(rows)


def test_serve_model_from_points_exact():
    m = ServeModel.from_points(_hand_table(), "Ann")
    assert m.first_serve_in == 0.6 and m.ace_first == pytest.approx(2 / 6)
    assert m.first_serve_won == pytest.approx(5 / 6)
    assert m.double_fault == 0.25 and m.ace_second == pytest.approx(1 / 3)
    assert m.second_serve_won == 0.5
    assert m.first_serve_kmh_median == 202.5  # speeds 200..205
    assert m.first_serve_kmh_iqr == 2.5
    assert m.second_serve_kmh_median == 158.0  # second serves in: rows 8, 9 -> 157, 158, 159
    assert m.rally_won_pmf == pytest.approx((0, 0, 0, 3 / 4, 0, 1 / 4))  # rallies 3, 5, 3, 3
    assert m.rally_lost_pmf == pytest.approx((0, 0, 0.5, 0, 0.5))
    assert m.return_won == 0.5  # Bea won 5 of her 10 service points
    assert m.tour_return_won == pytest.approx(8 / 20)  # servers won 7 + 5 of 20
    assert m.serve_points_won == pytest.approx(0.7)
    with pytest.raises(ValueError, match="Cid"):
        ServeModel.from_points(_hand_table(), "Cid")


def test_matchup_and_adjustment_barnett_clarke():
    t = _hand_table()
    # f_Ann = 7/10, g_Bea = 3/10 (Bea won 3 of Ann's serves), f_av = 12/20.
    assert matchup_point_probability(t, "Ann", "Bea") == pytest.approx(0.7 - 0.3 + 0.4)
    assert matchup_point_probability(t, "Bea", "Ann") == pytest.approx(0.5 - 0.5 + 0.4)
    with pytest.raises(ValueError, match="Cid"):
        matchup_point_probability(t, "Cid", "Ann")
    # A receiver who wins 5 points in 100 more returns than average costs the server 0.05.
    strong = ServeModel(0.6, 0.1, 0.75, 0.1, 0.0, 0.5, return_won=0.40, tour_return_won=0.35)
    adj = MODEL_B.adjusted_against(strong)
    assert adj.serve_points_won == pytest.approx(MODEL_B.serve_points_won - 0.05)
    assert MODEL_B.adjusted_against(MODEL_B) is MODEL_B  # unknown return rates: no change


def test_serve_model_validation():
    with pytest.raises(ValueError, match="first_serve_in"):
        ServeModel(1.2, 0.1, 0.7, 0.1, 0.0, 0.5)
    with pytest.raises(ValueError, match="ace_first"):
        ServeModel(0.6, 0.8, 0.7, 0.1, 0.0, 0.5)
    with pytest.raises(ValueError, match="second_serve_won"):
        ServeModel(0.6, 0.1, 0.7, 0.3, 0.0, 0.8)


@pytest.mark.skipif(slam_dir() is None, reason=SHARED_DATA_MISSING)
def test_serve_model_from_real_2011_points():
    """Federer's 2011 serving (US Open + Wimbledon pooled), as in the data README's table."""
    from sportsngen.data.slam import read_slam_events

    pts = read_slam_events(events=["2011-usopen", "2011-wimbledon"])
    m = ServeModel.from_points(pts, "Roger Federer")
    assert m.first_serve_in == pytest.approx(0.664, abs=5e-4)
    assert m.first_serve_won == pytest.approx(0.786, abs=5e-4)
    assert m.second_serve_won == pytest.approx(0.598, abs=5e-4)
    assert (1 - m.first_serve_in) * m.double_fault == pytest.approx(0.016, abs=5e-4)
    assert (m.first_serve_kmh_median, m.second_serve_kmh_median) == (189.0, 156.0)
    assert m.rally_won_pmf is not None and m.serve_points_won > 0.6
    assert 0.6 < matchup_point_probability(pts, "Roger Federer", "Rafael Nadal") < 0.75
