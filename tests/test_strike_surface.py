"""The hitters' surfaces table of the strike head's error shifts (`model.strike_surface`) and
its fit on top of the other tables (`train.strike_surface`)."""

import numpy as np
import pytest
import torch

from sportsngen.model import strike_bias
from sportsngen.model.config import ModelConfig
from sportsngen.train.head_fit import HeadStates
from sportsngen.train.strike_bias import with_strike_bias, with_strike_return
from sportsngen.train.strike_surface import fit_strike_surface, with_strike_surface
from tests.test_return_surface import long_odds_with, long_share_bins
from tests.test_strike_bias import _two_strikes_seen, small_model

LONG = torch.as_tensor(strike_bias.error_bins()[0])
HARD, CLAY = 0, 1
RALLY, RETURN = strike_bias.STROKE_RALLY, strike_bias.STROKE_RETURN


def _model():
    return with_strike_surface(with_strike_return(with_strike_bias(small_model())))


def test_the_hitters_row_of_the_surface_and_stroke_adds_on_every_strike():
    model = _model()
    assert model.strike_surface.shape == (model.cfg.n_ids, model.cfg.n_surfaces, 2, 3)
    assert (model.strike_surface == 0).all()
    model.strike_bias[3, 1, 0] = 1.0
    model.strike_return[3, 0] = 0.5
    model.strike_surface[3, CLAY, RETURN, 0] = 2.0
    model.strike_surface[3, CLAY, RALLY, 0] = -3.0
    model.strike_surface[3, HARD, RETURN, 0] = 7.0
    model.strike_surface[2, CLAY, RETURN, 0] = 40.0     # another hitter's row: never read here
    # Receiver 3: a return on clay, a later strike on clay, a return on hard.
    b = model.strike_head_bias(torch.tensor([3, 3, 3]), torch.ones(3, dtype=torch.bool),
                               torch.tensor([True, False, True]), torch.tensor([2] * 3),
                               serve=torch.tensor([0, 0, 1]),
                               surface=torch.tensor([CLAY, CLAY, HARD]))
    assert [b[i, 0][LONG].unique().item() for i in range(3)] == [3.5, -2.0, 8.5]
    assert (b[:, 1:] == 0).all()
    # Without the surface the table is not read.
    b = model.strike_head_bias(torch.tensor([3]), torch.tensor([True]), torch.tensor([True]),
                               torch.tensor([2]), serve=torch.tensor([0]))
    assert b[0, 0][LONG].unique().item() == 1.5
    with pytest.raises(ValueError, match="strike_bias=True"):
        ModelConfig(strike_head=True, strike_surface=True)


def test_a_rollouts_strike_reads_its_hitters_row_of_the_surface():
    model = _model()
    model.strike_surface[3, CLAY, RETURN, 0] = 4.0
    model.strike_surface[3, HARD, RETURN, 0] = 9.0
    model.strike_surface[2, CLAY, RALLY, 0] = -5.0
    seen, pos = _two_strikes_seen(model)
    for surface, want in ((CLAY, [4.0, -5.0]), (HARD, [9.0, 0.0])):
        model.place_strikes(torch.zeros(2, 3, 32), pos, torch.zeros(2, 3, 3), pos.clone(),
                            forced=torch.tensor([True, True]), serve=torch.tensor([0, 0]),
                            server_ident=torch.tensor([2, 2]),
                            receiver_ident=torch.tensor([3, 3]),
                            returning=torch.tensor([True, True]),
                            surface=torch.tensor([surface] * 2))
        # Row 0 is the receiver's return; row 1 the server's ball on his own end.
        assert [seen["bias"][i, 0][LONG].unique().item() for i in (0, 1)] == want


# Long shares by hitter, surface and stroke: hitter 3's returns err on hard and not on clay, his
# rally balls the other way round, so no one row per hitter (or per stroke) holds them.
SHARES = {(3, HARD, RETURN): 0.40, (3, CLAY, RETURN): 0.08, (3, HARD, RALLY): 0.06,
          (3, CLAY, RALLY): 0.30, (4, HARD, RETURN): 0.15, (4, CLAY, RETURN): 0.15}
