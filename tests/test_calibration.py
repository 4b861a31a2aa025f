"""Reliability table, ECE and Brier score on hand-made predictions with known answers."""

import numpy as np
import pytest

from sportsngen.eval.calibration import (
    IsotonicCalibrator,
    LogisticCalibrator,
    brier_score,
    calibrator_from_dict,
    cluster_bootstrap,
    cross_fitted,
    ece_if_calibrated,
    expected_calibration_error,
    fit_calibrator,
    reliability_table,
)
from sportsngen.viz.calibration_plot import plot_reliability


def test_known_values():
    p = np.array([0.05, 0.05, 0.95, 0.95])
    y = np.array([0, 1, 1, 1])
    t = reliability_table(p, y, n_bins=10)
    assert t["count"].tolist() == [2, 0, 0, 0, 0, 0, 0, 0, 0, 2]
    assert t["observed"].iat[0] == 0.5 and t["observed"].iat[9] == 1.0
    # ECE = 0.5 * |0.5 - 0.05| + 0.5 * |1.0 - 0.95| = 0.25
    assert expected_calibration_error(p, y) == pytest.approx(0.25)
    # Brier = (0.0025 + 0.9025 + 0.0025 + 0.0025) / 4 = 0.2275
    assert brier_score(p, y) == pytest.approx(0.2275)
    assert reliability_table([1.0], [1]).loc[9, "count"] == 1   # 1.0 lands in the last bin


def test_calibrated_predictor_has_small_ece_and_constant_one_large():
    rng = np.random.default_rng(0)
    p = rng.uniform(0, 1, 20000)
    y = (rng.uniform(0, 1, p.size) < p).astype(float)
    assert expected_calibration_error(p, y) < 0.02
    assert expected_calibration_error(np.full(p.size, 0.9), y) > 0.35
    assert brier_score(p, y) == pytest.approx(1 / 6, abs=0.01)   # E[p(1-p)] for uniform p


def test_bad_input_and_plot(tmp_path):
    with pytest.raises(ValueError, match="probabilities"):
        brier_score([1.2], [1])
    with pytest.raises(ValueError, match="0 or 1"):
        brier_score([0.2], [0.5])
    out = plot_reliability({"a": np.array([0.2, 0.8])}, np.array([0, 1]), tmp_path / "r.png")
    assert out.read_bytes()[:4] == b"\x89PNG"


def test_isotonic_pools_adjacent_violators_exactly():
    cal = IsotonicCalibrator([0.1, 0.2, 0.3, 0.4], [1, 0, 1, 1])
    # (0.1, 1) and (0.2, 0) violate the order and pool to 0.5 at mean prediction 0.15.
    np.testing.assert_allclose(cal.x, [0.15, 0.3, 0.4])
    np.testing.assert_allclose(cal.y, [0.5, 1.0, 1.0])
    np.testing.assert_allclose(cal([0.0, 0.15, 0.225, 0.9]), [0.5, 0.5, 0.75, 1.0])
    with pytest.raises(ValueError):
        IsotonicCalibrator([], [])


def test_isotonic_recalibrates_a_biased_predictor_on_new_data():
    rng = np.random.default_rng(3)
    truth = rng.uniform(0.05, 0.95, 8000)
    y = (rng.uniform(size=8000) < truth).astype(float)
    raw = truth ** 3                     # right order, wrong level
    cal = IsotonicCalibrator(raw[:4000], y[:4000])
    fixed = cal(raw[4000:])
    assert np.all(np.diff(cal.y) >= 0)
    assert expected_calibration_error(raw[4000:], y[4000:]) > 0.2
    assert expected_calibration_error(fixed, y[4000:]) < 0.03
    assert brier_score(fixed, y[4000:]) < brier_score(raw[4000:], y[4000:])


