"""The cached rollout's view of shots past the model's window against training's view."""

from __future__ import annotations

import types
from dataclasses import replace

import numpy as np
import pytest

from sportsngen.eval.diagnostics import DiagnosticsSetup, truth_points
from sportsngen.eval.long_rallies import late_shot_contact_odds
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