OPPONENT = 2


def _strike_states(model, n=400, seed=0):
    bins = long_share_bins(np.random.default_rng(seed), SHARES.values(), n)
    hitter, surface, stroke = ([k[i] for k in SHARES for _ in range(n)] for i in range(3))
    m, is_return = len(hitter), [s == RETURN for s in stroke]
    hitter, recv = np.array(hitter, dtype=np.int64), np.array(is_return)
    # Every row its own rally: a receiver's strike is that rally's return, a server's a rally
    # ball.
    return HeadStates(torch.randn(m, model.cfg.d_model), torch.as_tensor(bins), np.arange(m),
                      np.zeros(m, dtype=np.int64), np.zeros((m, 3)), recv,
                      np.where(recv, OPPONENT, hitter), np.where(recv, hitter, OPPONENT),
                      surface=np.array(surface, dtype=np.int64))


def _long_odds(model, st, with_surface=True):
    recv = torch.as_tensor(st.receiver)
    bias = model.strike_head_bias(torch.as_tensor(st.hitter_id()), recv, recv,
                                  torch.as_tensor(st.opponent_id()),
                                  serve=torch.as_tensor(st.serve),
                                  surface=torch.as_tensor(st.surface) if with_surface else None)
    return long_odds_with(model, st, bias)


def test_the_fit_finds_each_hitters_share_by_surface_and_stroke():
    model = _model()
    st = _strike_states(model)
    model.strike_surface[3, HARD, RETURN] = 5.0     # refitted from zero
    # Fitted on top of the other tables as they are.
    model.strike_bias[3, 0, 0] = 1.0
    model.strike_return[4, 0] = -1.0
    model.strike_surface[5, CLAY, RALLY] = 5.0      # a hitter without strikes: zeroed
    table = fit_strike_surface(model, st, prior_strikes=0.0)
    assert sorted(zip(table["id"], table["surface"], table["stroke"], table["n"])) == [
        (3, HARD, "rally", 400), (3, HARD, "return", 400), (3, CLAY, "rally", 400),
        (3, CLAY, "return", 400), (4, HARD, "return", 400), (4, CLAY, "return", 400)]
    odds = _long_odds(model, st)
    for k, p in enumerate(SHARES.values()):
        assert float(odds[k * 400:(k + 1) * 400].mean()) == pytest.approx(p, abs=0.01)
    assert (model.strike_surface[5] == 0).all()
    assert model.strike_bias[3, 0, 0] == 1.0 and model.strike_return[4, 0] == -1.0
    # Hard's returns err more than clay's for hitter 3, his rally balls less.
    assert model.strike_surface[3, HARD, RETURN, 0] > model.strike_surface[3, CLAY, RETURN, 0]
    assert model.strike_surface[3, HARD, RALLY, 0] < model.strike_surface[3, CLAY, RALLY, 0]


def test_the_fit_keeps_the_prior_skips_small_cells_and_refuses_bad_input():
    model = _model()
    st = _strike_states(model, n=60)
    before = _long_odds(model, st)
    table = fit_strike_surface(model, st, prior_strikes=60.0, min_strikes=61)
    assert table.empty and (model.strike_surface == 0).all()
    # With a prior of as many pseudo-strikes as the cell holds, the odds go half way.
    fit_strike_surface(model, st, prior_strikes=60.0)
    after = _long_odds(model, st)
    head, record = float(before[:60].mean()), SHARES[(3, HARD, RETURN)]
    assert float(after[:60].mean()) == pytest.approx((head + record) / 2, abs=0.02)
    with pytest.raises(ValueError, match="with_strike_surface"):
        fit_strike_surface(with_strike_return(with_strike_bias(small_model())), st)
    with pytest.raises(ValueError, match="min_strikes"):
        fit_strike_surface(model, st, min_strikes=0)
    st.surface = None
    with pytest.raises(ValueError, match="no surfaces"):
        fit_strike_surface(model, st)
