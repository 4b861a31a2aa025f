"""The late strikes' table and the player's rally rows moved by the model's own rollouts
(`sportsngen.train.rollout_tables`)."""

import numpy as np
import pandas as pd
import pytest
import torch

from sportsngen.data.tokens import Vocab
from sportsngen.errors import ArgumentError
from sportsngen.model.inputs import N_SPECIAL_IDS
from sportsngen.train.rollout_tables import (
    RALLY_STAGES,
    add_rollout_late_shift,
    add_rollout_rally_shift,
    rollout_error_gaps,
)
from sportsngen.train.serve_bias import MAX_SHIFT
from sportsngen.train.strike_bias import (
    with_strike_bias,
    with_strike_late,
    with_strike_pressure,
    with_strike_return,
)
from tests.test_strike_bias import small_model


def _endings(rows: list[tuple[str, str, str, int, float]]) -> pd.DataFrame:
    """A `strike_endings` table from (hitter, role, stage, n, error) rows."""
    frame = pd.DataFrame(rows, columns=["hitter", "role", "stage", "n", "error"])
    return frame.set_index(["hitter", "role", "stage"]).assign(winner=0.0)


def _logit(p: float) -> float:
    return float(np.log(p / (1 - p)))


def test_the_gaps_are_the_truths_log_odds_less_the_rollouts_pooled_by_the_rollouts_strikes():
    sim1 = _endings([("A", "receiver", "shots 5+", 100, 0.25), ("A", "receiver", "return", 50, 0.5),
                     ("B", "server", "shots 5+", 40, 0.1)])
    truth1 = _endings([("A", "receiver", "shots 5+", 1000, 0.20), ("B", "server", "shots 5+",
                                                                    900, 0.1)])
    sim2 = _endings([("A", "receiver", "shots 5+", 300, 0.10)])
    truth2 = _endings([("A", "receiver", "shots 5+", 2000, 0.15),
                       ("C", "server", "shots 5+", 500, 0.3)])      # no rollouts of C: left out
    got = rollout_error_gaps([(sim1, truth1), (sim2, truth2)])
    assert list(got.index) == [("A", "receiver"), ("B", "server")]
    a = got.loc[("A", "receiver")]
    assert a["n"] == 400
    assert a["error_sim"] == pytest.approx((100 * 0.25 + 300 * 0.10) / 400)
    assert a["error_truth"] == pytest.approx((100 * 0.20 + 300 * 0.15) / 400)
    want = (100 * (_logit(0.20) - _logit(0.25)) + 300 * (_logit(0.15) - _logit(0.10))) / 400
    assert a["gap"] == pytest.approx(want)
    assert got.loc[("B", "server"), "gap"] == pytest.approx(0.0)
    # Another stage is read the same way; the return's lone cell has no truth: nothing.
    assert rollout_error_gaps([(sim1, truth1)], stage="return").empty
    # A share of 0 is kept off by half a strike.
    zero = rollout_error_gaps([(_endings([("A", "server", "shots 5+", 50, 0.0)]),
                                _endings([("A", "server", "shots 5+", 50, 0.1)]))])
    assert zero["gap"].iloc[0] == pytest.approx(_logit(0.1) - _logit(0.01))
    with pytest.raises(ValueError, match="no .rollouts, truth. pair"):
        rollout_error_gaps([])
    with pytest.raises(ValueError, match="strike_endings"):
        rollout_error_gaps([(sim1, truth1.drop(columns="error"))])


