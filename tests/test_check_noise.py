"""The checks' noise: standard errors of a statistic's gap from resampling both sides."""

import math

import numpy as np
import pandas as pd
import pytest

from sportsngen.eval.check_noise import (
    chance_outside,
    concat_runs,
    expected_within,
    format_pooled,
    gap_noise,
    pool_gaps,
)


def _points(server: str, first_in: list[int], won: list[bool], rally: list[int]) -> pd.DataFrame:
    return pd.DataFrame({"server": server, "receiver": "B",
                         "winner": [server if w else "B" for w in won],
                         "first_serve_in": first_in, "ace": 0, "double_fault": 0,
                         "rally": rally})


def test_gap_and_point_values_exact():
    sim = _points("A", [1, 1, 0, 1], [True, True, False, True], [1, 3, 5, 7])
    truth = _points("A", [1, 0], [False, True], [2, 2])
    n = gap_noise(sim, truth, ["A"], ["first_serve_in", "serve_points_won", "rally_mean"],
                  n_boot=200).set_index("statistic")
    assert n.at["first_serve_in", "sim"] == 0.75 and n.at["first_serve_in", "truth"] == 0.5
    assert n.at["first_serve_in", "gap"] == pytest.approx(0.25)
    assert n.at["serve_points_won", "gap"] == pytest.approx(0.25)
    assert n.at["rally_mean", "gap"] == pytest.approx(2.0)
    assert (n["n_sim"] == 4).all() and (n["n_truth"] == 2).all()
    assert n.at["rally_mean", "z"] == pytest.approx(2.0 / n.at["rally_mean", "se"])


def test_values_replace_the_points_reading_as_a_median():
    sim = _points("A", [1, 1, 1], [True] * 3, [1, 1, 1])
    truth = _points("A", [1, 1], [True] * 2, [1, 1])
    vals = {("sim", "A", "first_serve_kmh_median"): np.array([150.0, 160.0, 170.0, np.nan]),
            ("truth", "A", "first_serve_kmh_median"): np.array([158.0, 162.0])}
    row = gap_noise(sim, truth, ["A"], ["first_serve_kmh_median"], values=vals).iloc[0]
    assert (row["sim"], row["truth"], row["gap"]) == (160.0, 160.0, 0.0)
    assert (row["n_sim"], row["n_truth"]) == (3, 2)


def test_standard_error_of_a_share_matches_the_binomial():
    rng = np.random.default_rng(4)
    p, n_sim, n_truth = 0.6, 500, 1500
    sim = _points("A", list(rng.random(n_sim) < p), [True] * n_sim, [1] * n_sim)
    truth = _points("A", list(rng.random(n_truth) < p), [True] * n_truth, [1] * n_truth)
    row = gap_noise(sim, truth, ["A"], ["first_serve_in"], n_boot=3000, seed=1).iloc[0]
    ps, pt = row["sim"], row["truth"]
    expected = math.sqrt(ps * (1 - ps) / n_sim + pt * (1 - pt) / n_truth)
    assert row["se"] == pytest.approx(expected, rel=0.05)


def test_chance_outside_and_expected_within():
    assert chance_outside(1.959964, 1.0) == pytest.approx(0.05, abs=1e-6)
    assert chance_outside(5.0, 0.0) == 0.0
    assert math.isnan(chance_outside(5.0, float("nan")))
    noise = pd.DataFrame({"statistic": ["first_serve_in", "rally_mean"],
                          "se": [0.025, 0.25]})
    got = expected_within(noise, {"first_serve_in": 5.0, "rally_mean": 0.5},
                          {"first_serve_in": 100.0})
    assert got == pytest.approx(2.0 - 2 * 0.0455003, abs=1e-5)


def test_bad_input_is_refused():
    good = _points("A", [1], [True], [1])
    with pytest.raises(ValueError, match="no per-point reading"):
        gap_noise(good, good, ["A"], ["n_points"])
    with pytest.raises(ValueError, match="missing the points table's columns"):
        gap_noise(good.drop(columns="winner"), good, ["A"], ["ace"])


