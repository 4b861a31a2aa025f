"""The model's players on the record's ball (`sportsngen.eval.chase`)."""

from __future__ import annotations

import numpy as np
import pytest

from sportsngen.eval.chase import (
    ALONG_FRAMES,
    FAR_M,
    PAST_FRAMES,
    _path_on,
    along_table,
    chase_table,
    path_gap_m,
    players_on_the_record,
)
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.tennis.court import FENCE_X_M, FENCE_Y_M


def test_path_gap_is_the_least_horizontal_distance_below_reach_height():
    t = np.arange(10)
    path = np.stack([10.0 - t, np.zeros(10), np.full(10, 1.0)], axis=1)
    path[4, 2] = 3.0                               # too high to strike: not counted
    player = np.stack([np.full(10, 6.0), np.full(10, 0.7)], axis=1)
    # Level with him at frame 4 (too high), so the nearest is a frame either side.
    assert path_gap_m(player, path, 0, 9) == pytest.approx(np.hypot(1.0, 0.7))
    assert path_gap_m(player, path, 0, 2) == pytest.approx(np.hypot(2.0, 0.7))
    # Clipped to both tracks; nothing left: NaN.
    assert path_gap_m(player, path, 8, 30) == pytest.approx(np.hypot(4.0, 0.7))
    assert np.isnan(path_gap_m(player, path, 4, 4))
    assert np.isnan(path_gap_m(player, path, 12, 20))


def test_the_path_flown_on_follows_a_recorded_flight(federer_points_and_head_model):
    # Ten frames after each return's contact, the ball flown on from its last three frames
    # stays within 5 cm of the recorded ball for the next 8 frames while it is in the air
    # (a median 1.3 cm; started at the last frame with its backward difference, 6.6 cm).
    data = federer_points_and_head_model[0]
    rules = analyse_rally_data(data)
    errs = []
    for rid, g in data.frames[data.frames["object"] == "ball"].groupby("rally_id"):
        c, b = list(rules.loc[rid, "contact_frames"]), list(rules.loc[rid, "bounce_frames"])
        if len(c) < 2:
            continue
        ball = g.sort_values("frame")[["x", "y", "z"]].to_numpy(float)
        f = c[1] + 10
        nxt = [x for x in b + c[2:] if x > c[1]]
        if not nxt or nxt[0] < f + 9 or f + 8 > len(ball):
            continue
        # a ball that reaches the fence stops there (wide returns, seed 6's rally 77)
        if (np.abs(ball[c[1]:f + 8, :2]) >= (FENCE_X_M - 0.01, FENCE_Y_M - 0.01)).any():
            continue
        path = _path_on(ball, f, 25.0)
        assert path.shape == (f + PAST_FRAMES, 3)
        assert np.array_equal(path[:f], ball[:f])
        errs.append(np.abs(path[f:f + 8] - ball[f:f + 8]).max())
    assert len(errs) >= 10
    assert np.median(errs) < 0.025 and max(errs) < 0.05, errs


def test_players_on_the_record_rows_and_tables(federer_points_and_head_model):
    data, model, sim = federer_points_and_head_model
    rows = players_on_the_record(model, sim.vocab, data, seed=3, max_rallies=6)
    assert rows["rally_id"].nunique() == 6
    assert rows["shot"].min() == 1
    assert set(rows["role"]) == {"server", "receiver"}
    assert (rows.loc[rows["shot"] % 2 == 1, "role"] == "receiver").all()
    # The record's players reach the record's balls; the runs start where the record stood.
    assert (rows["gap_record_m"] > FAR_M).mean() < 0.1
    assert np.allclose(rows["along_m_0"].dropna(), 0.0)
    assert np.allclose(rows["along_record_m_0"].dropna(), 0.0)
    # The record's own columns do not depend on the model's draws; the model's do. (Four
    # rallies from here on: the rule's rollouts cost three times the plain ones.)
    few = players_on_the_record(model, sim.vocab, data, seed=3, max_rallies=4)
    first = rows[rows["rally_id"].isin(few["rally_id"])].reset_index(drop=True)
    assert few["rally_id"].nunique() == 4 and len(few) == len(first)
    assert np.array_equal(first["gap_record_m"], few["gap_record_m"], equal_nan=True)
    again = players_on_the_record(model, sim.vocab, data, seed=4, max_rallies=4)
    assert np.array_equal(few["gap_record_m"], again["gap_record_m"], equal_nan=True)
    assert not np.array_equal(few["gap_m"], again["gap_m"], equal_nan=True)
    table = chase_table(rows)
    last = table.iloc[-1]
    assert last["group"] == "all after the return"
    assert last["n"] == (rows["shot"] >= 2).sum()
    assert last["far"] == pytest.approx((rows.loc[rows["shot"] >= 2, "gap_m"] > FAR_M).mean())
    assert table.loc[table["group"] == "shot 1", "n"].item() == (rows["shot"] == 1).sum()
    along = along_table(rows, min_run_m=0.0)
    assert list(along.columns[1:]) == list(ALONG_FRAMES) and len(along) == 2
    # Under the rule for late players the record's side is the same, the model's its own.
    ruled = players_on_the_record(model, sim.vocab, data, seed=3, max_rallies=4,
                                  keep_chasing=True)
    assert np.array_equal(few["gap_record_m"], ruled["gap_record_m"], equal_nan=True)
    assert not np.array_equal(few["gap_m"], ruled["gap_m"], equal_nan=True)
    with pytest.raises(ValueError, match="after_frames"):
        players_on_the_record(model, sim.vocab, data, after_frames=0)