def test_the_step_is_the_gap_shrunk_by_the_prior_on_all_three_kinds():
    vocab = Vocab(players=("A", "B", "C", "D"))
    model = with_strike_late(with_strike_pressure(with_strike_return(with_strike_bias_model(
        vocab))))
    model.strike_late[N_SPECIAL_IDS + 1, 0] = torch.tensor([0.5, 0.0, -0.5])
    gaps = pd.DataFrame({"hitter": ["A", "B", "C"], "role": ["receiver", "server", "server"],
                         "n": [600, 200, 100], "gap": [-0.4, 1.0, 50.0]}).set_index(
        ["hitter", "role"])
    before = model.strike_late.clone()
    got = add_rollout_late_shift(model, vocab, gaps, prior_strikes=200.0)
    a, b, c = (N_SPECIAL_IDS + k for k in range(3))
    torch.testing.assert_close(model.strike_late[a, 1], torch.full((3,), -0.4 * 600 / 800))
    torch.testing.assert_close(model.strike_late[b, 0], torch.tensor([1.0, 0.5, 0.0]))
    torch.testing.assert_close(model.strike_late[c, 0], torch.full((3,), MAX_SHIFT))  # bounded
    assert got["step"].tolist() == pytest.approx([-0.3, 0.5, 50.0 / 3])
    # Every other cell as it was.
    keep = torch.ones_like(before, dtype=torch.bool)
    keep[a, 1] = keep[b, 0] = keep[c, 0] = False
    assert torch.equal(model.strike_late[keep], before[keep])
    with pytest.raises(ArgumentError, match="unknown player"):
        add_rollout_late_shift(model, vocab, gaps.rename(index={"A": "Nobody"}))
    after = model.strike_late.clone()
    with pytest.raises(ValueError, match="role"):
        add_rollout_late_shift(model, vocab, gaps.rename(index={"server": "umpire"}))
    assert torch.equal(model.strike_late, after)          # A's row, checked first, not moved
    with pytest.raises(ValueError, match="with_strike_late"):
        add_rollout_late_shift(with_strike_bias_model(vocab), vocab, gaps)


def with_strike_bias_model(vocab: Vocab):
    return with_strike_bias(small_model(n_ids=vocab.n_ids))


def test_several_stages_are_pooled_by_their_strikes():
    sim = _endings([("A", "receiver", "shots 2-4", 100, 0.30), ("A", "receiver", "shots 5+", 300,
                                                                  0.10),
                    ("A", "receiver", "return", 400, 0.5)])
    truth = _endings([("A", "receiver", "shots 2-4", 1000, 0.20),
                      ("A", "receiver", "shots 5+", 3000, 0.20)])
    got = rollout_error_gaps([(sim, truth)], RALLY_STAGES).loc[("A", "receiver")]
    assert got["n"] == 400                                   # the return left out
    assert got["error_sim"] == pytest.approx(0.15)
    assert got["gap"] == pytest.approx(_logit(0.20) - _logit(0.15))


def test_the_rally_shift_moves_the_players_rows_and_keeps_the_receivers_returns():
    vocab = Vocab(players=("A", "B", "C"))
    model = with_strike_return(with_strike_bias_model(vocab))
    a, b, c = (N_SPECIAL_IDS + k for k in range(3))
    model.strike_bias[c, 1] = torch.tensor([MAX_SHIFT - 0.1, 0.0, 0.0])
    model.strike_return[a] = torch.tensor([0.2, 0.0, -0.1])
    gaps = pd.DataFrame({"hitter": ["A", "B", "C"], "role": ["receiver", "server", "receiver"],
                         "n": [600, 200, 200], "gap": [-0.4, 1.0, 0.4]}).set_index(
        ["hitter", "role"])
    bias, ret = model.strike_bias.clone(), model.strike_return.clone()
    got = add_rollout_rally_shift(model, vocab, gaps, prior_strikes=200.0)
    assert got["step"].tolist() == pytest.approx([-0.3, 0.5, 0.2])
    torch.testing.assert_close(model.strike_bias[a, 1], torch.full((3,), -0.3))
    torch.testing.assert_close(model.strike_bias[b, 0], torch.full((3,), 0.5))
    # A receiver's return draws as before: its row sum (player's + returns') unchanged.
    torch.testing.assert_close(model.strike_bias[a, 1] + model.strike_return[a],
                               bias[a, 1] + ret[a])
    # At the bound the cell moved less, and the return's row only by what it moved.
    torch.testing.assert_close(model.strike_bias[c, 1],
                               torch.tensor([MAX_SHIFT, 0.2, 0.2]))
    torch.testing.assert_close(model.strike_return[c], torch.tensor([-0.1, -0.2, -0.2]))
    torch.testing.assert_close(model.strike_return[b], ret[b])   # a server's: untouched
    keep = torch.ones_like(bias, dtype=torch.bool)
    keep[a, 1] = keep[b, 0] = keep[c, 1] = False
    assert torch.equal(model.strike_bias[keep], bias[keep])
    with pytest.raises(ValueError, match="cfg.strike_return"):
        add_rollout_rally_shift(with_strike_bias_model(vocab), vocab, gaps)
    with pytest.raises(ValueError, match="prior_strikes"):
        add_rollout_rally_shift(model, vocab, gaps, prior_strikes=-1)


