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

(`object_features` from `sportsngen.data.tokens`; velocities are backward differences,
`prev_vel` those of the frame before, for the ball's physics centre. A model with a strike head
also redraws a sampled strike with `model.place_strikes` and puts the launch's next two frames
down itself: `sportsngen.sim.rollout` does both.)
"""

from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import KVCache, SportsNGEN, baller2vec_mask
from sportsngen.model.event_classifier import EventClassifier
from sportsngen.model.export import load_model, save_model
from sportsngen.model.sampling import sample_top_p, top_p_filter

__all__ = ["EventClassifier", "KVCache", "ModelConfig", "SportsNGEN", "baller2vec_mask",
           "load_model", "sample_top_p", "save_model", "top_p_filter"]