def test_each_sides_error_and_pooling():
    rng = np.random.default_rng(2)
    sim = _points("A", list(rng.random(400) < 0.5), [True] * 400, [1] * 400)
    truth = _points("A", list(rng.random(4000) < 0.5), [True] * 4000, [1] * 4000)
    row = gap_noise(sim, truth, ["A"], ["first_serve_in"], n_boot=2000).iloc[0]
    assert row["se"] == pytest.approx(math.hypot(row["se_sim"], row["se_truth"]))
    # Ten times the points on the truth's side: about a third of the sim's error.
    assert row["se_truth"] / row["se_sim"] == pytest.approx(math.sqrt(0.1), rel=0.1)
    a = pd.DataFrame({"server": ["A", "A"], "statistic": ["ace", "rally_mean"],
                      "gap": [0.02, 0.4], "se": [0.01, 0.2]})
    b = pd.DataFrame({"server": ["A", "A"], "statistic": ["ace", "rally_mean"],
                      "gap": [0.04, np.nan], "se": [0.02, 0.2]})
    pooled = pool_gaps([a, b]).set_index("statistic")
    assert pooled.at["ace", "runs"] == 2 and pooled.at["rally_mean", "runs"] == 1
    assert pooled.at["ace", "gap"] == pytest.approx(0.03)
    assert pooled.at["ace", "se"] == pytest.approx(math.sqrt(0.01 ** 2 + 0.02 ** 2) / 2)
    assert pooled.at["rally_mean", "z"] == pytest.approx(2.0)
    with pytest.raises(ValueError, match="no checks"):
        pool_gaps([])


def test_runs_concatenated_read_as_one_sample_against_a_shared_truth():
    a = _points("A", [1, 1, 0, 1], [True] * 4, [1, 3, 5, 7])
    b = _points("A", [0, 0], [True] * 2, [2, 2])
    truth = _points("A", [1, 0] * 50, [True] * 100, [4] * 100)
    key = ("sim", "A", "first_serve_kmh_median")
    pts, vals = concat_runs([a, b], [{key: [150.0, 160.0]}, {key: np.array([170.0])}])
    assert len(pts) == 6 and pts.index.is_unique
    np.testing.assert_array_equal(vals[key], [150.0, 160.0, 170.0])
    vals[("truth", "A", "first_serve_kmh_median")] = np.array([150.0, 150.0])
    n = gap_noise(pts, truth, ["A"], ["first_serve_in", "rally_mean", "first_serve_kmh_median"],
                  values=vals, n_boot=200).set_index("statistic")
    # The pooled points' share (3 of 6) and mean rally (20 / 6), not the runs' mean of means.
    assert n.at["first_serve_in", "gap"] == pytest.approx(0.0)
    assert n.at["rally_mean", "gap"] == pytest.approx(20 / 6 - 4)
    assert n.at["first_serve_kmh_median", "gap"] == pytest.approx(10.0)
    assert n.at["rally_mean", "n_sim"] == 6
    with pytest.raises(ValueError, match="no runs"):
        concat_runs([])


def test_the_pooled_table_marks_gaps_outside_and_biases():
    rows = pd.DataFrame({"server": "A", "runs": 3,
                         "statistic": ["first_serve_in", "ace", "rally_mean"],
                         "gap": [0.02, 0.06, -0.6], "se": [0.01, 0.03, 0.1]})
    rows["z"] = rows["gap"] / rows["se"]
    line = format_pooled(rows).splitlines()[1]
    assert line.startswith("A") and " 3 " in line
    # 2 points inside the tolerance; 6 points outside with z 2 (*); -0.6 shots with z -6 (!).
    assert "+2.00±1.00  z +2.0 " in line
    assert "+6.00±3.00  z +2.0*" in line
    assert "-0.60±0.10  z -6.0!" in line
    assert line.split().count("-") == 3  # double faults, serve points won, km/h: absent