def test_the_second_serves_shift_moves_only_that_table():
    from sportsngen.train.rollout_tables import add_rollout_second_shift
    from sportsngen.train.strike_bias import with_strike_second

    vocab = Vocab(players=("A", "B"))
    model = with_strike_second(with_strike_return(with_strike_bias_model(vocab)))
    a = N_SPECIAL_IDS
    bias, ret = model.strike_bias.clone(), model.strike_return.clone()
    gaps = pd.DataFrame({"hitter": ["A"], "role": ["receiver"], "n": [600],
                         "gap": [-0.4]}).set_index(["hitter", "role"])
    got = add_rollout_second_shift(model, vocab, gaps, prior_strikes=200.0)
    assert got["step"].tolist() == pytest.approx([-0.3])
    torch.testing.assert_close(model.strike_second[a, 1], torch.full((3,), -0.3))
    assert float(model.strike_second.abs().sum()) == pytest.approx(0.9)
    assert torch.equal(model.strike_bias, bias) and torch.equal(model.strike_return, ret)
    with pytest.raises(ValueError, match="cfg.strike_second"):
        add_rollout_second_shift(with_strike_bias_model(vocab), vocab, gaps)
    with pytest.raises(ValueError, match="strike_second adds to the player's table"):
        small_model(n_ids=vocab.n_ids, strike_second=True)


def test_the_second_serves_row_shifts_rally_strikes_of_second_serve_points_only():
    from sportsngen.model import strike_bias as table
    from sportsngen.train.strike_bias import with_strike_second

    vocab = Vocab(players=("A", "B"))
    model = with_strike_second(with_strike_bias_model(vocab))
    a = N_SPECIAL_IDS
    model.strike_second[a, 1] = torch.tensor([0.5, -0.2, 0.1])
    hitter = torch.full((4,), a)
    receiver = torch.ones(4, dtype=torch.bool)
    returning = torch.tensor([False, False, True, True])
    serve = torch.tensor([0, 1, 0, 1])              # 0 first, 1 second
    with_row = model.strike_head_bias(hitter, receiver, returning, serve=serve)
    model.strike_second.zero_()
    without = model.strike_head_bias(hitter, receiver, returning, serve=serve)
    moved = (with_row - without).abs().sum(dim=(1, 2))
    assert moved[1] > 0 and moved[[0, 2, 3]].tolist() == [0.0, 0.0, 0.0]
    errs = torch.as_tensor(table.error_bins()[table.LONG], dtype=torch.bool)
    diff = with_row[1, 0] - without[1, 0]      # the depth dimension: long bins by 0.5
    assert torch.allclose(diff[errs], torch.tensor(0.5)) and (diff[~errs] == 0).all()
    # Without the serve given, the table is not read.
    model.strike_second[a, 1] = torch.tensor([0.5, -0.2, 0.1])
    assert torch.equal(model.strike_head_bias(hitter, receiver, returning), without)
