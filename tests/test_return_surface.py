"""The surfaces' table of the returns' error shifts (`model.strike_return_surface`) and its fit
in turn with the receivers' returns table (`train.return_surface`)."""

import numpy as np
import pytest
import torch

from sportsngen.model import strike_bias
from sportsngen.model.config import ModelConfig
from sportsngen.train.head_fit import HeadStates
from sportsngen.train.return_surface import fit_return_surface, with_return_surface
from sportsngen.train.strike_bias import fit_strike_return, with_strike_bias, with_strike_return
from tests.test_strike_bias import _two_strikes_seen, small_model

LONG = torch.as_tensor(strike_bias.error_bins()[0])
HARD, CLAY = 0, 1


def _model():
    return with_return_surface(with_strike_return(with_strike_bias(small_model())))


def test_the_row_of_the_surface_and_serve_adds_on_the_returns_only():
    model = _model()
    assert model.strike_return_surface.shape == (model.cfg.n_surfaces, 2, 3)
    assert (model.strike_return_surface == 0).all()
    model.strike_bias[3, 1, 0] = 1.0
    model.strike_return[3, 0] = 0.5
    model.strike_return_surface[CLAY, 0, 0] = 2.0
    model.strike_return_surface[CLAY, 1, 0] = -3.0
    model.strike_return_surface[HARD, 0, 0] = 7.0
    # Receiver 3 on clay: a first serve's return, a second's, a later strike; a return on hard.
    b = model.strike_head_bias(torch.tensor([3, 3, 3, 3]), torch.ones(4, dtype=torch.bool),
                               torch.tensor([True, True, False, True]), torch.tensor([2] * 4),
                               serve=torch.tensor([0, 1, 0, 0]),
                               surface=torch.tensor([CLAY, CLAY, CLAY, HARD]))
    assert [b[i, 0][LONG].unique().item() for i in range(4)] == [3.5, -1.5, 1.0, 8.5]
    assert (b[:, 1:] == 0).all()
    # Without the surface the table is not read.
    b = model.strike_head_bias(torch.tensor([3]), torch.tensor([True]), torch.tensor([True]),
                               torch.tensor([2]), serve=torch.tensor([0]))
    assert b[0, 0][LONG].unique().item() == 1.5
    with pytest.raises(ValueError, match="strike_return=True"):
        ModelConfig(strike_head=True, strike_bias=True, strike_return_surface=True)


def test_a_rollouts_return_reads_the_row_of_its_surface_and_serve():
    model = _model()
    model.strike_return_surface[CLAY, 1, 0] = 4.0
    model.strike_return_surface[HARD, 1, 0] = 9.0
    seen, pos = _two_strikes_seen(model)
    for serve, surface, want in ((1, CLAY, [4.0, 0.0]), (1, HARD, [9.0, 0.0]),
                                 (0, CLAY, [0.0, 0.0])):
        model.place_strikes(torch.zeros(2, 3, 32), pos, torch.zeros(2, 3, 3), pos.clone(),
                            forced=torch.tensor([True, True]), serve=torch.tensor([serve] * 2),
                            server_ident=torch.tensor([2, 2]),
                            receiver_ident=torch.tensor([3, 3]),
                            returning=torch.tensor([True, True]),
                            surface=torch.tensor([surface] * 2))
        # Row 0 is the receiver's return; row 1 a ball on the server's end.
        assert [seen["bias"][i, 0][LONG].unique().item() for i in (0, 1)] == want


# Long shares of the returns of receivers 2 and 3 by surface and serve: the surface's effect
# the same in log-odds for both receivers, and smaller on second serves.
SHARES = {(2, HARD, 0): 0.25, (2, CLAY, 0): 0.05, (3, HARD, 0): 0.40, (3, CLAY, 0): 0.10,
          (2, HARD, 1): 0.12, (2, CLAY, 1): 0.05, (3, HARD, 1): 0.22, (3, CLAY, 1): 0.10}


def long_share_bins(rng: np.random.Generator, shares, n: int) -> np.ndarray:
    """(len(shares) * n, 4) strike bins, `n` rows a share in turn, exactly that share of each
    block's depth bins long (the blocks' records are the shares themselves), laterals in the
    court, net heights clear."""
    masks = strike_bias.error_bins()
    long_b, deep_in = np.flatnonzero(masks[0])[:6], np.flatnonzero(~masks[0])[-20:]
    lat_in = np.flatnonzero(~masks[1])
    depth = []
    for p in shares:
        long = rng.permutation(n) < round(p * n)
        depth.append(np.where(long, rng.choice(long_b, n), rng.choice(deep_in, n)))
    m = len(shares) * n
    return np.stack([np.concatenate(depth), rng.choice(lat_in, m), rng.integers(20, 40, m),
                     rng.integers(96, size=m)], -1)


