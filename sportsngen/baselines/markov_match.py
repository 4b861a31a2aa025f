"""Whole matches of the Markov engine (`simulate.py engine=markov`): i.i.d. points from one serve
model per player (`serve_model`), and player 1's exact live win probability along a match."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from sportsngen.baselines.markov import match_win_probability
from sportsngen.baselines.serve_model import serve_model, simulate_match_points
from sportsngen.tennis.scoring import MatchFormat, MatchState


def win_probability_path(points: pd.DataFrame, pa: float, pb: float, fmt: MatchFormat,
                         player1: str, first_server: int) -> np.ndarray:
    """Player 1's match-win probability before each point and after the last (Markov, exact)."""
    state = MatchState.new(fmt, first_server=first_server)
    probs = [match_win_probability(pa, pb, fmt, state)]
    for winner in points["winner"]:
        state = state.point_won(0 if winner == player1 else 1)
        probs.append(1.0 if state.is_over and state.winner == 0 else
                     0.0 if state.is_over else match_win_probability(pa, pb, fmt, state))
    return np.asarray(probs)


def serve_points_won(names: tuple[str, str]) -> tuple[float, float]:
    """Each player's chance of winning a point on his serve against the other (Barnett-Clarke
    adjusted serve models of the real 2011 data)."""
    models = (serve_model(names[0]), serve_model(names[1]))
    return (models[0].adjusted_against(models[1]).serve_points_won,
            models[1].adjusted_against(models[0]).serve_points_won)


def play_markov_matches(names: tuple[str, str], fmt: MatchFormat, surface: str, n_matches: int,
                        seed: int, first_server: int) -> Iterator[tuple[pd.DataFrame, MatchState]]:
    """`n_matches` matches (seeds `seed`, `seed` + 1, ...) -> each one's points table and final
    state, as they are played."""
    models = (serve_model(names[0]), serve_model(names[1]))
    for i in tqdm(range(n_matches), desc="matches", disable=n_matches < 2):
        yield simulate_match_points(models[0], models[1], names=names, fmt=fmt, surface=surface,
                                    seed=seed + i, match_id=f"sim-{i + 1}",
                                    first_server=first_server)
