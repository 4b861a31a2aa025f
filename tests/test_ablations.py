"""Ablation switches: ModelConfig fields (features, use_context, id_dim 0), the embedding that
honours them, the conf/experiment/ablation_*.yaml configs and the bundled model's unchanged
outputs."""

from pathlib import Path

import pytest
import torch
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from sportsngen.data.tokens import Vocab
from sportsngen.model import EventClassifier, ModelConfig, SportsNGEN, load_model, save_model
from sportsngen.model.config import FEATURE_GROUPS
from sportsngen.model.inputs import N_FEATURES
from sportsngen.studies.ablations import overrides
from sportsngen.train.module import DecoderModule
from sportsngen.train.run import build_model_config

torch.set_num_threads(1)
REPO = Path(__file__).resolve().parents[1]
BUNDLED = REPO / "sportsngen/model/bundled/sportsngen-small.pt"
VOCAB = Vocab(players=("A", "B", "C"), tournaments=("T1",))   # 5 identities, 2 tournaments
ALL = ("position", "velocity", "distance", "time")

# What each experiment config must change relative to the full model (flattened keys).
EXPECTED = {
    "baseline": {"model.features": ["position"], "model.use_context": False},
    "no_velocity": {"model.features": ["position", "distance", "time"]},
    "no_distance": {"model.features": ["position", "velocity", "time"]},
    "no_time": {"model.features": ["position", "velocity", "distance"]},
    "no_context": {"model.use_context": False},
    "ball_noise": {"windows.augment.ball_noise": True},
    "id0": {"model.id_dim": 0},
    "id4": {"model.id_dim": 4},
    "id20": {"model.id_dim": 20},
    "id64": {"model.id_dim": 64},
}


def _compose(overrides: list[str]):
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base=None):
        return compose(config_name="train", overrides=overrides)


