"""The bundled model file loads without Hydra and knows the named players."""

from pathlib import Path

import torch

from sportsngen.model.export import load_model
from sportsngen.synth.profiles import named_profiles

BUNDLED = Path(__file__).resolve().parents[1] / "sportsngen/model/bundled/sportsngen-small.pt"


def test_bundled_model_loads_with_event_classifier_and_named_players():
    assert BUNDLED.stat().st_size < 40 * 1024 * 1024
    model, events, vocab, cfg = load_model(BUNDLED)
    assert events is not None
    assert set(named_profiles()) <= set(vocab.players)
    assert cfg.head == "factorised" and cfg.n_bins == 61
    assert all(torch.isfinite(p).all() for p in model.parameters())
