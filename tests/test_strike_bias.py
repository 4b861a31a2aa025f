"""The strike head's per-hitter shifts of its odds of a rally ball long, wide or into the net
(`sportsngen.model.strike_bias`, `sportsngen.train.strike_bias`)."""

import numpy as np
import pytest
import torch

from sportsngen.eval.strike_draws import strike_errors
from sportsngen.model import strike, strike_bias
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.strike_heads import BALL
from sportsngen.train.head_fit import HeadStates
from sportsngen.train.serve_bias import MAX_SHIFT
from sportsngen.train.strike_bias import (
    error_shares,
    fit_strike_bias,
    fit_strike_pressure,
    fit_strike_return,
    fit_strike_shape,
    fit_strike_width,
    with_strike_bias,
    with_strike_late,
    with_strike_pressure,
    with_strike_return,
    with_strike_shape,
    with_strike_width,
)
from tests.test_serve_bias import small_model as serve_small_model


def small_model(**kw) -> SportsNGEN:
    return serve_small_model(**{"strike_head": True, **kw})


def _centres(dim: int) -> np.ndarray:
    e = strike.strike_edges()[dim]
    return 0.5 * (e[1:] + e[:-1])


def test_the_error_bins_are_those_the_error_reading_calls_errors():
    bins = strike_bias.error_bins()
    assert bins.shape == (strike_bias.N_KINDS, strike.STRIKE_BINS)
    n = strike.STRIKE_BINS
    # Depth: long exactly where the reading says so, the rest of the ball well in.
    depth = np.stack([_centres(0), np.zeros(n), np.full(n, 2.0), np.zeros(n)], -1)
    assert bins[strike_bias.LONG].tolist() == strike_errors(depth).tolist()
    assert bins[strike_bias.LONG].sum() == 48
    lateral = np.stack([np.full(n, 6.0), _centres(1), np.full(n, 2.0), np.zeros(n)], -1)
    assert bins[strike_bias.WIDE].tolist() == strike_errors(lateral).tolist()
    assert bins[strike_bias.WIDE].sum() == 40
    # Net: a bin marked is in the net wherever the ball crosses; the first bin above is not
    # wholly, since at the centre it clears.
    net = bins[strike_bias.NET]
    for y in (0.0, 3.0, 4.1):
        over = np.stack([np.full(n, 6.0), np.full(n, y), _centres(2), np.zeros(n)], -1)
        assert strike_errors(over)[net].all()
    first_above = int(np.flatnonzero(net)[-1]) + 1
    e = strike.strike_edges()[2]
    assert e[first_above] < 0.914 < e[first_above + 1]
    assert net[:first_above].all() and not net[first_above:].any()


def test_the_table_is_added_at_zero_and_read_per_hitter_and_role():
    plain = small_model()
    assert plain.strike_bias is None
    assert plain.strike_head_bias(torch.tensor([2]), torch.tensor([True])) is None
    model = with_strike_bias(plain)
    assert model.cfg.strike_bias and model.strike_bias.shape == (6, 2, 3)
    assert (model.strike_bias == 0).all() and with_strike_bias(model) is model
    model.strike_bias[3, 1] = torch.tensor([1.0, -2.0, 0.5])
    b = model.strike_head_bias(torch.tensor([3, 3, 4]), torch.tensor([True, False, True]))
    assert b.shape == (3, 4, strike.STRIKE_BINS)
    masks = torch.as_tensor(strike_bias.error_bins())
    for dim, value in ((0, 1.0), (1, -2.0), (2, 0.5)):
        assert (b[0, dim][masks[dim]] == value).all() and (b[0, dim][~masks[dim]] == 0).all()
    assert (b[0, 3] == 0).all() and (b[1] == 0).all() and (b[2] == 0).all()
    again = SportsNGEN(model.cfg)
    again.load_state_dict(model.state_dict())
    torch.testing.assert_close(again.strike_bias, model.strike_bias)
    with pytest.raises(ValueError, match="strike_head"):
        ModelConfig(strike_bias=True, strike_head=False)


def _states(model, n_per=(300, 300, 60), seed=0):
    """Rally strikes of hitter 2 as server (long 30 % of the time), hitter 2 as receiver (long
    5 %) and hitter 3 as receiver (wide 25 %), net-height bins all clear of the net."""
    rng = np.random.default_rng(seed)
    n = sum(n_per)
    cell = np.repeat([0, 1, 2], n_per)
    masks = strike_bias.error_bins()
    long_b, deep_in = np.flatnonzero(masks[0])[:6], np.flatnonzero(~masks[0])[-20:]
    wide_b, lat_in = np.flatnonzero(masks[1]), np.flatnonzero(~masks[1])
    long_share = np.array([0.3, 0.05, 0.0])[cell]
    wide_share = np.array([0.0, 0.0, 0.25])[cell]
    depth = np.where(rng.random(n) < long_share, rng.choice(long_b, n), rng.choice(deep_in, n))
    lateral = np.where(rng.random(n) < wide_share, rng.choice(wide_b, n), rng.choice(lat_in, n))
    bins = np.stack([depth, lateral, rng.integers(20, 40, n), rng.integers(96, size=n)], -1)
    receiver = cell > 0
    server_id = np.where(cell == 2, 4, np.where(cell == 0, 2, 5))
    receiver_id = np.where(cell == 2, 3, np.where(cell == 1, 2, 5))
    return HeadStates(torch.randn(n, model.cfg.d_model), torch.as_tensor(bins), np.arange(n),
                      np.zeros(n, dtype=np.int64), np.zeros((n, 3)), receiver,
                      server_id.astype(np.int64), receiver_id.astype(np.int64))


def test_the_hitter_is_the_receiver_on_his_end_else_the_server():
    model = small_model()
    st = _states(model)
    assert st.hitter_id()[:300].tolist() == [2] * 300
    assert st.hitter_id()[300:600].tolist() == [2] * 300
    assert st.hitter_id()[600:].tolist() == [3] * 60
    # Whom each answers: the other player of the rally.
    assert st.opponent_id()[:300].tolist() == [5] * 300
    assert st.opponent_id()[300:600].tolist() == [5] * 300
    assert st.opponent_id()[600:].tolist() == [4] * 60
    both = HeadStates.concat([st, st])
    assert both.receiver_id is not None and len(both.receiver_id) == 2 * len(st)
    st.receiver_id = None
    assert HeadStates.concat([st, st]).receiver_id is None
    with pytest.raises(ValueError, match="receivers' identities"):
        st.hitter_id()
    with pytest.raises(ValueError, match="receivers' identities"):
        st.opponent_id()


