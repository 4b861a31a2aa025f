"""A fine-tuned player's rows of the per-player tables (`sportsngen.train.player_tables`)."""

import numpy as np
import pytest
import torch

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.model import serve_bias, strike_bias
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN
from sportsngen.train.finetune import add_player
from sportsngen.train.head_fit import collect_head_states
from sportsngen.train.player_tables import fit_player_tables
from sportsngen.train.serve_bias import with_serve_bias, with_serve_short
from sportsngen.train.strike_bias import with_strike_bias, with_strike_return

TABLES = ("serve_bias", "serve_short", "strike_bias", "strike_return")


@pytest.fixture(scope="module")
def data(truth_data):
    return truth_data(80, 5)


def model_for(vocab: Vocab) -> SportsNGEN:
    torch.manual_seed(0)
    cfg = ModelConfig(d_model=32, n_layers=1, n_heads=2, ff_mult=2, dropout=0.0, id_dim=8,
                      embed_hidden=(32,), score_hidden=16, n_bins=9, head="factorised",
                      head_hidden=16, window_s=4.0, fps=25.0, n_ids=vocab.n_ids,
                      n_tournaments=4, event_d_model=16, event_layers=1, event_heads=2,
                      ball_centre="physics", serve_head=True, strike_head=True)
    return with_strike_return(with_strike_bias(with_serve_short(with_serve_bias(
        SportsNGEN(cfg))))).eval()


def _others_unchanged(model, before, row):
    for name in TABLES:
        after = getattr(model, name)
        others = torch.ones(len(after), dtype=torch.bool)
        others[row] = False
        assert torch.equal(after[others], before[name][others]), name


def test_only_the_players_rows_move_and_each_matches_his_own_record(data):
    """The fixture's points are all served by one player: the server's fit fills his serves'
    and his rally strikes' rows, the receiver's his receiving and returns' rows."""
    vocab = Vocab.from_data(data)
    server = str(data.rallies["server"].iloc[0])
    receiver = str(data.rallies["receiver"].iloc[0])
    model = model_for(vocab)
    for name in TABLES:
        getattr(model, name).fill_(0.25)          # the others' rows, as fitted before
    for p in (server, receiver):
        for name in TABLES:
            getattr(model, name)[vocab.player_index(p)] = 0.0     # as `add_player` leaves them
    row = vocab.player_index(server)
    before = {name: getattr(model, name).clone() for name in TABLES}
    table = fit_player_tables(model, vocab, data, server, prior_serves=0.0,
                              prior_strikes=0.0)
    _others_unchanged(model, before, row)
    assert set(table["table"]) == {"serve_bias", "serve_short", "strike_bias"}
    assert set(table["role"]) == {"first", "second", "server"}
    assert (model.serve_bias[row] != 0).all() and (model.strike_bias[row, 0] != 0).all()
    assert (model.serve_short[row] != 0).all()
    assert (model.strike_bias[row, 1] == 0).all() and (model.strike_return[row] == 0).all()
    # With no prior the head's odds after the fit are his record's, read on his serves.
    arrays = rally_arrays(data, vocab)
    states = collect_head_states(model, arrays, "serve", flip=True, progress=False)
    first = (states.server_id == row) & (states.serve == 0)
    long_share = serve_bias.long_fraction()[states.bins[first, 0].numpy()].mean()
    cell = table[table["role"] == "first"].iloc[0]
    assert cell["n"] == int(first.sum()) and cell["long_record"] == pytest.approx(long_share)
    assert cell["long_after"] == pytest.approx(cell["long_record"], abs=1e-4)
    st = collect_head_states(model, arrays, "strike", flip=True, progress=False)
    his = st.hitter_id() == row
    net = strike_bias.error_bins()[strike_bias.NET][st.bins[his, 2].numpy()].mean()
    srv = table[table["role"] == "server"].iloc[0]
    assert srv["n"] == int(his.sum()) and srv["net_record"] == pytest.approx(net)
    assert srv["net_after"] == pytest.approx(net, abs=1e-4)

    # The receiver: his receiving row (refitted on his strikes that are not returns) and his
    # returns' row; the server's rows as the first fit left them.
    row = vocab.player_index(receiver)
    before = {name: getattr(model, name).clone() for name in TABLES}
    table = fit_player_tables(model, vocab, data, receiver, prior_serves=0.0,
                              prior_strikes=0.0)
    _others_unchanged(model, before, row)
    assert sorted(zip(table["table"], table["role"])) == [
        ("strike_bias", "receiver"), ("strike_return", "return")]
    assert (model.serve_bias[row] == 0).all() and (model.strike_bias[row, 0] == 0).all()
    assert (model.serve_short[row] == 0).all()
    assert (model.strike_bias[row, 1] != 0).all() and (model.strike_return[row] != 0).any()
    returns = st.returns() & (st.hitter_id() == row)
    ret = table[table["role"] == "return"].iloc[0]
    assert ret["n"] == int(returns.sum())
    assert ret["long_record"] == pytest.approx(
        strike_bias.error_bins()[strike_bias.LONG][st.bins[returns, 0].numpy()].mean())