def _return_states(model, n=400, seed=0):
    bins = long_share_bins(np.random.default_rng(seed), SHARES.values(), n)
    recv, surface, serve = ([k[i] for k in SHARES for _ in range(n)] for i in range(3))
    m = len(recv)
    return HeadStates(torch.randn(m, model.cfg.d_model), torch.as_tensor(bins), np.arange(m),
                      np.array(serve, dtype=np.int64), np.zeros((m, 3)), np.ones(m, dtype=bool),
                      np.full(m, 4, dtype=np.int64), np.array(recv, dtype=np.int64),
                      surface=np.array(surface, dtype=np.int64))


def long_odds_with(model, st, bias: torch.Tensor) -> torch.Tensor:
    """The strike head's odds of a long ball at each of `st`'s states with the shifts `bias`."""
    with torch.no_grad():
        return (model.strike_head.dim_logits(st.h, st.bins, 0, bias).softmax(-1) * LONG).sum(-1)


def _long_odds(model, st, with_surface=True):
    bias = model.strike_head_bias(torch.as_tensor(st.receiver_id),
                                  torch.ones(len(st), dtype=torch.bool),
                                  torch.ones(len(st), dtype=torch.bool),
                                  torch.as_tensor(st.server_id), serve=torch.as_tensor(st.serve),
                                  surface=torch.as_tensor(st.surface) if with_surface else None)
    return long_odds_with(model, st, bias)


def test_the_fit_finds_each_surfaces_share_of_the_returns_errors_by_the_serve():
    model = _model()
    st = _return_states(model)
    returns = np.ones(len(st), dtype=bool)
    table = fit_return_surface(model, st, returns, rounds=8, prior_strikes=0.0)
    assert set(table["table"]) == {"receiver", "surface"}
    assert len(table) == 2 + 4            # two receivers; two surfaces by two serves
    odds = _long_odds(model, st)
    for k, p in enumerate(SHARES.values()):
        assert float(odds[k * 400:(k + 1) * 400].mean()) == pytest.approx(p, abs=0.02)
    # Hard's first serves draw more long returns than its second.
    assert model.strike_return_surface[HARD, 0, 0] - model.strike_return_surface[HARD, 1, 0] > 0.5
    # The receivers' rows alone (`fit_strike_return`): one share per receiver, the surfaces'
    # spread lost.
    alone = with_strike_return(with_strike_bias(small_model()))
    alone.load_state_dict({k: v for k, v in model.state_dict().items()
                           if k in alone.state_dict()})
    fit_strike_return(alone, st, returns, prior_strikes=0.0, rally=False)
    odds = _long_odds(alone, st, with_surface=False)
    assert abs(float(odds[:400].mean()) - 0.25) > 0.05


def test_the_fit_reads_only_the_receivers_returns_and_refuses_bad_input():
    model = _model()
    st = _return_states(model, n=100)
    returns = np.zeros(len(st), dtype=bool)
    returns[:400] = True                                   # the first serves' returns
    st.receiver[300:400] = False             # receiver 3 on clay: the server strikes
    table = fit_return_surface(model, st, returns, prior_strikes=0.0)
    assert sorted(zip(table["table"], table["id"], table["serve"], table["n"])) == [
        ("receiver", 2, -1, 200), ("receiver", 3, -1, 100), ("surface", HARD, 0, 200),
        ("surface", CLAY, 0, 100)]
    assert (model.strike_return_surface[:, 1] == 0).all()
    with pytest.raises(ValueError, match="rows"):
        fit_return_surface(model, st, returns[:10])
    with pytest.raises(ValueError, match="no recorded return"):
        fit_return_surface(model, st, np.zeros(len(st), dtype=bool))
    with pytest.raises(ValueError, match="with_return_surface"):
        fit_return_surface(with_strike_return(with_strike_bias(small_model())), st, returns)
    st.surface = None
    with pytest.raises(ValueError, match="no surfaces"):
        fit_return_surface(model, st, returns)


def test_states_keep_their_surfaces_when_taken_and_joined():
    st = _return_states(_model(), n=10)
    keep = np.zeros(len(st), dtype=bool)
    keep[5:25] = True
    part = st.take(keep)
    assert part.surface.tolist() == st.surface[5:25].tolist()
    both = HeadStates.concat([part, st])
    assert both.surface.tolist() == part.surface.tolist() + st.surface.tolist()
    st.surface = None
    assert HeadStates.concat([part, st]).surface is None
