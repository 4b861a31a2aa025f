"""Calibration of probabilistic predictions: reliability table, expected calibration error,
Brier score, recalibration (logistic on the log-odds, or isotonic) judged out of fold. Pure
numpy; the paper's reliability diagram with the histogram of predictions (Fig. 14/15) is
`viz.calibration_plot.plot_reliability`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd


def _check(pred, outcome) -> tuple[np.ndarray, np.ndarray]:
    p = np.asarray(pred, dtype=float)
    y = np.asarray(outcome, dtype=float)
    if p.shape != y.shape or p.ndim != 1:
        raise ValueError(f"predictions and outcomes must be 1-D of one length, got {p.shape}, "
                         f"{y.shape}")
    if np.isnan(p).any() or ((p < 0) | (p > 1)).any():
        raise ValueError("predictions must be probabilities in [0, 1] (no NaN)")
    if not np.isin(y, (0.0, 1.0)).all():
        raise ValueError("outcomes must be 0 or 1")
    return p, y


def reliability_table(pred, outcome, n_bins: int = 10) -> pd.DataFrame:
    """Equal-width bins of the predicted probability: per bin its count, mean prediction and
    observed frequency (NaN for empty bins). The last bin includes 1.0."""
    p, y = _check(pred, outcome)
    edges = np.linspace(0.0, 1.0, n_bins + 1)
    b = np.clip(np.digitize(p, edges[1:-1], right=False), 0, n_bins - 1)
    count = np.bincount(b, minlength=n_bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_pred = np.bincount(b, weights=p, minlength=n_bins) / count
        freq = np.bincount(b, weights=y, minlength=n_bins) / count
    return pd.DataFrame({"lo": edges[:-1], "hi": edges[1:], "count": count,
                         "mean_pred": mean_pred, "observed": freq})


def expected_calibration_error(pred, outcome, n_bins: int = 10) -> float:
    """Sum over bins of (bin share) * |observed frequency - mean prediction|."""
    t = reliability_table(pred, outcome, n_bins)
    w = t["count"].to_numpy() / max(int(t["count"].sum()), 1)
    gap = np.abs(t["observed"].to_numpy() - t["mean_pred"].to_numpy())
    return float(np.nansum(w * gap))


def brier_score(pred, outcome) -> float:
    """Mean squared difference between the probability and the 0/1 outcome."""
    p, y = _check(pred, outcome)
    return float(np.mean((p - y) ** 2))


def ece_if_calibrated(pred, n_rollouts, n_boot: int = 500, seed: int = 0,
                      n_bins: int = 10, groups=None) -> np.ndarray:
    """ECE a perfectly calibrated simulator would show with this design: `n_boot` draws.

    A rollout probability is a share of `n_rollouts` (a scalar or one count a prediction)
    branches, and an ECE over a few hundred outcomes is not zero even for the truth: the
    bins' observed frequencies are noisy, and so are the shares that sort the predictions into
    bins. Each draw takes the predictions as the true probabilities, redraws every share from
    its binomial and every outcome from its probability, and computes the ECE: the spread of
    values a right model would score. With predictions spread like the bundled model's, 16
    rollouts and 800 independent branch points give a mean of about 0.049; 32 rollouts about
    0.039 (docs/evaluation.md, twenty-second part).

    The branch points of one rally share its outcome, which widens that spread. Without
    `groups` every outcome is drawn apart (a lower bound of the noise floor). With `groups`
    (one label a prediction, e.g. the rally id) the predictions of a group draw their outcomes
    from one shared uniform number: each stays right on its own (outcome = 1 with probability
    p) and a group's outcomes agree as far as their probabilities allow, the most a fixed set
    of probabilities lets them agree (docs/evaluation.md, eighty-first part).
    """
    p = np.asarray(pred, dtype=float)
    _check(p, np.zeros(p.shape))
    n = np.broadcast_to(np.asarray(n_rollouts), p.shape)
    if (n < 1).any():
        raise ValueError("every prediction needs at least one rollout")
    if n_boot < 1:
        raise ValueError(f"n_boot must be >= 1, got {n_boot}")
    codes = None
    if groups is not None:
        labels = np.asarray(groups).ravel()
        if labels.shape != p.shape:
            raise ValueError(f"groups needs one label a prediction: {labels.shape} against "
                             f"{p.shape}")
        codes = np.unique(labels, return_inverse=True)[1].ravel()
    rng = np.random.default_rng(seed)
    out = np.empty(n_boot)
    for b in range(n_boot):
        share = rng.binomial(n, p) / n
        u = rng.random(p.shape) if codes is None else rng.random(codes.max() + 1)[codes]
        out[b] = expected_calibration_error(share, (u < p).astype(float), n_bins)
    return out


def cluster_bootstrap(stat, groups, n_boot: int = 1000, seed: int = 0,
                      level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Percentile interval of `stat` when whole groups are resampled, not single rows.

    Predictions that share a group (the points of one match, which share its outcome) are
    not independent; resampling groups with replacement keeps that dependence, so the
    interval is honest about how few independent outcomes there are. `stat(idx)` gets an
    index array into the rows (a group drawn twice appears twice) and returns a number or an
    array; the result is (low, high) of the same shape.
    """
    codes = np.unique(np.asarray(groups).ravel(), return_inverse=True)[1].ravel()
    if n_boot < 1:
        raise ValueError(f"n_boot must be >= 1, got {n_boot}")
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1), got {level}")
    order = np.argsort(codes, kind="stable")
    counts = np.bincount(codes)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    rng = np.random.default_rng(seed)
    draws = []
    for _ in range(n_boot):
        pick = rng.integers(0, len(counts), len(counts))
        n = counts[pick]
        offset = np.repeat(starts[pick] - (np.cumsum(n) - n), n)
        draws.append(np.asarray(stat(order[offset + np.arange(n.sum())]), dtype=float))
    tail = 100.0 * (1.0 - level) / 2.0
    lo, hi = np.nanpercentile(np.stack(draws), [tail, 100.0 - tail], axis=0)
    return lo, hi