def test_calibrator_round_trips_through_a_dict_and_rejects_bad_maps():
    cal = IsotonicCalibrator([0.1, 0.2, 0.6, 0.9], [0, 1, 0, 1])
    again = IsotonicCalibrator.from_dict(cal.to_dict())
    grid = np.linspace(0, 1, 11)
    np.testing.assert_array_equal(again(grid), cal(grid))
    assert cal.to_dict() == {"kind": "isotonic", "x": [0.1, 0.4, 0.9], "y": [0.0, 0.5, 1.0],
                             "n": [1, 2, 1]}
    with pytest.raises(ValueError, match="non-decreasing"):
        IsotonicCalibrator.from_dict({"x": [0.5, 0.2], "y": [0.1, 0.3]})


def test_cluster_bootstrap_resamples_whole_groups():
    # 200 groups of 50 rows, every row of a group sharing its 0/1 outcome: the mean has the
    # spread of 200 coin flips (half-width 1.96 * sqrt(0.25 / 200) = 0.069), not of 10,000.
    rng = np.random.default_rng(0)
    y = np.repeat(rng.integers(0, 2, 200), 50).astype(float)
    groups = np.repeat(np.arange(200), 50)
    lo, hi = cluster_bootstrap(lambda i: y[i].mean(), groups, n_boot=400, seed=1)
    assert 0.11 < hi - lo < 0.17
    assert lo < y.mean() < hi
    # Identical groups: every resample is the same, so the interval has no width.
    same = np.tile([0.0, 1.0, 1.0], 30)
    lo, hi = cluster_bootstrap(lambda i: same[i].mean(), np.repeat(np.arange(30), 3), 50)
    assert lo == pytest.approx(2 / 3) and hi == pytest.approx(2 / 3)
    # Array statistics keep their shape; groups may come in any order.
    g = np.array([2, 0, 2, 1, 0, 1])
    v = np.array([1.0, 0.0, 1.0, 5.0, 0.0, 5.0])
    lo, hi = cluster_bootstrap(lambda i: np.array([v[i].min(), v[i].max()]), g, 100)
    assert lo.shape == (2,) and (lo <= hi).all() and hi[1] == 5.0 and lo[0] == 0.0
    with pytest.raises(ValueError, match="n_boot"):
        cluster_bootstrap(lambda i: 0.0, g, 0)


def test_ece_if_calibrated_is_zero_for_certain_predictions_and_grows_with_fewer_rollouts():
    certain = np.array([0.0, 1.0, 1.0, 0.0])
    np.testing.assert_array_equal(ece_if_calibrated(certain, 16, n_boot=20), np.zeros(20))
    # p = 0.45 (inside one bin) with many rollouts: the ECE is |observed - 0.45| of 400
    # coins, whose mean is sqrt(0.45 * 0.55 / 400) * sqrt(2 / pi) = 0.0199.
    one_bin = ece_if_calibrated(np.full(400, 0.45), 100_000, n_boot=2000, seed=1)
    assert one_bin.mean() == pytest.approx(0.0199, abs=0.0015)
    rng = np.random.default_rng(0)
    spread = rng.beta(2, 1, 800)
    few, many = (ece_if_calibrated(spread, n, n_boot=200, seed=2).mean() for n in (4, 1000))
    assert few > many + 0.02
    per_item = ece_if_calibrated(spread, np.full(800, 16), n_boot=200, seed=2)
    assert per_item.mean() == pytest.approx(0.049, abs=0.004)
    with pytest.raises(ValueError, match="rollout"):
        ece_if_calibrated([0.5], 0)