def _flat(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def tiny_cfg(**kw) -> ModelConfig:
    base = dict(d_model=32, n_layers=2, n_heads=2, ff_mult=2, dropout=0.0, id_dim=8,
                embed_hidden=(32,), score_hidden=16, n_bins=9, head="factorised",
                head_hidden=16, window_s=0.4, fps=25.0, n_ids=5, n_tournaments=2,
                event_d_model=16, event_layers=1, event_heads=2)
    base.update(kw)
    return ModelConfig(**base)


def make_model(**kw) -> SportsNGEN:
    torch.manual_seed(0)
    return SportsNGEN(tiny_cfg(**kw)).eval()


def inputs(b: int = 2, t: int = 6, seed: int = 0):
    g = torch.Generator().manual_seed(seed)
    feats = torch.randn(b, t, 3, N_FEATURES, generator=g)
    ident = torch.tensor([[2, 3, 0], [4, 1, 0]])[:b]
    ctx = (torch.tensor([0, 2])[:b], torch.tensor([1, 0])[:b], torch.tensor([0, 1])[:b],
           torch.rand(b, 7, generator=g))
    return feats, ident, ctx


@torch.no_grad()
def outputs(model: SportsNGEN, feats, ident, ctx) -> torch.Tensor:
    """Every head's logits of dimension 0 and the decoder states, as one vector."""
    h = model(feats, ident, model.context_tokens(*ctx))
    return torch.cat([h.flatten(), model.player_head.first(h[..., :2, :]).flatten(),
                      model.ball_head.first(h[..., 2, :]).flatten()])


# --- configs ------------------------------------------------------------------------------

def test_model_config_defaults_old_dicts_and_validation():
    old = tiny_cfg().to_dict()
    del old["features"], old["use_context"]          # a config saved before the ablations
    cfg = ModelConfig.from_dict(old)
    assert cfg.features == ALL and cfg.use_context is True
    assert ModelConfig.from_dict(cfg.to_dict()) == cfg
    # Any order or repetition of groups gives the canonical order.
    assert tiny_cfg(features=["time", "position", "time"]).features == ("position", "time")
    assert tiny_cfg(features=["time", "position"]).to_dict()["features"] == ["position", "time"]
    for bad in (["position", "speed"], []):
        with pytest.raises(ValueError, match="model.features"):
            tiny_cfg(features=bad)
    with pytest.raises(ValueError, match="id_dim"):
        tiny_cfg(id_dim=-1)
    assert [c for g in ALL for c in range(*FEATURE_GROUPS[g])] == list(range(N_FEATURES))


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_each_ablation_changes_only_its_switch_and_builds(name):
    base = _flat(OmegaConf.to_container(_compose(overrides("default", 10, 0)), resolve=True))
    cfg = _compose(overrides(name, 10, 0))
    flat = _flat(OmegaConf.to_container(cfg, resolve=True))
    diff = {k: flat.get(k) for k in set(base) | set(flat) if base.get(k) != flat.get(k)}
    assert diff == EXPECTED[name]
    assert cfg.model.d_model == 32 and cfg.data.name == "synthetic_tiny"   # tiny scale
    model_cfg = build_model_config(OmegaConf.to_container(cfg.model, resolve=True), 25.0, VOCAB)
    model = SportsNGEN(model_cfg).eval()
    feats, ident, ctx = inputs()
    assert outputs(model, feats, ident, ctx).isfinite().all()
    kept = sum(e - s for g, (s, e) in FEATURE_GROUPS.items() if g in model_cfg.features)
    assert model.embed.mlp[0].in_features == kept + model_cfg.id_dim


def test_ablation_configs_default_to_the_small_model_and_data():
    cfg = _compose(["experiment=ablation_baseline"])
    assert cfg.model.d_model == 128 and cfg.data.name == "synthetic_small"
    assert list(cfg.model.features) == ["position"] and cfg.model.use_context is False


# --- the switches act -----------------------------------------------------------------------

@pytest.mark.parametrize("group", ["velocity", "distance", "time"])
def test_a_disabled_feature_group_has_no_effect(group):
    feats, ident, ctx = inputs()
    changed = feats.clone()
    s, e = FEATURE_GROUPS[group]
    changed[..., s:e] += torch.randn(changed[..., s:e].shape, generator=torch.Generator()
                                     .manual_seed(3)) * 2.0
    full = make_model()
    assert (outputs(full, feats, ident, ctx) - outputs(full, changed, ident, ctx)).abs().max() \
        > 1e-3
    ablated = make_model(features=[g for g in ALL if g != group])
    assert torch.equal(outputs(ablated, feats, ident, ctx),
                       outputs(ablated, changed, ident, ctx))
    # The event classifier reads the same kept features.
    torch.manual_seed(0)
    g = EventClassifier(ablated.cfg).eval()
    with torch.no_grad():
        a, b = g(feats), g(changed)
    assert all(torch.equal(a[k], b[k]) for k in a)


def test_without_context_surface_and_score_change_nothing_and_the_cache_agrees():
    feats, ident, ctx = inputs()
    other = (ctx[0].flip(0), ctx[1].flip(0), 1 - ctx[2], ctx[3] + 1.0)
    full = make_model()
    assert (outputs(full, feats, ident, ctx) - outputs(full, feats, ident, other)).abs().max() \
        > 1e-3
    model = make_model(use_context=False)
    assert torch.equal(outputs(model, feats, ident, ctx), outputs(model, feats, ident, other))
    c = model.context_tokens(*ctx)
    assert c.shape == (2, 4, 32)
    with torch.no_grad():
        h = model(feats, ident, c)
        cache = model.init_cache(ident, model.context_tokens(*other))
        steps = [model.forward_step(feats[:, i], cache)[0] for i in range(feats.shape[1])]
    torch.testing.assert_close(torch.stack(steps, dim=1), h, atol=1e-4, rtol=0)


def test_identity_size_zero_runs_and_ignores_who_plays():
    model = make_model(id_dim=0)
    feats, ident, ctx = inputs()
    assert model.embed.mlp[0].in_features == N_FEATURES
    other = torch.tensor([[4, 2, 1], [3, 3, 3]])
    out = outputs(model, feats, ident, ctx)
    assert out.isfinite().all()
    assert torch.equal(out, outputs(model, feats, other, ctx))
    assert (out - outputs(make_model(), feats, other, ctx)).abs().max() > 1e-3


@pytest.mark.filterwarnings("ignore:You are trying to `self.log\\(\\)`")
def test_ablated_model_trains_and_exports(tmp_path):
    """Positions only, no context, no identity: the loss falls on a fixed batch, the constant
    context tokens learn without weight decay, and the model file round-trips."""
    cfg = tiny_cfg(features=["position"], use_context=False, id_dim=0)
    torch.manual_seed(0)
    mod = DecoderModule(cfg.to_dict(), VOCAB.to_dict(), lr=3e-3, warmup_steps=1)
    opt = mod.configure_optimizers()["optimizer"]
    const = mod.model.context.constant
    assert any(p is const for p in opt.param_groups[1]["params"])      # no weight decay
    g = torch.Generator().manual_seed(1)
    b, t = 4, 10
    pos = torch.cumsum(torch.randn(b, t + 1, 3, 3, generator=g) * 0.05, dim=1)
    pos[..., :2, 2] = 0.0
    vel = torch.cat([torch.zeros(b, 1, 3, 3), (pos[:, 1:] - pos[:, :-1]) * 25.0], dim=1)
    batch = {"pos_m": pos[:, :t], "vel_mps": vel[:, :t], "next_pos_m": pos[:, 1:],
             "t_s": torch.arange(t).float().expand(b, t) / 25.0,
             "has_next": torch.ones(b, t, dtype=torch.bool),
             "valid": torch.ones(b, t, dtype=torch.bool),
             "ident": torch.tensor([[2, 3, 0]] * b), "surface": torch.zeros(b, dtype=torch.long),
             "tournament": torch.zeros(b, dtype=torch.long),
             "serve": torch.zeros(b, dtype=torch.long), "score": torch.zeros(b, 7)}
    before = const.detach().clone()
    losses = []
    for _ in range(25):
        opt.zero_grad()
        loss = mod.training_step(batch, 0)
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert losses[-1] < 0.7 * losses[0], losses
    assert not torch.equal(before, const.detach())
    path = save_model(tmp_path / "m.pt", mod.model.eval(), VOCAB)
    loaded, _, _, cfg2 = load_model(path)
    assert cfg2 == mod.model.cfg and cfg2.features == ("position",)
    feats, ident, ctx = inputs()
    assert torch.equal(outputs(loaded, feats, ident, ctx), outputs(mod.model, feats, ident, ctx))


# --- backward compatibility -----------------------------------------------------------------

def test_default_embedding_is_the_plain_identity_and_features_mlp():
    """The full model's embeddings compute exactly what they did before the switches."""
    model = make_model()
    feats, ident, ctx = inputs()
    emb, c = model.embed, model.context
    with torch.no_grad():
        e = emb.identity(ident)[:, None].expand(*feats.shape[:-1], -1)
        assert torch.equal(emb(feats, ident), emb.mlp(torch.cat([e, feats], dim=-1)))
        assert torch.equal(c(*ctx), torch.stack([c.surface(ctx[0]), c.tournament(ctx[1]),
                                                 c.serve(ctx[2]), c.score(ctx[3])], dim=1))


def test_bundled_model_loads_with_defaults():
    """The bundled file predates the ablation switches: its saved config lacks them and loads
    with the defaults (the full model), which round-trip."""
    blob = torch.load(BUNDLED, map_location="cpu", weights_only=True)
    model, ec, _, cfg = load_model(BUNDLED)
    assert cfg.features == ALL and cfg.use_context is True
    assert ModelConfig.from_dict(cfg.to_dict()) == cfg
    saved = blob["config"]
    assert {k: v for k, v in cfg.to_dict().items() if k in saved} == saved
    old = {k: v for k, v in saved.items() if k not in ("features", "use_context")}
    assert ModelConfig.from_dict(old) == cfg