class IsotonicCalibrator:
    """A monotone map from raw probabilities to observed frequencies, fitted by pool-adjacent-
    violators on (prediction, outcome) pairs; new predictions are interpolated linearly between
    the fitted blocks' mean predictions (constant beyond them).

    For win probabilities on a broadcast: a simulator that is right about which situations are
    better but biased in level (its receivers return too few serves, say) keeps its ranking
    and gets the level from data. Fit on one set of rallies, judge on another.
    """

    def __init__(self, pred, outcome):
        p, y = _check(pred, outcome)
        if len(p) == 0:
            raise ValueError("fitting a calibrator needs at least one prediction")
        order = np.argsort(p, kind="stable")
        # Blocks as (sum of outcomes, sum of predictions, count); merge while they decrease.
        ys, ps, ns = [], [], []
        for pi, yi in zip(p[order], y[order]):
            ys.append(yi)
            ps.append(pi)
            ns.append(1)
            while len(ys) > 1 and ys[-2] / ns[-2] > ys[-1] / ns[-1]:
                y_last, p_last, n_last = ys.pop(), ps.pop(), ns.pop()
                ys[-1] += y_last
                ps[-1] += p_last
                ns[-1] += n_last
        n = np.asarray(ns, dtype=float)
        self.x = np.asarray(ps) / n          # mean raw prediction of each block (increasing)
        self.y = np.asarray(ys) / n          # observed frequency of each block (non-decreasing)
        self.n = n.astype(int)

    def __call__(self, pred) -> np.ndarray:
        p = np.asarray(pred, dtype=float)
        return np.interp(p, self.x, self.y)

    def to_dict(self) -> dict:
        """Plain lists (a model file's extras, JSON)."""
        return {"kind": "isotonic", "x": self.x.tolist(), "y": self.y.tolist(),
                "n": self.n.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> IsotonicCalibrator:
        """The calibrator `to_dict` wrote (no refit)."""
        x, y = np.asarray(d["x"], dtype=float), np.asarray(d["y"], dtype=float)
        if x.ndim != 1 or x.shape != y.shape or len(x) == 0 or (np.diff(x) < 0).any() \
                or (np.diff(y) < 0).any():
            raise ValueError("a calibrator needs equally long, non-decreasing x and y")
        out = cls.__new__(cls)
        out.x, out.y = x, y
        out.n = np.asarray(d.get("n", np.ones(len(x))), dtype=int)
        return out


class LogisticCalibrator:
    """Platt scaling on the log-odds: `sigmoid(a + b * logit(p))`, `a` and `b` fitted by maximum
    likelihood on (prediction, outcome) pairs; raw predictions are clipped to
    [`eps`, 1 - `eps`] first, because rollout shares of 0 or 1 have no finite log-odds.

    Two numbers instead of a step per block: on a few hundred branch points of a hundred-odd
    rallies an isotonic map learns the fitting rallies' noise (out of fold it scored worse than
    the raw rollouts), while a simulator's usual fault, a level off by a few points (its
    servers win too few rallies), is a shift of `a`.
    """

    def __init__(self, pred, outcome, eps: float = 0.01):
        p, y = _check(pred, outcome)
        if len(p) == 0:
            raise ValueError("fitting a calibrator needs at least one prediction")
        if not 0.0 < eps < 0.5:
            raise ValueError(f"eps must be in (0, 0.5), got {eps}")
        self.eps = float(eps)
        x = self._logit(p)
        design = np.stack([np.ones_like(x), x], axis=1)
        w = np.array([0.0, 1.0])
        # Newton's method on the log-likelihood with a whisker of ridge toward the identity
        # map, so that outcomes all 0 or all 1 (or one distinct prediction) stay finite.
        ridge = 1e-3 * np.eye(2)
        for _ in range(100):
            q = 1.0 / (1.0 + np.exp(-(design @ w)))
            grad = design.T @ (q - y) + ridge @ (w - np.array([0.0, 1.0]))
            hess = (design * (q * (1.0 - q))[:, None]).T @ design + ridge
            step = np.linalg.solve(hess, grad)
            w = w - step
            if np.abs(step).max() < 1e-10:
                break
        self.a, self.b = float(w[0]), float(w[1])

    def _logit(self, p: np.ndarray) -> np.ndarray:
        q = np.clip(p, self.eps, 1.0 - self.eps)
        return np.log(q / (1.0 - q))

    def __call__(self, pred) -> np.ndarray:
        z = self.a + self.b * self._logit(np.asarray(pred, dtype=float))
        return 1.0 / (1.0 + np.exp(-z))

    def to_dict(self) -> dict:
        """Plain numbers (a model file's extras, JSON)."""
        return {"kind": "logistic", "a": self.a, "b": self.b, "eps": self.eps}

    @classmethod
    def from_dict(cls, d: dict) -> LogisticCalibrator:
        """The calibrator `to_dict` wrote (no refit)."""
        a, b, eps = float(d["a"]), float(d["b"]), float(d.get("eps", 0.01))
        if not (np.isfinite(a) and np.isfinite(b) and 0.0 < eps < 0.5):
            raise ValueError(f"a logistic calibrator needs finite a, b and eps in (0, 0.5), "
                             f"got {d}")
        out = cls.__new__(cls)
        out.a, out.b, out.eps = a, b, eps
        return out


CALIBRATORS = {"logistic": LogisticCalibrator, "isotonic": IsotonicCalibrator}


def _calibrator_class(kind: str):
    if kind not in CALIBRATORS:
        raise ValueError(f"unknown calibrator {kind!r}: one of {sorted(CALIBRATORS)}")
    return CALIBRATORS[kind]


def fit_calibrator(kind: str, pred, outcome):
    """A `kind` ("logistic" or "isotonic") calibrator fitted on (prediction, outcome) pairs."""
    return _calibrator_class(kind)(pred, outcome)


def calibrator_from_dict(d: dict):
    """The calibrator a `to_dict` wrote; a dict without "kind" is an isotonic map (the files
    written before there was a choice)."""
    return _calibrator_class(d.get("kind", "isotonic")).from_dict(d)


def cross_fitted(kind: str, pred, outcome, fold) -> np.ndarray:
    """Each prediction mapped by a `kind` calibrator fitted on the other folds only (`fold`: a
    label per prediction; give a rally's branch points one fold, as they share its outcome):
    recalibration judged on every point without judging a map on its own data."""
    p, y = _check(pred, outcome)
    fold = np.asarray(fold)
    if fold.shape != p.shape:
        raise ValueError(f"one fold label per prediction, got {fold.shape} for {p.shape}")
    labels = np.unique(fold)
    if len(labels) < 2:
        raise ValueError("cross-fitting needs at least two folds")
    out = np.empty_like(p)
    for k in labels:
        test = fold == k
        out[test] = fit_calibrator(kind, p[~test], y[~test])(p[test])
    return out
