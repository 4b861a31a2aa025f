"""The serve head teacher-forced at recorded serves (`sportsngen.eval.serve_draws`)."""

import numpy as np
import pandas as pd
import pytest
import torch

from sportsngen.data.tokens import Vocab
from sportsngen.eval.serve_draws import serve_draw_table, serve_faults, teacher_forced_serves

FPS = 25.0


def test_a_serve_is_read_in_long_wide_or_into_the_net():
    # Served from the deuce side of the +x end (y < 0): the box is across the net at y > 0,
    # which a serve's lateral (measured from the server's side) gives as lateral < 0.
    contact = np.tile([11.9, -0.8, 2.9], (5, 1))
    serves = np.array([
        [5.0, -2.0, 45.0, 0.0],    # in the box
        [7.2, -2.0, 45.0, 0.0],    # beyond the service line
        [5.0, 2.0, 45.0, 0.0],     # the other box
        [5.0, -4.6, 45.0, 0.0],    # beyond the singles sideline
        [1.0, -1.0, 60.0, 0.0],    # a flat 216 km/h serve landing 1 m past the net: too low
    ])
    out = serve_faults(contact, serves, FPS)
    assert out["found"].tolist() == [True] * 5
    assert out[["long", "wide", "net"]].to_numpy(bool).tolist() == [
        [False, False, False], [True, False, False], [False, True, False],
        [False, True, False], [False, False, True]]
    assert out["fault"].tolist() == [0.0, 1.0, 1.0, 1.0, 1.0]


@pytest.fixture(scope="module")
def truth_and_model():
    from sportsngen.eval.diagnostics import DiagnosticsSetup, truth_points
    from sportsngen.model.config import ModelConfig
    from sportsngen.model.decoder import SportsNGEN

    data = truth_points(DiagnosticsSetup(n_points=60, seed=5))
    torch.manual_seed(0)
    cfg = ModelConfig(d_model=32, n_layers=2, n_heads=2, ff_mult=2, dropout=0.0, id_dim=8,
                      embed_hidden=(32,), score_hidden=16, n_bins=9, head="factorised",
                      head_hidden=16, window_s=4.0, fps=FPS, n_ids=40, n_tournaments=4,
                      event_d_model=16, event_layers=1, event_heads=2,
                      ball_centre="physics", serve_head=True)
    return data, SportsNGEN(cfg).eval()


def test_the_records_serves_read_as_the_shots_table_says(truth_and_model):
    data, model = truth_and_model

    class Sim:   # what serve_draw_table reads of a Simulator
        vocab = Vocab.from_data(data)

    Sim.model = model
    from sportsngen.data.tokens import rally_arrays

    rows = teacher_forced_serves(model, rally_arrays(data, Sim.vocab), draws=3)
    rec = rows[rows["source"] == "record"].set_index("rally_id")
    shots = data.shots[data.shots["shot_index"] == 0].set_index("rally_id")
    fault = (shots["error_kind"] == "fault").astype(float)
    # Every rally's serve, read through its bins: faults where the generator called a fault.
    assert sorted(rec.index) == sorted(data.rallies["rally_id"])
    agree = (rec["fault"] == fault.loc[rec.index]).mean()
    assert agree >= 0.95, agree
    assert set(rec["serve"]) <= {0, 1}
    # An untrained head draws anywhere: most of its serves are faults.
    mod = rows[rows["source"] == "model"]
    assert mod["fault"].mean() > 0.5
    table = serve_draw_table(Sim, data, draws=2)
    assert list(table.columns) == ["serve", "source", "n", "long", "wide", "net", "fault",
                                   "speed_kmh"]
    first = table[(table["serve"] == "first") & (table["source"] == "record")].iloc[0]
    n_first = int((data.rallies["serve_number"] == 1).sum())
    assert first["n"] == n_first
    assert first["fault"] == pytest.approx(
        fault.loc[data.rallies.loc[data.rallies["serve_number"] == 1, "rally_id"]].mean(),
        abs=0.05)
    assert isinstance(table, pd.DataFrame)


def test_a_model_without_a_serve_head_is_refused(truth_and_model):
    import dataclasses

    from sportsngen.model.decoder import SportsNGEN

    _, model = truth_and_model
    bare = SportsNGEN(dataclasses.replace(model.cfg, serve_head=False))
    with pytest.raises(ValueError, match="no serve head"):
        teacher_forced_serves(bare, None)