def test_ece_if_calibrated_groups_share_one_draw():
    rng = np.random.default_rng(3)
    spread = rng.beta(2, 1, 300)
    # one label a point, in point order: the same uniform numbers, so the same draws
    apart = ece_if_calibrated(spread, 16, n_boot=50, seed=4)
    singles = ece_if_calibrated(spread, 16, n_boot=50, seed=4, groups=np.arange(300))
    np.testing.assert_array_equal(apart, singles)
    # one group of equal predictions: every outcome agrees, so the ECE is 0.7 (all won, with
    # probability 0.3) or 0.3 (all lost), never the small value of 300 coins drawn apart
    one = ece_if_calibrated(np.full(300, 0.3), 10**9, n_boot=2000, seed=5,
                            groups=np.zeros(300))
    assert np.all(np.isclose(one, 0.7, atol=1e-3) | np.isclose(one, 0.3, atol=1e-3))
    assert np.isclose(one, 0.7, atol=1e-3).mean() == pytest.approx(0.3, abs=0.03)
    free = ece_if_calibrated(np.full(300, 0.3), 10**9, n_boot=200, seed=5)
    assert free.max() < 0.15
    # rallies of four that share their outcome spread the floor wider than points apart
    rallies = np.repeat(np.arange(75), 4)
    shared = ece_if_calibrated(spread, 32, n_boot=300, seed=6, groups=rallies)
    assert np.percentile(shared, 90) > np.percentile(
        ece_if_calibrated(spread, 32, n_boot=300, seed=6), 90)
    with pytest.raises(ValueError, match="one label a prediction"):
        ece_if_calibrated(spread, 16, groups=np.zeros(5))


def _brownian_rallies(rng, n_rallies=200, times=(1.0, 2.0, 3.0, 4.0), end=5.0):
    """Rallies whose truth is known: a Brownian state, the server winning if it ends above
    zero, and at each branch time the exact probability of that (a calibrated predictor whose
    branch points share their rally's outcome)."""
    from scipy.stats import norm

    t = np.asarray(times)
    drift = 0.35 * np.sqrt(end)
    steps = rng.normal(0.0, 1.0, (n_rallies, len(t) + 1)) * np.sqrt(np.diff(np.r_[0, t, end]))
    x = np.cumsum(steps, axis=1)
    won = np.repeat((x[:, -1] + drift > 0).astype(float), len(t))
    return norm.cdf((x[:, :-1] + drift) / np.sqrt(end - t)).ravel(), won


def test_shared_draws_match_the_spread_of_rallies_that_share_their_outcome():
    # The ECE a calibrated predictor really scores when 4 branch points share each of 200
    # rallies' outcomes, against what the two nulls say from its predictions alone: drawn
    # apart, the floor is too low; one shared number a rally comes near (in s99: true mean
    # 0.042, shared 0.041, apart 0.036 over 300 samples).
    rng = np.random.default_rng(0)
    true, apart, shared = [], [], []
    for b in range(120):
        p, won = _brownian_rallies(rng)
        share = rng.binomial(32, p) / 32
        true.append(expected_calibration_error(share, won))
        if b < 12:
            rallies = np.repeat(np.arange(200), 4)
            apart.append(ece_if_calibrated(share, 32, n_boot=60, seed=b))
            shared.append(ece_if_calibrated(share, 32, n_boot=60, seed=b, groups=rallies))
    true_mean, apart_mean, shared_mean = np.mean(true), np.mean(apart), np.mean(shared)
    assert abs(shared_mean - true_mean) < 0.003
    assert apart_mean < true_mean - 0.004


def _logit(p):
    return np.log(p / (1 - p))


def test_logistic_recovers_the_level_and_slope_of_a_biased_predictor():
    rng = np.random.default_rng(4)
    raw = rng.uniform(0.05, 0.95, 40_000)
    truth = 1 / (1 + np.exp(-(0.5 + 1.3 * _logit(raw))))      # a = 0.5, b = 1.3
    y = (rng.uniform(size=raw.size) < truth).astype(float)
    cal = LogisticCalibrator(raw, y)
    assert cal.a == pytest.approx(0.5, abs=0.04) and cal.b == pytest.approx(1.3, abs=0.04)
    np.testing.assert_allclose(cal(raw), truth, atol=0.01)
    # Already calibrated: the identity map (a = 0, b = 1).
    y_cal = (rng.uniform(size=raw.size) < raw).astype(float)
    ident = LogisticCalibrator(raw, y_cal)
    assert ident.a == pytest.approx(0.0, abs=0.04) and ident.b == pytest.approx(1.0, abs=0.04)
    # Shares of 0 and 1 are clipped to eps before the log-odds: finite, and a = 0, b = 1 maps
    # them to eps and 1 - eps exactly.
    ident.a, ident.b = 0.0, 1.0
    np.testing.assert_allclose(ident([0.0, 0.5, 1.0]), [0.01, 0.5, 0.99])


