"""The strike head's errors by where the ball is struck: the depth table
(`model.strike_bias.depth_band`, `ModelConfig.strike_depth`, `fit_strike_pressure(depth_only=)`)."""

import numpy as np
import pytest
import torch

from sportsngen.model import strike_bias
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN
from sportsngen.train.head_fit import HeadStates
from sportsngen.train.strike_bias import (
    fit_strike_pressure,
    with_strike_bias,
    with_strike_depth,
    with_strike_pressure,
    with_strike_return,
)
from tests.test_strike_bias import _two_strikes_seen, small_model

BASE = 11.885


def _depth_model() -> SportsNGEN:
    return with_strike_depth(with_strike_pressure(with_strike_return(with_strike_bias(
        small_model()))))


def test_a_contacts_band_is_its_distance_behind_the_baseline_either_end():
    behind = [-2.0, -1.0, -0.5, 0.0, 0.5, 0.75, 1.0, 2.0, 2.25, 2.5, 3.0, 5.0]
    for sign in (1.0, -1.0):
        x = torch.tensor([sign * (BASE + b) for b in behind], dtype=torch.float64)
        assert strike_bias.depth_band(x).tolist() == [0, 1, 1, 2, 2, 3, 3, 4, 5, 5, 6, 6]
    assert strike_bias.N_DEPTH_BANDS == 7


def test_the_depth_table_adds_its_band_on_every_strike_but_the_return():
    model = _depth_model()
    assert model.strike_depth.shape == (7, 2, 3) and (model.strike_depth == 0).all()
    assert "strike_depth" not in SportsNGEN.PER_IDENTITY_TABLES     # a row a band, not a player
    model.strike_bias[3, 1] = torch.tensor([1.0, 0.0, 0.0])
    model.strike_depth[5, 1] = torch.tensor([0.5, -1.0, 0.0])
    model.strike_depth[5, 0] = torch.tensor([9.0, 9.0, 9.0])        # another role: not read
    model.strike_depth[2, 1] = torch.tensor([-0.25, 0.0, 0.0])
    x = torch.tensor([-(BASE + 2.5), BASE + 2.5, BASE + 0.2])
    b = model.strike_head_bias(torch.full((3,), 3), torch.ones(3, dtype=torch.bool),
                               torch.tensor([True, False, False]), torch.full((3,), 2),
                               torch.tensor([1, 3, 3]), x)
    masks = torch.as_tensor(strike_bias.error_bins())
    assert [b[k, 0][masks[0]].unique().tolist() for k in range(3)] == [[1.0], [1.5], [0.75]]
    assert [b[k, 1][masks[1]].unique().tolist() for k in range(3)] == [[0.0], [-1.0], [0.0]]
    # Where the ball is not given: no band read.
    torch.testing.assert_close(
        model.strike_head_bias(torch.full((3,), 3), torch.ones(3, dtype=torch.bool),
                               torch.tensor([True, False, False]), torch.full((3,), 2),
                               torch.tensor([1, 3, 3])), b[[0, 0, 0]])
    with pytest.raises(ValueError, match="strike_pressure"):
        ModelConfig(strike_head=True, strike_bias=True, strike_return=True, strike_depth=True)


def test_a_rollouts_strike_reads_the_band_of_the_ball_it_strikes():
    model = _depth_model()
    model.strike_depth[:, :, 0] = torch.arange(7, dtype=torch.float32)[:, None]
    seen, pos = _two_strikes_seen(model)
    pos[0, 3 - 1, 0] = -(BASE + 2.5)      # the receiver's ball 2.5 m behind his baseline
    pos[1, 3 - 1, 0] = BASE - 0.5         # the server's half a metre inside his
    model.place_strikes(torch.zeros(2, 3, 32), pos, torch.zeros(2, 3, 3), pos.clone(),
                        forced=torch.tensor([True, True]), server_ident=torch.tensor([2, 2]),
                        receiver_ident=torch.tensor([3, 3]),
                        returning=torch.tensor([False, False]))
    long = torch.as_tensor(strike_bias.error_bins()[0])
    assert [seen["bias"][k, 0][long].unique().tolist() for k in (0, 1)] == [[5.0], [1.0]]