def test_the_fit_matches_each_hitters_record_by_role_pulled_toward_the_head():
    model = with_strike_bias(small_model())
    st = _states(model)
    table = fit_strike_bias(model, st, prior_strikes=0.0, min_strikes=50)
    table = table.set_index(["hitter_id", "receiver"])
    assert sorted(table.index) == [(2, False), (2, True), (3, True)]
    for key in table.index:
        for kind in ("long", "wide", "net"):
            r = table.loc[key]
            if r[f"{kind}_record"] > 0:
                assert r[f"{kind}_after"] == pytest.approx(r[f"{kind}_record"], abs=1e-4)
            else:       # a share of 0 lies beyond any shift: the bound, the odds pushed down
                assert r[f"{kind}_shift"] == pytest.approx(-MAX_SHIFT, abs=1e-6)
                assert r[f"{kind}_after"] < r[f"{kind}_head"]
    assert table.loc[(2, False), "long_record"] == pytest.approx(
        np.mean(strike_bias.error_bins()[0][st.bins[:300, 0].numpy()]))
    assert table.loc[(2, False), "long_shift"] > table.loc[(2, True), "long_shift"]
    assert table.loc[(3, True), "wide_shift"] > table.loc[(2, True), "wide_shift"]
    assert table.loc[(2, False), "net_record"] == 0.0
    # Each shift sits in its hitter's and role's cell only.
    assert model.strike_bias[2, 0, strike_bias.LONG] == pytest.approx(
        table.loc[(2, False), "long_shift"])
    assert (model.strike_bias[[0, 1, 4, 5]] == 0).all() and (model.strike_bias[3, 0] == 0).all()
    # Pseudo-strikes pull the target toward the head, the more the fewer strikes a cell has.
    pulled = fit_strike_bias(model, st, prior_strikes=200.0,
                             min_strikes=50).set_index(["hitter_id", "receiver"])
    for key, n in (((2, False), 300), ((3, True), 60)):
        w = n / (n + 200.0)
        r = pulled.loc[key]
        assert r["wide_target"] == pytest.approx(w * r["wide_record"] + (1 - w) * r["wide_head"])
    # Too few strikes: left at zero.
    fresh = with_strike_bias(small_model())
    assert (3, True) not in set(map(tuple, fit_strike_bias(
        fresh, st, min_strikes=100)[["hitter_id", "receiver"]].itertuples(index=False)))
    assert (fresh.strike_bias[3] == 0).all()
    # The combined error share: 1 - (1 - long)(1 - wide)(1 - net).
    shares = error_shares(table.reset_index())
    r = table.loc[(3, True)]
    assert shares["error_record"].iloc[2] == pytest.approx(
        1 - (1 - r["long_record"]) * (1 - r["wide_record"]) * (1 - r["net_record"]))
    with pytest.raises(ValueError, match="with_strike_bias"):
        fit_strike_bias(small_model(), st)


def test_the_fitted_model_draws_each_hitters_long_share():
    model = with_strike_bias(small_model())
    st = _states(model, n_per=(400, 400, 0), seed=1)
    fit_strike_bias(model, st, prior_strikes=0.0)
    bias = model.strike_head_bias(torch.as_tensor(st.hitter_id()), torch.as_tensor(st.receiver))
    long = strike_bias.error_bins()[0]
    draws = torch.stack([model.strike_head.sample(st.h, 1.0, torch.Generator().manual_seed(k),
                                                  dim_bias=bias) for k in range(10)])
    got = long[draws[..., 0].numpy()]
    assert got[:, :400].mean() == pytest.approx(0.3, abs=0.03)
    assert got[:, 400:].mean() == pytest.approx(0.05, abs=0.02)


def _two_strikes_seen(model) -> tuple[dict, torch.Tensor]:
    """`model`'s strike head made to record the shifts it is handed (`seen["bias"]`), and two
    frames: the server on the +x end, the receiver on the -x end, the ball at the receiver's
    (row 0) and at the server's (row 1)."""
    seen = {}

    def sample(h, top_p, generator, dim_bias=None):
        seen["bias"] = dim_bias
        return torch.full((len(h), 4), 40, dtype=torch.long)

    model.strike_head.sample = sample
    pos = torch.zeros(2, 3, 3)
    pos[:, 0, 0] = 12.0
    pos[:, 1, 0] = -12.0
    pos[0, BALL] = torch.tensor([-11.0, 0.0, 1.0])
    pos[1, BALL] = torch.tensor([11.0, 0.0, 1.0])
    return seen, pos


