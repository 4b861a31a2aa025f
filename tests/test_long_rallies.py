"""The cached rollout's view of shots past the model's window against training's view."""

from __future__ import annotations

import types
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from sportsngen.eval.diagnostics import DiagnosticsSetup, truth_points
from sportsngen.eval.long_rallies import late_shot_contact_odds, points_after_window
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.model.decoder import SportsNGEN
from sportsngen.sim import Simulator


@pytest.fixture(scope="module")
def scored(tiny_model_file):
    sim = Simulator.from_pretrained(tiny_model_file, max_retries=0)
    truth = truth_points(DiagnosticsSetup(n_points=30, seed=1))
    return sim, truth, analyse_rally_data(truth)


def test_late_shots_are_read_two_ways_and_agree_for_one_layer(scored):
    sim, truth, rules = scored
    two = late_shot_contact_odds(sim, truth, rules)
    # The tiny model's window is 2 s: the generator's rallies strike many shots after it.
    assert two["shots"] > 5
    assert 0.0 <= two["band"] <= 1.0 and 0.0 <= two["window"] <= 1.0
    assert two["band"] != pytest.approx(two["window"], abs=1e-6)
    # With one layer a token reads only the inputs of its band, so both views are the same
    # numbers: the difference is the depth reaching back past the window.
    one = SportsNGEN(replace(sim.model.cfg, n_layers=1)).eval()
    one.load_state_dict(sim.model.state_dict(), strict=False)
    flat = late_shot_contact_odds(types.SimpleNamespace(model=one, vocab=sim.vocab), truth,
                                  rules)
    assert flat["shots"] == two["shots"]
    assert flat["band"] == pytest.approx(flat["window"], abs=1e-5)


def test_no_late_shot_gives_nan(scored):
    sim, truth, rules = scored
    long_window = SportsNGEN(replace(sim.model.cfg, window_s=60.0)).eval()
    long_window.load_state_dict(sim.model.state_dict())
    out = late_shot_contact_odds(types.SimpleNamespace(model=long_window, vocab=sim.vocab),
                                 truth, rules)
    assert out["shots"] == 0 and np.isnan(out["band"]) and np.isnan(out["window"])


def test_points_after_window_splits_decided_points_by_the_serve_leaving_the_window():
    # Rally 1: last shot 149 frames after the serve (inside a 150-frame window), server wins;
    # rally 2: 150 after, receiver wins; rally 3: 400 after, server wins; rally 4: a first-serve
    # fault (no winner), left out; rally 5: a winner but no serve row, left out.
    rallies = pd.DataFrame({"rally_id": [1, 2, 3, 4, 5], "server": ["A", "A", "B", "A", "B"],
                            "winner": ["A", "B", "B", "", "A"]})
    shots = pd.DataFrame({"rally_id": [1, 1, 2, 2, 2, 3, 3, 4, 5],
                          "shot_index": [0, 1, 0, 1, 2, 0, 5, 0, 1],
                          "frame": [27, 176, 30, 100, 180, 27, 427, 27, 60]})
    t = points_after_window(types.SimpleNamespace(rallies=rallies, shots=shots), 150)
    assert t.loc["before"].tolist() == [1, pytest.approx(1 / 3), 1.0]
    assert t.loc["after"].tolist() == [2, pytest.approx(2 / 3), 0.5]
    t = points_after_window(types.SimpleNamespace(rallies=rallies, shots=shots), 1000)
    assert t.at["after", "points"] == 0 and np.isnan(t.at["after", "server_won"])
    with pytest.raises(ValueError, match="window_frames"):
        points_after_window(types.SimpleNamespace(rallies=rallies, shots=shots), 0)
