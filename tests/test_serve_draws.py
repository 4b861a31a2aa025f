"""The serve head teacher-forced at recorded serves (`sportsngen.eval.serve_draws`)."""

import numpy as np
import pandas as pd
import pytest

from sportsngen.eval.serve_draws import serve_draw_table, serve_faults, teacher_forced_serves
from sportsngen.model import strike

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


def test_the_records_serves_read_as_the_shots_table_says(federer_points_and_head_model):
    data, model, sim = federer_points_and_head_model
    from sportsngen.data.tokens import rally_arrays

    rows = teacher_forced_serves(model, rally_arrays(data, sim.vocab), draws=3)
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
    table = serve_draw_table(sim, data, draws=2)
    assert list(table.columns) == ["serve", "source", "n", "long", "wide", "net", "fault",
                                   "speed_kmh"]
    first = table[(table["serve"] == "first") & (table["source"] == "record")].iloc[0]
    n_first = int((data.rallies["serve_number"] == 1).sum())
    assert first["n"] == n_first
    # Read through their bins, a serve or two near a line may flip (the rally-level agreement
    # above is 0.95 or more): within three first serves of the shots table.
    assert first["fault"] == pytest.approx(
        fault.loc[data.rallies.loc[data.rallies["serve_number"] == 1, "rally_id"]].mean(),
        abs=3.0 / n_first)
    assert isinstance(table, pd.DataFrame)
    # The nucleus is the rollouts': at a tiny one every draw is the head's top bin whatever
    # the seed, so the speeds differ only inside their bin (`--top-p-serve` had been accepted
    # and ignored); the full head's draws differ by more.
    def model_speeds(seed: int, top_p: float) -> np.ndarray:
        got = teacher_forced_serves(model, rally_arrays(data, sim.vocab), draws=2, seed=seed,
                                    top_p=top_p)
        return got.loc[got["source"] == "model", "speed_mps"].to_numpy()

    bin_mps = float(np.diff(strike.serve_edges()[2])[0])
    assert np.abs(model_speeds(0, 1e-6) - model_speeds(1, 1e-6)).max() < bin_mps
    assert np.abs(model_speeds(0, 1.0) - model_speeds(1, 1.0)).max() > 3 * bin_mps


def test_a_model_without_a_serve_head_is_refused(federer_points_and_head_model):
    import dataclasses

    from sportsngen.model.decoder import SportsNGEN

    _, model, _ = federer_points_and_head_model
    bare = SportsNGEN(dataclasses.replace(model.cfg, serve_head=False))
    with pytest.raises(ValueError, match="no serve head"):
        teacher_forced_serves(bare, None)
