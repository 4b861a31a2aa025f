"""The strike head teacher-forced at recorded rally strikes (`sportsngen.eval.strike_draws`)."""

import dataclasses

import numpy as np
import pytest
import torch

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.eval.strike_draws import (
    _nearest_target,
    strike_draw_table,
    strike_error_table,
    strike_errors,
    teacher_forced_strikes,
)
from sportsngen.train.windows import WindowDataset

FPS = 25.0


def test_a_strike_is_read_long_wide_or_into_the_net():
    strikes = np.array([
        [10.0, 2.0, 1.5, -0.2],     # deep, inside the line, well over the net
        [12.0, 0.0, 1.5, -0.2],     # beyond the baseline (11.885)
        [11.8, 4.2, 1.5, -0.2],     # beyond the singles line (4.115)
        [8.0, -4.0, 0.95, -0.2],    # near the sideline over the net's 0.914 at the centre
        [8.0, 0.0, 0.9, -0.2],      # under the net at the centre strap
    ])                              # (the net at |y| = 4.0 m stands higher than 0.95 m)
    assert strike_errors(strikes).tolist() == [False, True, True, True, True]
    assert strike_errors(strikes.reshape(5, 1, 4)).shape == (5, 1)


def test_nearest_target_prefers_the_frame_then_the_earlier_neighbour():
    mask = np.zeros((4, 10), dtype=bool)
    mask[0, 5] = True                      # exactly there
    mask[1, [3, 5]] = True                 # one each side of 4: the earlier
    mask[2, 9] = True                      # three frames away: none
    mask[3, 0] = True                      # at the window's start, wanted at 1
    assert _nearest_target(mask, np.array([5, 4, 6, 1])).tolist() == [5, 3, -1, 0]


def test_windows_given_as_items_are_read_there_and_checked():
    from sportsngen.data.toy import make_toy_rallies

    data = make_toy_rallies(n_rallies=2, seed=0)
    arr = rally_arrays(data, Vocab.from_data(data))
    ds = WindowDataset(arr, 20, None, items=[(1, 5)])
    assert len(ds) == 1
    item = ds[0]
    start = arr.start[1]
    assert np.allclose(item["pos_m"][:3], arr.pos_m[start + 5:start + 8])
    with pytest.raises(ValueError, match="outside their rallies"):
        WindowDataset(arr, 20, None, items=[(0, int(arr.length[0]))])


def test_the_records_strikes_read_as_the_shots_table_says(federer_points_and_head_model):
    data, model, sim = federer_points_and_head_model
    rows = teacher_forced_strikes(model, rally_arrays(data, sim.vocab), data, draws=3)
    strikes = data.shots[data.shots["shot_index"] >= 1]
    # Nearly every recorded rally strike is found among the head's targets, once.
    assert len(rows) >= 0.9 * len(strikes)
    assert not rows.duplicated(["rally_id", "shot"]).any()
    table = strikes.set_index(["rally_id", "shot_index"])
    err = table.loc[list(zip(rows["rally_id"], rows["shot"])), "outcome"].to_numpy() == "error"
    # Read through its bins, the record's strike errs where the generator says it did.
    assert (rows["record_error"].to_numpy() == err).mean() >= 0.95
    assert rows["receiver"].tolist() == (rows["shot"] % 2 == 1).tolist()
    serve = data.rallies.set_index("rally_id").loc[rows["rally_id"], "serve_number"] - 1
    assert rows["serve"].tolist() == serve.tolist()
    # An untrained head draws anywhere: most of its strikes are errors.
    assert rows["model_error"].mean() > 0.5
    out = strike_draw_table(sim, data, draws=2)
    assert list(out.columns) == ["shot", "hitter", "serve", "n", "record", "model"]
    assert out["n"].sum() == len(rows)
    assert set(out["hitter"]) <= {"server", "receiver", "both"} and "receiver" in set(out["hitter"])
    first_returns = out[(out["shot"] == "1") & (out["serve"] == "first")].iloc[0]
    sel = (rows["shot"] == 1) & (rows["serve"] == 0)
    assert first_returns["n"] == sel.sum()
    assert first_returns["record"] == pytest.approx(rows.loc[sel, "record_error"].mean())


def test_each_strike_is_read_with_its_number(federer_points_and_head_model, monkeypatch):
    """The head's input at a recorded strike is given that strike's number (the shots table's
    `shot_index`, 1 the return), which a model with `cfg.strike_shots` reads."""
    data, model, sim = federer_points_and_head_model
    seen = []
    read = model.strike_input

    def spy(h, role, shot=None, hitter=None, opponent=None):
        seen.append(shot.clone())
        return read(h, role, shot, hitter, opponent)

    monkeypatch.setattr(model, "strike_input", spy)
    rows = teacher_forced_strikes(model, rally_arrays(data, sim.vocab), data, draws=1)
    assert torch.cat(seen).tolist() == rows["shot"].tolist()
    assert rows["shot"].max() >= 4


def test_the_table_pools_the_late_shots():
    import pandas as pd

    rows = pd.DataFrame({"rally_id": [1, 1, 2, 3], "shot": [1, 8, 9, 7], "serve": [0, 0, 1, 1],
                         "receiver": [True, False, True, True],
                         "record_error": [True, False, True, False],
                         "model_error": [0.5, 0.0, 1.0, 0.5]})
    out = strike_error_table(rows)
    assert out["shot"].tolist() == ["1", "7+", "7+"]
    assert out["n"].tolist() == [1, 1, 2]
    assert out["model"].tolist() == [0.5, 0.0, 0.75]


def test_a_model_without_a_strike_head_is_refused(federer_points_and_head_model):
    from sportsngen.model.decoder import SportsNGEN

    _, model, _ = federer_points_and_head_model
    bare = SportsNGEN(dataclasses.replace(model.cfg, strike_head=False))
    with pytest.raises(ValueError, match="no strike head"):
        teacher_forced_strikes(bare, None, None)
