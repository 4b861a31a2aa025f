"""The SportsNGEN model: token embedding, decoder f with KV cache, binned heads, sampling,
event classifier g, export.

One simulation step, as the simulator would run it (B rallies in a batch)::

    model, g, vocab, cfg = load_model("model.pt")
    ctx = model.context_tokens(surface, tournament, serve, score)        # (B,), (B,), (B,), (B, 7)
    cache = model.init_cache(ident, ctx)                                # ident (B, 3)
    feats = object_features(pos[:, None], vel[:, None], t_s[:, None])   # -> (B, 1, 3, 8)
    h, cache = model.forward_step(feats[:, 0], cache)                   # (B, 3, d)
    nxt = model.sample_next(h, pos, vel, top_p_player, top_p_ball, generator,
                            prev_vel)                                   # (B, 3, 3)

(`object_features` from `sportsngen.model.inputs`; velocities are backward differences,
`prev_vel` those of the frame before, for the ball's physics centre. A model with a strike head
also redraws a sampled strike with `model.place_strikes` and puts the launch's next two frames
down itself: `sportsngen.sim.frame_draws` does both.)
"""

from __future__ import annotations

import importlib

# The package's names are imported on first use (PEP 562), so that reading a light submodule
# (`model.inputs`, the input schema `data.tokens` cuts tracking to) does not load the decoder,
# which itself reads `data.tokens`: a load-time cycle otherwise.
_WHERE = {"ModelConfig": "config", "KVCache": "decoder", "SportsNGEN": "decoder",
          "baller2vec_mask": "decoder", "EventClassifier": "event_classifier",
          "load_model": "export", "save_model": "export", "sample_top_p": "sampling",
          "top_p_filter": "sampling"}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(importlib.import_module(f"sportsngen.model.{_WHERE[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
