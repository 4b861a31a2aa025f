"""Exact look-ahead within a match (`sim.lookahead`): every rally from a seed of its own
(`match.rally_seed`), so playing the likely next rallies ahead in a worker process gives the same
match."""

import numpy as np
import pandas as pd
import pytest

from sportsngen.errors import ArgumentError
from sportsngen.sim.lookahead import play_rally
from sportsngen.sim.match import _Context, _Odds, _plan_row, likely_path, rally_seed
from sportsngen.sim.simulator import Simulator
from sportsngen.tennis.scoring import MatchFormat, MatchState

SHORT = MatchFormat(best_of=1, games_per_set=2, tiebreak_at=1, no_ad=True)
PAIR = ("Toy Alpha", "Toy Beta")


def _sim(path) -> Simulator:
    return Simulator.from_pretrained(path, max_duration_s=1.2, max_retries=1,
                                     physical_limits=False)


def _row(state: MatchState, point: int = 1, serve: int = 1) -> dict:
    return _plan_row(state, PAIR, "sim-0-0000", point, serve, "hard", "synthetic")


def test_a_rallys_seed_is_its_context_and_nothing_else():
    state = MatchState.new(SHORT, first_server=0)
    row = _row(state)
    assert rally_seed(0, row, 0) == rally_seed(0, dict(reversed(list(row.items()))), 0)
    others = {rally_seed(1, row, 0), rally_seed(0, row, 1), rally_seed(0, _row(state, serve=2), 0),
              rally_seed(0, _row(state.point_won(1), point=2), 0),
              rally_seed(0, _row(state.point_won(0), point=2), 0)}
    assert rally_seed(0, row, 0) not in others and len(others) == 5
    assert 0 <= rally_seed(0, row, 0) < 2 ** 62


def test_the_likely_path_follows_each_serves_likeliest_outcome():
    ctx = _Context(MatchState.new(SHORT, first_server=0))
    odds = _Odds()
    path = likely_path(ctx, odds, 3)
    # Priors: a first serve's likeliest outcome is the server's point.
    assert [(c.point, c.serve, c.state.points) for c in path] == \
        [(1, 1, (0, 0)), (2, 1, (1, 0)), (3, 1, (2, 0)), (4, 1, (3, 0))]
    for _ in range(3):
        odds.add(1, "fault")
    path = likely_path(ctx, odds, 2)
    assert [(c.point, c.serve) for c in path] == [(1, 1), (1, 2), (2, 1)]
    assert path[2].state.points == (1, 0)          # a second serve: still the server's
    assert ctx.after("replay").attempt == 1 and ctx.after("receiver").state.points == (0, 1)
    state = ctx.state
    while not state.is_over:
        state = state.point_won(0)
    over = _Context(state, 9)
    assert over.state.is_over and likely_path(over, odds, 3) == [over]


def test_lookahead_plays_the_same_match(tiny_model_file):
    sim = _sim(tiny_model_file)
    for seed in (0, 1):
        off = sim.simulate_match(*PAIR, "hard", fmt=SHORT, seed=seed, first_server=0,
                                 progress=False)
        on = sim.simulate_match(*PAIR, "hard", fmt=SHORT, seed=seed, first_server=0,
                                progress=False, lookahead=1, lookahead_depth=2)
        pd.testing.assert_frame_equal(off.points, on.points)
        pd.testing.assert_frame_equal(off.rallies.frames, on.rallies.frames)
        assert off.score_line == on.score_line and off.n_discarded == on.n_discarded
    # The match's first rally (kept or set aside) is the rally its context plays alone.
    frames = off.rallies.frames if off.discarded is None else \
        pd.concat([off.rallies.frames, off.discarded.frames])
    state = MatchState.new(SHORT, first_server=0)
    alone = play_rally(sim, _row(state) | {"match_id": "sim-1-0000"},
                       rally_seed(1, _row(state) | {"match_id": "sim-1-0000"}, 0))
    mine = frames[frames["rally_id"] == 0]
    np.testing.assert_array_equal(alone.frames[["x", "y", "z"]].to_numpy(),
                                  mine[["x", "y", "z"]].to_numpy())


def test_lookahead_refuses_several_matches_and_bad_counts(tiny_model_file):
    sim = _sim(tiny_model_file)
    with pytest.raises(ArgumentError, match="one match"):
        sim.simulate_matches([PAIR, PAIR], "hard", fmt=SHORT, lookahead=1, progress=False)
    with pytest.raises(ArgumentError, match="lookahead"):
        sim.simulate_match(*PAIR, "hard", fmt=SHORT, lookahead=-1, progress=False)