def test_logistic_stays_finite_on_degenerate_data_and_rejects_bad_input():
    ones = LogisticCalibrator([0.3, 0.6, 0.6, 0.8], [1, 1, 1, 1])
    assert np.isfinite([ones.a, ones.b]).all() and (ones([0.3, 0.8]) > [0.3, 0.8]).all()
    single = LogisticCalibrator([0.5, 0.5, 0.5, 0.5], [1, 0, 1, 1])
    assert single(0.5) == pytest.approx(0.75, abs=0.01)
    with pytest.raises(ValueError, match="at least one"):
        LogisticCalibrator([], [])
    with pytest.raises(ValueError, match="eps"):
        LogisticCalibrator([0.5], [1], eps=0.5)


def test_calibrators_round_trip_by_kind_and_old_maps_read_as_isotonic():
    cal = LogisticCalibrator([0.2, 0.4, 0.6, 0.8, 0.9], [0, 1, 1, 1, 1])
    d = cal.to_dict()
    assert d["kind"] == "logistic" and set(d) == {"kind", "a", "b", "eps"}
    again = calibrator_from_dict(d)
    assert isinstance(again, LogisticCalibrator)
    grid = np.linspace(0, 1, 11)
    np.testing.assert_array_equal(again(grid), cal(grid))
    old = calibrator_from_dict({"x": [0.2, 0.6], "y": [0.3, 0.5]})     # no "kind"
    assert isinstance(old, IsotonicCalibrator)
    np.testing.assert_allclose(old([0.4]), [0.4])
    with pytest.raises(ValueError, match="unknown calibrator"):
        calibrator_from_dict({"kind": "beta"})
    with pytest.raises(ValueError, match="finite"):
        calibrator_from_dict({"kind": "logistic", "a": float("nan"), "b": 1.0})
    with pytest.raises(ValueError, match="unknown calibrator"):
        fit_calibrator("beta", [0.5], [1])
    assert isinstance(fit_calibrator("isotonic", [0.5], [1]), IsotonicCalibrator)


def test_cross_fitted_maps_each_fold_by_the_others_only():
    rng = np.random.default_rng(5)
    raw = rng.uniform(0.1, 0.9, 600)
    y = (rng.uniform(size=600) < raw).astype(float)
    fold = np.arange(600) % 3
    out = cross_fitted("logistic", raw, y, fold)
    # Fold 0's values are the map of folds 1 and 2, whatever fold 0's outcomes are.
    expected = LogisticCalibrator(raw[fold != 0], y[fold != 0])(raw[fold == 0])
    np.testing.assert_allclose(out[fold == 0], expected)
    flipped = y.copy()
    flipped[fold == 0] = 1 - flipped[fold == 0]
    np.testing.assert_allclose(cross_fitted("logistic", raw, flipped, fold)[fold == 0], expected)
    with pytest.raises(ValueError, match="two folds"):
        cross_fitted("logistic", raw, y, np.zeros(600))
    with pytest.raises(ValueError, match="fold label"):
        cross_fitted("logistic", raw, y, fold[:10])


def test_logistic_out_of_fold_fixes_a_biased_level():
    # The rally outcome study's situation: a few hundred predictions from 32 rollouts each, a
    # level off by 0.4 on the log-odds; the two-number map, fitted on the other half only,
    # brings the ECE down to about the noise of 200 points (0.034 here; raw 0.101).
    rng = np.random.default_rng(6)
    truth = rng.beta(4, 2, 400)
    shares = rng.binomial(32, 1 / (1 + np.exp(-(_logit(truth) - 0.4)))) / 32
    y = (rng.uniform(size=400) < truth).astype(float)
    fold = np.arange(400) % 2
    raw_ece = expected_calibration_error(shares, y)
    logistic = expected_calibration_error(cross_fitted("logistic", shares, y, fold), y)
    assert raw_ece > 0.09 and logistic < 0.045