def test_a_rollouts_strike_reads_the_hitters_row():
    """`SportsNGEN.place_strikes` hands the strike head the row of whoever strikes: the
    receiver for a ball on his end, the server for one on the server's."""
    model = with_strike_bias(small_model())
    model.strike_bias[2] = torch.tensor([[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    model.strike_bias[3] = torch.tensor([[3.0, 0.0, 0.0], [4.0, 0.0, 0.0]])
    seen, pos = _two_strikes_seen(model)
    vel = torch.zeros(2, 3, 3)
    model.place_strikes(torch.zeros(2, 3, 32), pos, vel, pos.clone(),
                        forced=torch.tensor([True, True]), server_ident=torch.tensor([2, 2]),
                        receiver_ident=torch.tensor([3, 3]))
    long = torch.as_tensor(strike_bias.error_bins()[0])
    assert seen["bias"][0, 0][long].unique().tolist() == [4.0]      # receiver 3, receiving
    assert seen["bias"][1, 0][long].unique().tolist() == [1.0]      # server 2, serving
    seen.clear()
    model.place_strikes(torch.zeros(2, 3, 32), pos, vel, pos.clone(),
                        forced=torch.tensor([True, True]), server_ident=torch.tensor([2, 2]))
    assert seen["bias"] is None               # no receiver given: the head as it is


def test_the_returns_table_adds_to_the_receivers_row_on_his_returns_only():
    model = with_strike_return(with_strike_bias(small_model()))
    assert model.strike_return.shape == (6, 3) and (model.strike_return == 0).all()
    model.strike_bias[3, 1] = torch.tensor([1.0, 0.0, 0.0])
    model.strike_return[3] = torch.tensor([0.5, -1.0, 0.0])
    b = model.strike_head_bias(torch.tensor([3, 3]), torch.tensor([True, True]),
                               torch.tensor([True, False]))
    masks = torch.as_tensor(strike_bias.error_bins())
    assert b[0, 0][masks[0]].unique().tolist() == [1.5]       # the return: both rows
    assert b[0, 1][masks[1]].unique().tolist() == [-1.0]
    assert b[1, 0][masks[0]].unique().tolist() == [1.0]       # a later strike: his row alone
    assert (b[1, 1] == 0).all()
    # Not told which are returns: none is.
    torch.testing.assert_close(model.strike_head_bias(torch.tensor([3]), torch.tensor([True])),
                               b[1:])
    with pytest.raises(ValueError, match="strike_bias"):
        ModelConfig(strike_head=True, strike_return=True)


def test_a_rallys_first_strike_is_its_return_where_the_receiver_struck_it():
    model = small_model()
    st = _states(model, n_per=(3, 3, 0))
    # Rallies 7 (server's strike first: its return was not read), 8 (return, server, receiver)
    # and 9 (the return alone); rally 7 again later is another rally's run.
    st.rally_id = np.array([7, 7, 8, 8, 8, 9])
    st.receiver = np.array([False, True, True, False, True, True])
    assert st.returns().tolist() == [False, False, True, False, False, True]


def test_the_returns_fit_splits_each_receivers_record():
    model = with_strike_bias(small_model())
    # Hitter 2 receiving: long 5 % over 300 strikes; the first 100 of them called returns
    # and made long 30 % of the time, the rest never.
    st = _states(model, n_per=(300, 300, 60), seed=3)
    long_b = np.flatnonzero(strike_bias.error_bins()[0])[:6]
    deep_in = np.flatnonzero(~strike_bias.error_bins()[0])[-20:]
    rng = np.random.default_rng(4)
    ret = np.zeros(len(st), dtype=bool)
    ret[300:400] = True
    depth = st.bins[:, 0].numpy().copy()
    depth[300:400] = np.where(rng.random(100) < 0.3, rng.choice(long_b, 100),
                              rng.choice(deep_in, 100))
    depth[400:600] = rng.choice(deep_in, 200)
    st.bins[:, 0] = torch.as_tensor(depth)
    fit_strike_bias(model, st, prior_strikes=0.0)
    server_row = model.strike_bias[2, 0].clone()
    with pytest.raises(ValueError, match="with_strike_return"):
        fit_strike_return(model, st, ret)
    model = with_strike_return(model)
    table = fit_strike_return(model, st, ret, prior_strikes=0.0).set_index(
        ["hitter_id", "is_return"])
    assert sorted(table.index) == [(2, False), (2, True), (3, False)]
    long = torch.as_tensor(strike_bias.error_bins()[0])
    head = model.strike_head
    for rows, share in ((slice(300, 400), 0.3),):
        x, bins = st.h[rows], st.bins[rows]
        bias = model.strike_head_bias(torch.full((len(x),), 2), torch.ones(len(x), dtype=bool),
                                      torch.full((len(x),), rows.start == 300))
        odds = (head.dim_logits(x, bins, 0) + bias[:, 0]).softmax(-1)[:, long].sum(-1).detach()
        assert float(odds.mean()) == pytest.approx(
            float(long[st.bins[rows, 0]].float().mean()), abs=1e-3)
        assert float(long[st.bins[rows, 0]].float().mean()) == pytest.approx(share, abs=0.1)
    # The rest never long: a share of 0 lies beyond any shift, the bound.
    assert float(model.strike_bias[2, 1, 0]) == pytest.approx(-MAX_SHIFT, abs=1e-6)
    assert table.loc[(2, True), "long_record"] == pytest.approx(
        float(long[st.bins[300:400, 0]].float().mean()))
    torch.testing.assert_close(model.strike_bias[2, 0], server_row)   # the server's row kept
    assert (model.strike_return[[0, 1, 3, 4, 5]] == 0).all()
    shares = error_shares(table.reset_index())
    assert "is_return" in shares and len(shares) == 3
    with pytest.raises(ValueError, match="rows"):
        fit_strike_return(model, st, ret[:10])


def test_a_rollouts_return_reads_the_returns_table():
    """`returning` (the rally's next contact is the return) adds the receiver's returns' row to
    a strike from his end, never to the server's."""
    model = with_strike_return(with_strike_bias(small_model()))
    model.strike_bias[2, 0, 0] = 1.0
    model.strike_bias[3, 1, 0] = 4.0
    model.strike_return[3, 0] = 0.5
    model.strike_return[2, 0] = 9.0
    seen, pos = _two_strikes_seen(model)
    long = torch.as_tensor(strike_bias.error_bins()[0])
    for returning, want in ((torch.tensor([True, True]), (4.5, 1.0)),
                            (torch.tensor([False, False]), (4.0, 1.0)), (None, (4.0, 1.0))):
        model.place_strikes(torch.zeros(2, 3, 32), pos, torch.zeros(2, 3, 3), pos.clone(),
                            forced=torch.tensor([True, True]),
                            server_ident=torch.tensor([2, 2]),
                            receiver_ident=torch.tensor([3, 3]), returning=returning)
        assert [seen["bias"][i, 0][long].unique().item() for i in (0, 1)] == list(want)


def _offsets_m() -> np.ndarray:
    return np.abs(_centres(1))


def test_the_width_tilts_only_the_lateral_bins_in_play_around_their_mean():
    tilt = strike_bias.width_tilt()
    wide = strike_bias.error_bins()[strike_bias.WIDE]
    assert (tilt[wide] == 0).all()
    assert tilt[~wide].mean() == pytest.approx(0.0, abs=1e-12)
    # One unit a metre: the tilt's steps are the bins' steps in distance from the centre line.
    off = _offsets_m()
    inside = np.flatnonzero(~wide)
    np.testing.assert_allclose(np.diff(tilt[inside]), np.diff(off[inside]), atol=1e-12)
    # Read with the error table, per hitter and role, on the lateral dimension only.
    model = with_strike_width(with_strike_bias(small_model()))
    assert model.strike_width.shape == (6, 2) and (model.strike_width == 0).all()
    model.strike_width[3, 1] = 0.7
    b = model.strike_head_bias(torch.tensor([3, 3]), torch.tensor([True, False]))
    torch.testing.assert_close(b[0, 1], torch.as_tensor(0.7 * tilt, dtype=b.dtype))
    assert (b[1] == 0).all() and (b[0, [0, 2, 3]] == 0).all()
    again = SportsNGEN(model.cfg)
    again.load_state_dict(model.state_dict())
    torch.testing.assert_close(again.strike_width, model.strike_width)
    with pytest.raises(ValueError, match="strike_bias"):
        ModelConfig(strike_head=True, strike_width=True)


def test_the_width_fit_matches_each_hitters_distance_from_the_centre_line():
    """Hitter 2 plays his balls in play near the centre line as server and near the lines as
    receiver: the fitted head draws each cell's mean distance among the bins in play, and his
    wide errors' share stays his record's."""
    model = with_strike_bias(small_model())
    st = _states(model, n_per=(400, 400, 60), seed=2)
    wide = strike_bias.error_bins()[strike_bias.WIDE]
    inside = np.flatnonzero(~wide)
    off = _offsets_m()
    rng = np.random.default_rng(3)
    near, far = inside[off[inside] < 1.0], inside[off[inside] > 3.0]
    lat = st.bins[:, 1].numpy().copy()
    lat[:400] = rng.choice(near, 400)
    lat[400:800] = rng.choice(far, 400)
    st.bins[:, 1] = torch.as_tensor(lat)
    fit_strike_bias(model, st, prior_strikes=0.0)
    with pytest.raises(ValueError, match="with_strike_width"):
        fit_strike_width(model, st)
    model = with_strike_width(model)
    # Without the wide errors' refit the error table stays as it was (the opponents' and
    # returns' fit refits it instead); the tilt is the same.
    errors = model.strike_bias.clone()
    alone = fit_strike_width(model, st, prior_strikes=0.0, refit_wide=False)
    torch.testing.assert_close(model.strike_bias, errors)
    assert "wide_shift" not in alone
    table = fit_strike_width(model, st, prior_strikes=0.0).set_index(["hitter_id", "receiver"])
    np.testing.assert_allclose(alone["width_shift"], table["width_shift"].to_numpy())
    assert table.loc[(2, False), "width_record_m"] == pytest.approx(off[lat[:400]].mean())
    for key in ((2, False), (2, True), (3, True)):
        assert table.loc[key, "width_after_m"] == pytest.approx(
            table.loc[key, "width_record_m"], abs=1e-3)
    assert table.loc[(2, False), "width_shift"] < 0 < table.loc[(2, True), "width_shift"]
    assert model.strike_width[2, 0] == pytest.approx(table.loc[(2, False), "width_shift"])
    # Drawn with both tables: the cell's mean distance in play, and hitter 3's wide share kept
    # his record's under his tilt.
    bias = model.strike_head_bias(torch.as_tensor(st.hitter_id()), torch.as_tensor(st.receiver))
    draws = torch.stack([model.strike_head.sample(st.h, 1.0, torch.Generator().manual_seed(k),
                                                  dim_bias=bias) for k in range(8)])
    d = draws[..., 1].numpy()
    for rows, key in ((slice(0, 400), (2, False)), (slice(400, 800), (2, True))):
        got = d[:, rows][~wide[d[:, rows]]]
        assert off[got].mean() == pytest.approx(table.loc[key, "width_record_m"], abs=0.08)
    assert table.loc[(3, True), "wide_after"] == pytest.approx(wide[lat[800:]].mean(), abs=1e-4)
    assert wide[d[:, 800:]].mean() == pytest.approx(wide[lat[800:]].mean(), abs=0.06)


def test_a_player_added_for_fine_tuning_gets_a_zero_row_in_every_per_identity_table():
    """`add_player` widens every buffer with a row per identity (the bundled file, with the
    strike tables, could not be fine-tuned: a size mismatch of `strike_bias`)."""
    from sportsngen.data.tokens import Vocab
    from sportsngen.train.finetune import add_player
    from sportsngen.train.receiver_start import with_receiver_start
    from sportsngen.train.serve_bias import (
        with_serve_aim,
        with_serve_bias,
        with_serve_lateral,
        with_serve_short,
    )
    from sportsngen.train.strike_inputs import with_strike_players
    from sportsngen.train.strike_surface import with_strike_surface

    vocab = Vocab(players=("A", "B", "C", "D"))
    from sportsngen.train.strike_bias import with_strike_second

    model = with_strike_late(with_strike_players(with_strike_shape(
        with_strike_pressure(with_strike_return(with_strike_width(with_strike_bias(
            with_receiver_start(with_serve_lateral(with_serve_short(with_serve_aim(
                with_serve_bias(small_model(n_ids=vocab.n_ids, strike_roles=True)))))))))))))
    model = with_strike_second(with_strike_surface(model))
    # The tables are buffers, the players' input shifts parameters of the model itself (the
    # identity embedding's rows are copied, not zeroed: not a table).
    per_identity = sorted(name for name, b in [*model.named_buffers(), *model.named_parameters()]
                          if "." not in name and b.ndim >= 1 and b.shape[0] == vocab.n_ids)
    assert per_identity == sorted(SportsNGEN.PER_IDENTITY_TABLES)
    with torch.no_grad():
        for name in per_identity:
            getattr(model, name).fill_(0.5)
    new, _, idx = add_player(model, vocab, "New Player")
    assert idx == vocab.n_ids
    for name in per_identity:
        old, wide = getattr(model, name), getattr(new, name)
        assert wide.shape == (vocab.n_ids + 1, *old.shape[1:])
        torch.testing.assert_close(wide[:vocab.n_ids], old)
        assert (wide[idx] == 0).all()


def test_the_opponents_table_adds_on_every_strike_but_the_return():
    model = with_strike_pressure(with_strike_return(with_strike_bias(small_model())))
    assert model.strike_pressure.shape == (6, 2, 3) and (model.strike_pressure == 0).all()
    model.strike_bias[3, 1] = torch.tensor([1.0, 0.0, 0.0])
    model.strike_pressure[2, 1] = torch.tensor([0.5, -1.0, 0.0])
    model.strike_pressure[2, 0] = torch.tensor([9.0, 9.0, 9.0])     # another role: not read
    b = model.strike_head_bias(torch.tensor([3, 3]), torch.tensor([True, True]),
                               torch.tensor([True, False]), torch.tensor([2, 2]))
    masks = torch.as_tensor(strike_bias.error_bins())
    assert b[0, 0][masks[0]].unique().tolist() == [1.0]       # the return: his row alone
    assert (b[0, 1] == 0).all()
    assert b[1, 0][masks[0]].unique().tolist() == [1.5]       # a rally ball: both rows
    assert b[1, 1][masks[1]].unique().tolist() == [-1.0]
    # No opponent named: his row alone.
    torch.testing.assert_close(model.strike_head_bias(torch.tensor([3]), torch.tensor([True]),
                                                      torch.tensor([False])), b[:1])
    with pytest.raises(ValueError, match="strike_return"):
        ModelConfig(strike_head=True, strike_bias=True, strike_pressure=True)


def test_a_rollouts_strike_reads_the_opponents_row():
    """`SportsNGEN.place_strikes` adds the row of whoever struck the ball being answered: the
    server's for the receiver's strike, the receiver's for the server's."""
    model = with_strike_pressure(with_strike_return(with_strike_bias(small_model())))
    model.strike_pressure[2] = torch.tensor([[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    model.strike_pressure[3] = torch.tensor([[3.0, 0.0, 0.0], [4.0, 0.0, 0.0]])
    seen, pos = _two_strikes_seen(model)
    model.place_strikes(torch.zeros(2, 3, 32), pos, torch.zeros(2, 3, 3), pos.clone(),
                        forced=torch.tensor([True, True]), server_ident=torch.tensor([2, 2]),
                        receiver_ident=torch.tensor([3, 3]),
                        returning=torch.tensor([False, False]))
    long = torch.as_tensor(strike_bias.error_bins()[0])
    assert seen["bias"][0, 0][long].unique().tolist() == [2.0]      # receiver 3 answers 2
    assert seen["bias"][1, 0][long].unique().tolist() == [3.0]      # server 2 answers 3


def _opponent_states(model, n=400, seed=0):
    """Receivers 2 and 3 against servers 4 and 5, `n` rally strikes a pair: long 5 / 20 %
    (receiver 2 against 4 / 5) and 10 / 35 % (receiver 3): an opponent's effect that is the
    same in log-odds for both; net-height and lateral bins in play."""
    rng = np.random.default_rng(seed)
    share = {(2, 4): 0.05, (2, 5): 0.20, (3, 4): 0.10, (3, 5): 0.35}
    masks = strike_bias.error_bins()
    long_b, deep_in = np.flatnonzero(masks[0])[:6], np.flatnonzero(~masks[0])[-20:]
    lat_in = np.flatnonzero(~masks[1])
    recv, srv, depth = [], [], []
    for (r, s), p in share.items():
        recv += [r] * n
        srv += [s] * n
        depth.append(np.where(rng.random(n) < p, rng.choice(long_b, n), rng.choice(deep_in, n)))
    m = len(recv)
    bins = np.stack([np.concatenate(depth), rng.choice(lat_in, m), rng.integers(20, 40, m),
                     rng.integers(96, size=m)], -1)
    return HeadStates(torch.randn(m, model.cfg.d_model), torch.as_tensor(bins), np.arange(m),
                      np.zeros(m, dtype=np.int64), np.zeros((m, 3)), np.ones(m, dtype=bool),
                      np.array(srv, dtype=np.int64), np.array(recv, dtype=np.int64)), share


def test_the_fit_finds_the_opponents_share_of_the_errors():
    model = with_strike_pressure(with_strike_return(with_strike_bias(small_model())))
    st, share = _opponent_states(model)
    returns = np.zeros(len(st), dtype=bool)
    table = fit_strike_pressure(model, st, returns, rounds=6, prior_strikes=0.0)
    assert set(table["table"]) == {"opponent", "hitter"}
    assert model.strike_pressure[5, 1, 0] - model.strike_pressure[4, 1, 0] > 1.0
    # The two rows together draw each pair's long share; either alone cannot.
    long = torch.as_tensor(strike_bias.error_bins()[0])
    ids = torch.as_tensor(st.receiver_id)
    bias = model.strike_head_bias(ids, torch.ones(len(st), dtype=torch.bool),
                                  torch.zeros(len(st), dtype=torch.bool),
                                  torch.as_tensor(st.server_id))
    with torch.no_grad():
        odds = (model.strike_head.dim_logits(st.h, st.bins, 0, bias).softmax(-1) * long).sum(-1)
    for k, p in enumerate(share.values()):
        assert float(odds[k * 400:(k + 1) * 400].mean()) == pytest.approx(p, abs=0.02)
    # The hitters' rows alone: one share per receiver, the pairs' spread lost.
    alone = with_strike_bias(small_model())
    alone.load_state_dict({k: v for k, v in model.state_dict().items()
                           if k in alone.state_dict()}, strict=True)
    fit_strike_bias(alone, st, prior_strikes=0.0)
    b = alone.strike_head_bias(ids, torch.ones(len(st), dtype=torch.bool))
    with torch.no_grad():
        odds = (alone.strike_head.dim_logits(st.h, st.bins, 0, b).softmax(-1) * long).sum(-1)
    assert abs(float(odds[400:800].mean()) - 0.20) > 0.05
    # Returns are left to the returns' table: their rows move neither table.
    again = with_strike_pressure(with_strike_return(with_strike_bias(small_model())))
    again.load_state_dict(model.state_dict())
    marked = returns.copy()
    marked[::2] = True
    fit_strike_pressure(again, st, marked, rounds=6, prior_strikes=0.0)
    assert again.strike_pressure[5, 1, 0] - again.strike_pressure[4, 1, 0] > 1.0
    assert (again.strike_return[[2, 3], 0] != 0).all()
    with pytest.raises(ValueError, match="with_strike_pressure"):
        fit_strike_pressure(with_strike_return(with_strike_bias(small_model())), st, returns)


def _late_model() -> SportsNGEN:
    return with_strike_late(with_strike_pressure(with_strike_return(with_strike_bias(
        small_model()))))


def test_the_late_table_adds_on_a_hitters_strikes_from_the_fifth_on():
    model = _late_model()
    assert model.strike_late.shape == (6, 2, 3) and (model.strike_late == 0).all()
    model.strike_bias[3, 1] = torch.tensor([1.0, 0.0, 0.0])
    model.strike_late[3, 1] = torch.tensor([0.5, -1.0, 0.0])
    model.strike_late[3, 0] = torch.tensor([9.0, 9.0, 9.0])       # another role: not read
    shots = torch.tensor([1, 3, 4, 5, 7, 12])
    n = len(shots)
    b = model.strike_head_bias(torch.full((n,), 3), torch.ones(n, dtype=torch.bool),
                               shots == 1, torch.full((n,), 2), shots)
    masks = torch.as_tensor(strike_bias.error_bins())
    assert [b[k, 0][masks[0]].unique().tolist() for k in range(n)] == \
        [[1.0], [1.0], [1.0], [1.5], [1.5], [1.5]]
    assert [b[k, 1][masks[1]].unique().tolist() for k in range(n)] == \
        [[0.0], [0.0], [0.0], [-1.0], [-1.0], [-1.0]]
    assert strike_bias.LATE_SHOT == 5
    # The strike's number not given: no strike is late.
    torch.testing.assert_close(
        model.strike_head_bias(torch.full((n,), 3), torch.ones(n, dtype=torch.bool),
                               shots == 1, torch.full((n,), 2)), b[[0, 1, 1, 1, 1, 1]])
    with pytest.raises(ValueError, match="strike_pressure"):
        ModelConfig(strike_head=True, strike_bias=True, strike_return=True, strike_late=True)


def test_a_rollouts_strike_reads_the_late_row_by_the_rallys_shot():
    model = _late_model()
    model.strike_late[3, 1, 0] = 2.0
    model.strike_late[2, 0, 0] = 5.0
    seen, pos = _two_strikes_seen(model)
    long = torch.as_tensor(strike_bias.error_bins()[0])
    for shot, want in (([3, 4], [0.0, 0.0]), ([5, 6], [2.0, 5.0])):
        model.place_strikes(torch.zeros(2, 3, 32), pos, torch.zeros(2, 3, 3), pos.clone(),
                            forced=torch.tensor([True, True]),
                            server_ident=torch.tensor([2, 2]),
                            receiver_ident=torch.tensor([3, 3]),
                            returning=torch.tensor([False, False]), shot=torch.tensor(shot))
        assert [seen["bias"][k, 0][long].unique().tolist() for k in (0, 1)] == \
            [[want[0]], [want[1]]]


def _late_states(model, n=800, seed=0):
    """Receiver 2 against server 4 (long 5 % before his fifth strike, 30 % from it on) and
    receiver 3 against server 5 (15 % throughout), `n` rally strikes each, half of them late."""
    rng = np.random.default_rng(seed)
    masks = strike_bias.error_bins()
    long_b, deep_in = np.flatnonzero(masks[0])[:6], np.flatnonzero(~masks[0])[-20:]
    shot = np.tile(np.repeat([3, 7], n // 2), 2)
    share = np.concatenate([np.where(shot[:n] >= 5, 0.30, 0.05), np.full(n, 0.15)])
    m = 2 * n
    depth = np.where(rng.random(m) < share, rng.choice(long_b, m), rng.choice(deep_in, m))
    bins = np.stack([depth, rng.choice(np.flatnonzero(~masks[1]), m), rng.integers(20, 40, m),
                     rng.integers(96, size=m)], -1)
    return HeadStates(torch.randn(m, model.cfg.d_model), torch.as_tensor(bins), np.arange(m),
                      np.zeros(m, dtype=np.int64), np.zeros((m, 3)), np.ones(m, dtype=bool),
                      np.repeat([4, 5], n).astype(np.int64), np.repeat([2, 3], n).astype(np.int64),
                      shot=shot.astype(np.int64))


def test_the_late_fit_splits_a_hitters_errors_by_the_strikes_number():
    model = _late_model()
    st = _late_states(model)
    returns = np.zeros(len(st), dtype=bool)
    table = fit_strike_pressure(model, st, returns, rounds=6, prior_strikes=0.0)
    assert set(table["table"]) == {"opponent", "hitter", "late"}
    late = table[table["table"] == "late"].set_index("id")
    assert late.loc[2, "n"] == 400 and late.loc[3, "n"] == 400
    long = torch.as_tensor(strike_bias.error_bins()[0])
    record = long[st.bins[:, 0]].float()

    def odds(m) -> torch.Tensor:
        bias = m.strike_head_bias(torch.as_tensor(st.receiver_id),
                                  torch.ones(len(st), dtype=torch.bool),
                                  torch.as_tensor(returns), torch.as_tensor(st.server_id),
                                  torch.as_tensor(st.shot))
        with torch.no_grad():
            return (m.strike_head.dim_logits(st.h, st.bins, 0, bias).softmax(-1) * long).sum(-1)

    got = odds(model)
    for rows in (slice(0, 400), slice(400, 800), slice(800, 1200), slice(1200, 1600)):
        assert float(got[rows].mean()) == pytest.approx(float(record[rows].mean()), abs=0.01)
    assert float(record[:400].mean()) == pytest.approx(0.05, abs=0.03)
    assert float(record[400:800].mean()) == pytest.approx(0.30, abs=0.05)
    assert float(model.strike_late[2, 1, 0]) > 1.0          # 5 % -> 30 %: about 2 logits
    assert abs(float(model.strike_late[3, 1, 0])) < 0.5
    # Without the late table a hitter's one row misses both: his early strikes drawn too long.
    plain = with_strike_pressure(with_strike_return(with_strike_bias(small_model())))
    plain.load_state_dict({k: v for k, v in model.state_dict().items() if k != "strike_late"})
    fit_strike_pressure(plain, st, returns, rounds=6, prior_strikes=0.0)
    assert float(odds(plain)[:400].mean()) - float(record[:400].mean()) > 0.08
    # The late table alone on top of that fit: the other tables kept, the late strikes matched.
    kept = with_strike_late(plain)
    before = {k: getattr(kept, k).clone() for k in ("strike_bias", "strike_pressure",
                                                    "strike_return")}
    alone = fit_strike_pressure(kept, st, returns, prior_strikes=0.0, late_only=True)
    assert set(alone["table"]) == {"late"}
    for k, v in before.items():
        assert torch.equal(getattr(kept, k), v), k
    assert float(odds(kept)[400:800].mean()) == pytest.approx(float(record[400:800].mean()),
                                                              abs=0.01)
    assert float(odds(kept)[:400].mean()) == pytest.approx(float(odds(plain)[:400].mean()))
    with pytest.raises(ValueError, match="with_strike_late"):
        fit_strike_pressure(plain, st, returns, late_only=True)


def _shape_model() -> SportsNGEN:
    return with_strike_shape(with_strike_pressure(with_strike_return(with_strike_bias(
        small_model()))))


def test_the_shapes_tilt_the_depth_in_play_and_the_height_over_the_net_around_their_means():
    errors = strike_bias.error_bins()
    for tilt, dim, kind, centre_m in (
            (strike_bias.depth_tilt(), 0, strike_bias.LONG, strike_bias.DEPTH_CENTRE_M),
            (strike_bias.height_tilt(), 2, strike_bias.NET, strike_bias.HEIGHT_CENTRE_M)):
        assert (tilt[errors[kind]] == 0).all()
        keep = np.flatnonzero(~errors[kind])
        # One unit a metre from the centre, which lies among the bins kept.
        np.testing.assert_allclose(tilt[keep], _centres(dim)[keep] - centre_m, atol=1e-12)
        assert tilt[keep].min() < 0 < tilt[keep].max()
    model = _shape_model()
    assert model.strike_shape.shape == (6, 2, 2) and (model.strike_shape == 0).all()
    assert model.strike_shape_opponent.shape == (6, 2, 2)
    model.strike_shape[3, 1] = torch.tensor([0.5, -1.0])
    model.strike_shape_opponent[2, 1] = torch.tensor([0.25, 2.0])
    model.strike_shape_opponent[2, 0] = torch.tensor([9.0, 9.0])   # another role: not read
    b = model.strike_head_bias(torch.tensor([3, 3, 3]), torch.tensor([True, True, True]),
                               torch.tensor([True, False, False]), torch.tensor([2, 2, 4]))
    depth = torch.as_tensor(strike_bias.depth_tilt(), dtype=b.dtype)
    height = torch.as_tensor(strike_bias.height_tilt(), dtype=b.dtype)
    assert (b[0] == 0).all()                                      # the return: no shape
    torch.testing.assert_close(b[1, 0], 0.75 * depth)             # his row and the opponent's
    torch.testing.assert_close(b[1, 2], 1.0 * height)
    assert (b[1, 1] == 0).all() and (b[1, 3] == 0).all()
    torch.testing.assert_close(b[2, 0], 0.5 * depth)              # an opponent without a row
    torch.testing.assert_close(b[2, 2], -1.0 * height)
    again = SportsNGEN(model.cfg)
    again.load_state_dict(model.state_dict())
    torch.testing.assert_close(again.strike_shape_opponent, model.strike_shape_opponent)
    with pytest.raises(ValueError, match="strike_pressure"):
        ModelConfig(strike_head=True, strike_bias=True, strike_return=True, strike_shape=True)


def _shape_states(model, n=400, seed=0):
    """Receivers 2 and 3 against servers 4 and 5, `n` rally strikes a pair: against server 5
    both receivers' balls in play land short and cross high, against server 4 deep and low
    (receiver 3 a little deeper than 2 against both); a tenth of them long."""
    rng = np.random.default_rng(seed)
    errors = strike_bias.error_bins()
    in_play = np.flatnonzero(~errors[0])
    long_b = np.flatnonzero(errors[0])[:6]
    above = np.flatnonzero(~errors[2])
    depth_c, height_c = _centres(0), _centres(2)
    pairs = [(2, 4), (2, 5), (3, 4), (3, 5)]
    recv, srv, depth, height = [], [], [], []
    for r, s in pairs:
        target = (7.8 if s == 4 else 6.6) + (0.3 if r == 3 else 0.0)
        d = in_play[np.abs(depth_c[in_play] - target) < 0.6]
        h = above[np.abs(height_c[above] - (1.3 if s == 4 else 2.2)) < 0.3]
        recv += [r] * n
        srv += [s] * n
        depth.append(np.where(rng.random(n) < 0.1, rng.choice(long_b, n), rng.choice(d, n)))
        height.append(rng.choice(h, n))
    m = len(recv)
    bins = np.stack([np.concatenate(depth), rng.choice(np.flatnonzero(~errors[1]), m),
                     np.concatenate(height), rng.integers(96, size=m)], -1)
    return HeadStates(torch.randn(m, model.cfg.d_model), torch.as_tensor(bins), np.arange(m),
                      np.zeros(m, dtype=np.int64), np.zeros((m, 3)), np.ones(m, dtype=bool),
                      np.array(srv, dtype=np.int64), np.array(recv, dtype=np.int64)), pairs


def test_the_shape_fit_finds_the_opponents_depth_and_height_and_keeps_the_errors():
    model = _shape_model()
    st, pairs = _shape_states(model)
    returns = np.zeros(len(st), dtype=bool)
    with pytest.raises(ValueError, match="with_strike_shape"):
        fit_strike_shape(with_strike_pressure(with_strike_return(with_strike_bias(
            small_model()))), st, returns)
    table = fit_strike_shape(model, st, returns, rounds=8, prior_strikes=0.0)
    assert set(table["table"]) == {"hitter", "opponent"}
    assert set(table["shape"]) == {"depth", "height"}
    # Server 5's opponents play shorter and higher than server 4's.
    opp = model.strike_shape_opponent
    assert opp[5, 1, 0] < opp[4, 1, 0] and opp[5, 1, 1] > opp[4, 1, 1]
    # Teacher-forced, the two rows together give each pair's mean depth in play and height
    # over the net, and each pair's long share stays the record's (the tables refitted).
    ids = torch.as_tensor(st.receiver_id)
    bias = model.strike_head_bias(ids, torch.ones(len(st), dtype=torch.bool),
                                  torch.zeros(len(st), dtype=torch.bool),
                                  torch.as_tensor(st.server_id))
    errors = strike_bias.error_bins()
    lab = st.bins.numpy()
    with torch.no_grad():
        p0 = model.strike_head.dim_logits(st.h, st.bins, 0, bias).softmax(-1).numpy()
        p2 = model.strike_head.dim_logits(st.h, st.bins, 2, bias).softmax(-1).numpy()
    keep0, keep2 = ~errors[0], ~errors[2]
    depth = (p0 * keep0 * _centres(0)).sum(1) / (p0 * keep0).sum(1)
    height = (p2 * keep2 * _centres(2)).sum(1) / (p2 * keep2).sum(1)
    for k in range(len(pairs)):
        rows = slice(k * 400, (k + 1) * 400)
        ok = keep0[lab[rows, 0]]
        assert depth[rows][ok].mean() == pytest.approx(_centres(0)[lab[rows, 0]][ok].mean(),
                                                       abs=0.08)
        assert height[rows].mean() == pytest.approx(_centres(2)[lab[rows, 2]].mean(), abs=0.08)
        assert (p0[rows] * errors[0]).sum(1).mean() == pytest.approx(
            errors[0][lab[rows, 0]].mean(), abs=0.03)
    # A prior holds the cells near the head's own means.
    held = _shape_model()
    held.load_state_dict({k: v for k, v in model.state_dict().items()
                          if not k.startswith("strike_shape")}, strict=False)
    held.strike_shape.zero_()
    held.strike_shape_opponent.zero_()
    fit_strike_shape(held, st, returns, rounds=8, prior_strikes=1e6)
    assert held.strike_shape_opponent.abs().max() < 0.05
    # Returns move neither table.
    marked = returns.copy()
    marked[pairs.index((2, 5)) * 400:(pairs.index((2, 5)) + 1) * 400] = True
    again = _shape_model()
    fit_strike_shape(again, st, marked, rounds=8, prior_strikes=0.0)
    assert again.strike_shape_opponent[5, 1, 0] < again.strike_shape_opponent[4, 1, 0]
    assert again.strike_shape[2, 1, 0] != pytest.approx(float(model.strike_shape[2, 1, 0]))


def _net_odds(model, st, prev):
    """Mean odds of a net ball over `st` with the kinds read at `prev`'s earlier bins."""
    net = torch.as_tensor(strike_bias.error_bins()[strike_bias.NET])
    bias = model.strike_head_bias(torch.as_tensor(st.hitter_id()), torch.as_tensor(st.receiver),
                                  torch.zeros(len(st), dtype=torch.bool),
                                  torch.as_tensor(st.opponent_id()))
    with torch.no_grad():
        lg = model.strike_head.dim_logits(st.h, prev, strike_bias.NET, bias)
    return float((lg.softmax(-1) * net).sum(-1).mean())


def test_matched_at_the_heads_own_draws_a_rollout_draws_the_records_errors():
    """Fitted at the record's earlier bins the head's net odds there equal the record's, but a
    rollout draws its net height after its own depth and lateral; with `draws` the fit reads
    them there, and fresh draws of the fitted head give the record's net share."""
    base = with_strike_pressure(with_strike_return(with_strike_bias(small_model())))
    st, _ = _opponent_states(base)
    rng = np.random.default_rng(3)
    net_b = np.flatnonzero(strike_bias.error_bins()[strike_bias.NET])
    bins = st.bins.clone()
    bins[:, 2] = torch.as_tensor(np.where(rng.random(len(st)) < 0.15, rng.choice(net_b, len(st)),
                                          rng.integers(60, 80, len(st))))
    st = HeadStates(st.h, bins, st.rally_id, st.serve, st.contact_m, st.receiver, st.server_id,
                    st.receiver_id)
    record = float(torch.as_tensor(strike_bias.error_bins()[2])[bins[:, 2]].float().mean())
    returns = np.zeros(len(st), dtype=bool)
    plain, drawn = (with_strike_pressure(with_strike_return(with_strike_bias(small_model())))
                    for _ in range(2))
    for m in (plain, drawn):
        # A head whose net height hangs on the depth and lateral drawn before it.
        with torch.no_grad():
            for emb in m.strike_head.bin_emb:
                emb.weight.mul_(30.0)
    fit_strike_pressure(plain, st, returns, rounds=3, prior_strikes=0.0)
    fit_strike_pressure(drawn, st, returns, rounds=3, prior_strikes=0.0, draws=8)

    def fresh(model, seed):
        gen = torch.Generator().manual_seed(seed)
        bias = model.strike_head_bias(torch.as_tensor(st.hitter_id()),
                                      torch.as_tensor(st.receiver),
                                      torch.zeros(len(st), dtype=torch.bool),
                                      torch.as_tensor(st.opponent_id()))
        with torch.no_grad():
            return model.strike_head.sample(st.h.repeat(8, 1), 1.0, gen,
                                            dim_bias=bias.repeat(8, 1, 1))

    big = HeadStates(st.h.repeat(8, 1), bins.repeat(8, 1), *(np.tile(a, 8) if a.ndim == 1
                     else np.tile(a, (8, 1)) for a in (st.rally_id, st.serve, st.contact_m,
                                                       st.receiver, st.server_id)),
                     receiver_id=np.tile(st.receiver_id, 8))
    assert _net_odds(plain, st, bins) == pytest.approx(record, abs=0.005)
    # The plain fit's head draws another net share from its own depth and lateral; the
    # draws' fit gives the record's at fresh draws (another seed).
    assert abs(_net_odds(plain, big, fresh(plain, 11)) - record) > 0.02
    assert _net_odds(drawn, big, fresh(drawn, 11)) == pytest.approx(record, abs=0.01)
    with pytest.raises(ValueError, match="draws"):
        from sportsngen.train.strike_bias import head_draws
        head_draws(plain, st, np.arange(3), st.h[:3], 0)