def test_a_prior_keeps_a_player_with_few_serves_near_the_head(data):
    vocab = Vocab.from_data(data)
    player = str(data.rallies["server"].iloc[0])
    free, held = model_for(vocab), model_for(vocab)
    t0 = fit_player_tables(free, vocab, data, player, prior_serves=0.0, prior_strikes=0.0)
    t1 = fit_player_tables(held, vocab, data, player, prior_serves=1e4, prior_strikes=1e4)
    row = vocab.player_index(player)
    assert held.serve_bias[row].abs().max() < 0.1 * free.serve_bias[row].abs().max()
    assert np.allclose(t1["long_head"].dropna(), t0["long_head"].dropna())


def test_a_player_without_his_own_row_or_a_model_without_tables(data):
    vocab = Vocab.from_data(data)
    with pytest.raises(ValueError, match="add him first"):
        fit_player_tables(model_for(vocab), vocab, data, "Nobody Known")
    plain = model_for(vocab)
    plain = SportsNGEN(ModelConfig(**{**plain.cfg.to_dict(), "serve_bias": False,
                                      "serve_short": False, "strike_bias": False,
                                      "strike_return": False})).eval()
    assert fit_player_tables(plain, vocab, data, vocab.players[0]).empty
    # A player added by fine-tuning but absent from the rallies: nothing to fit on.
    new, vocab2, idx = add_player(model_for(vocab), vocab, "New Player")
    assert (new.serve_bias[idx] == 0).all()
    with pytest.raises(ValueError, match="plays no rally"):
        fit_player_tables(new, vocab2, data, "New Player")


def test_the_rule_tables_carry_over_with_the_players_own_rows(data):
    """The base file's reach and top-speed tables keyed by name come through a fine-tune with
    the player's rows fitted on his rallies: the receiver's return reach, both players' rally
    reach and top speed (the generator's own, 6.8 m/s for Federer and 7.0 for Nadal), the base's
    other rows as they were; a player with too few balls or frames keeps the pooled row."""
    from sportsngen.sim.reach_table import ReachTable
    from sportsngen.sim.top_speed import TopSpeeds
    from sportsngen.train.player_tables import player_rule_tables

    server = str(data.rallies["server"].iloc[0])
    receiver = str(data.rallies["receiver"].iloc[0])
    base = {"return_reach": ReachTable((1.5, 0.04), {"Other": (1.4, 0.03)}).to_dict(),
            "rally_reach": ReachTable((1.9, 0.2)).to_dict(),
            "top_speed": TopSpeeds(6.5, {"Other": 6.1}).to_dict()}
    got = player_rule_tables(base, data, receiver, min_balls=30, min_frames=1000)
    ret = ReachTable.from_dict(got["return_reach"])
    assert ret.players["Other"] == (1.4, 0.03) and ret.pooled == (1.5, 0.04)
    assert 1.2 < ret.players[receiver][0] < 1.8 and ret.players[receiver][1] > 0
    assert receiver in ReachTable.from_dict(got["rally_reach"]).players
    speeds = TopSpeeds.from_dict(got["top_speed"])
    top = {"Roger Federer": 6.8, "Rafael Nadal": 7.0}[receiver]
    assert speeds.players_mps["Other"] == 6.1 and 6.0 < speeds.players_mps[receiver] <= top + 1e-6
    # The server receives no serve here: his return reach stays the pooled row. His rally
    # reach is his own where he let a good ball due to him go, and the pooled row on the
    # rallies where he answered every one (the fall of his odds cannot be read).
    from sportsngen.eval.reach import reach_rows

    got = player_rule_tables(base, data, server, min_balls=30, min_frames=1000)
    assert server not in ReachTable.from_dict(got["return_reach"]).players
    assert server in TopSpeeds.from_dict(got["top_speed"]).players_mps
    rows = reach_rows(data)
    mine = rows[(rows["shot"] >= 1) & (rows["role"] == "server")]   # he serves every rally
    missed = set(mine.loc[~mine["answered"].astype(bool), "rally_id"])
    assert len(mine) >= 30 and 0 < len(missed) < len(mine) / 4
    assert server in ReachTable.from_dict(got["rally_reach"]).players
    clean = data.subset(sorted(set(data.rallies["rally_id"]) - missed))
    got = player_rule_tables(base, clean, server, min_balls=30, min_frames=1000)
    assert server not in ReachTable.from_dict(got["rally_reach"]).players
    few = player_rule_tables({"top_speed": base["top_speed"]}, data, server, min_frames=10 ** 9)
    assert set(few) == {"top_speed"} and server not in few["top_speed"]["players_mps"]