def _depth_states(model, n=600, seed=0):
    """Receivers 2 and 3 against servers 4 and 5, `n` rally strikes each, half struck 0.3 m
    behind the baseline (band 2; long 20 %) and half 2.6 m behind (band 5; long 5 %): the
    record errs less from deep, whoever strikes."""
    rng = np.random.default_rng(seed)
    masks = strike_bias.error_bins()
    long_b, deep_in = np.flatnonzero(masks[0])[:6], np.flatnonzero(~masks[0])[-20:]
    behind = np.tile(np.repeat([0.3, 2.6], n // 2), 2)
    share = np.where(behind < 1.0, 0.20, 0.05)
    m = 2 * n
    depth = np.where(rng.random(m) < share, rng.choice(long_b, m), rng.choice(deep_in, m))
    bins = np.stack([depth, rng.choice(np.flatnonzero(~masks[1]), m), rng.integers(20, 40, m),
                     rng.integers(96, size=m)], -1)
    contact = np.zeros((m, 3))
    contact[:, 0] = -(BASE + behind)
    return HeadStates(torch.randn(m, model.cfg.d_model), torch.as_tensor(bins), np.arange(m),
                      np.zeros(m, dtype=np.int64), contact, np.ones(m, dtype=bool),
                      np.repeat([4, 5], n).astype(np.int64),
                      np.repeat([2, 3], n).astype(np.int64), shot=np.full(m, 3))


def _long_odds(model, st) -> torch.Tensor:
    long = torch.as_tensor(strike_bias.error_bins()[0])
    bias = model.strike_head_bias(torch.as_tensor(st.receiver_id),
                                  torch.ones(len(st), dtype=torch.bool),
                                  torch.zeros(len(st), dtype=torch.bool),
                                  torch.as_tensor(st.server_id), torch.as_tensor(st.shot),
                                  torch.as_tensor(st.contact_m[:, 0]))
    with torch.no_grad():
        return (model.strike_head.dim_logits(st.h, st.bins, 0, bias).softmax(-1) * long).sum(-1)


def test_the_depth_fit_alone_tilts_the_errors_by_depth_and_keeps_their_level():
    plain = with_strike_pressure(with_strike_return(with_strike_bias(small_model())))
    st = _depth_states(plain)
    returns = np.zeros(len(st), dtype=bool)
    fit_strike_pressure(plain, st, returns, rounds=4, prior_strikes=0.0)
    near = np.abs(st.contact_m[:, 0]) - BASE < 1.0
    before = _long_odds(plain, st)
    record = torch.as_tensor(strike_bias.error_bins()[0])[st.bins[:, 0]].float()
    # One row per player: both depths drawn alike, the level matched.
    assert float(before.mean()) == pytest.approx(float(record.mean()), abs=0.01)
    assert abs(float(before[near].mean()) - float(before[~near].mean())) < 0.03
    model = with_strike_depth(plain)
    kept = {k: getattr(model, k).clone() for k in ("strike_bias", "strike_pressure",
                                                   "strike_return")}
    table = fit_strike_pressure(model, st, returns, prior_strikes=0.0, depth_only=True)
    assert set(table["table"]) == {"depth"} and sorted(table["id"]) == [2, 5]
    for k, v in kept.items():
        assert torch.equal(getattr(model, k), v), k
    d = model.strike_depth
    assert float(d[2, 1, 0] - d[5, 1, 0]) > 1.0               # 20 % against 5 %: ~1.6 logits
    assert float(d[2, 1, 0]) > 0 > float(d[5, 1, 0])
    assert (d[[0, 1, 3, 4, 6]] == 0).all() and (d[:, 0] == 0).all()   # no strikes there
    after = _long_odds(model, st)
    assert float(after[near].mean()) - float(after[~near].mean()) > 0.08
    # Centred where the errors are drawn: the level is the other tables' to the digit.
    assert float(after.mean()) == pytest.approx(float(before.mean()), abs=1e-4)
    # Fitted in turn with the others instead, each band's share is the record's.
    both = with_strike_depth(with_strike_pressure(with_strike_return(with_strike_bias(
        small_model()))))
    fit_strike_pressure(both, st, returns, rounds=6, prior_strikes=0.0)
    got = _long_odds(both, st)
    for rows in (near, ~near):
        assert float(got[rows].mean()) == pytest.approx(float(record[rows].mean()), abs=0.015)
    with pytest.raises(ValueError, match="with_strike_depth"):
        fit_strike_pressure(plain, st, returns, depth_only=True)
    with pytest.raises(ValueError, match="one"):
        fit_strike_pressure(model, st, returns, depth_only=True, late_only=True)
