"""Training: loss goes down, frozen fine-tuning, NaN errors, data sources, train.py via Hydra
(checkpoint, resume, config mismatch, fine-tune a player) and one DDP run on 2 CPU processes."""

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_dir
from torch.utils.data import default_collate

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.data.toy import make_toy_rallies
from sportsngen.model import load_model
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.export import read_extra, update_extra
from sportsngen.model.inputs import GENERIC_ID, N_SPECIAL_IDS
from sportsngen.train.datamodule import load_rally_data
from sportsngen.train.evaluate import data_config, evaluate_held_out, metrics_table
from sportsngen.train.finetune import (
    add_player,
    average_generic_identity,
    check_data_matches,
    player_rallies,
)
from sportsngen.train.metrics import NextFrameMetrics
from sportsngen.train.module import (
    PLAYER_TOKEN_WEIGHTS,
    DecoderModule,
    movement_changes,
    movement_onsets,
)
from sportsngen.train.run import build_model_config, train_from_config
from sportsngen.train.windows import WindowDataset

torch.set_num_threads(1)
REPO = Path(__file__).resolve().parents[1]
TINY = dict(d_model=32, n_layers=2, n_heads=2, ff_mult=2, dropout=0.0, id_dim=8,
            embed_hidden=(32,), score_hidden=16, n_bins=11, head="factorised", head_hidden=16,
            bin_centre="cv", window_s=1.0)


@pytest.fixture(autouse=True)
def _no_user_cache(tmp_path, monkeypatch):
    """Nothing here may read or write the user's synthetic-data cache."""
    monkeypatch.setenv("SPORTSNGEN_CACHE", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def toy():
    return make_toy_rallies(10, seed=1)


def module_and_batch(toy, generic=False, **kw):
    vocab = Vocab.from_data(toy, generic=generic)
    cfg = build_model_config({**TINY, "generic_identity": generic}, toy.fps, vocab)
    torch.manual_seed(0)
    mod = DecoderModule(cfg.to_dict(), vocab.to_dict(), lr=3e-3, warmup_steps=1, **kw)
    arrays = rally_arrays(toy, vocab)
    batch = default_collate([WindowDataset(arrays, cfg.window_frames)[i] for i in range(8)])
    return mod, batch, vocab


def test_a_few_steps_reduce_the_loss_on_a_fixed_batch(toy):
    mod, batch, _ = module_and_batch(toy)
    opt = mod.configure_optimizers()["optimizer"]
    losses = []
    for _ in range(25):
        opt.zero_grad()
        loss = mod.training_step(batch, 0)
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert losses[-1] < 0.6 * losses[0], losses


def test_a_batch_with_nothing_for_the_part_trained_alone_is_skipped(toy):
    # A serve head trained alone (train_only) on windows that hold no serve has nothing to
    # learn: the step is skipped rather than backpropagating a loss without a gradient.
    vocab = Vocab.from_data(toy)
    cfg = build_model_config({**TINY, "serve_head": True, "ball_centre": "physics"}, toy.fps,
                             vocab)
    mod = DecoderModule(cfg.to_dict(), vocab.to_dict(), train_only="serve_head")
    arrays = rally_arrays(toy, vocab)
    batch = default_collate([WindowDataset(arrays, cfg.window_frames)[i] for i in range(8)])
    no_targets = {**batch, "has_next": torch.zeros_like(batch["has_next"])}
    assert mod.training_step(no_targets, 0) is None
    loss = mod.training_step(batch, 0)       # the toy rallies' serves are in their first window
    loss.backward()
    grads = {n for n, p in mod.model.named_parameters() if p.grad is not None}
    assert grads and all(n.startswith("serve_head.") for n in grads)


def test_frozen_finetuning_changes_only_the_new_identity(toy):
    base, batch, vocab = module_and_batch(toy, generic=True)
    model, vocab2, row = add_player(base.model, vocab, "Toy Alpha")
    assert row == 2 and vocab2.players == ("Toy Alpha",)
    old = model.embed.identity.weight.detach().clone()
    assert torch.equal(old[row], old[GENERIC_ID])  # starts from the generic identity
    mod = DecoderModule(model.cfg.to_dict(), vocab2.to_dict(), lr=1e-2, warmup_steps=1,
                        trainable_id_rows=[row])
    mod.model.load_state_dict(model.state_dict())
    before = {k: v.clone() for k, v in mod.model.state_dict().items()}
    mine = rally_arrays(player_rallies(toy, "Toy Alpha", 4), vocab2, unknown="generic")
    batch = default_collate([WindowDataset(mine, 25)[i] for i in range(6)])
    assert (batch["ident"][:, :2] == row).any()
    opt = mod.configure_optimizers()["optimizer"]
    for _ in range(3):
        opt.zero_grad()
        mod.training_step(batch, 0).backward()
        opt.step()
    after = mod.model.state_dict()
    changed = [k for k in before if not torch.equal(before[k], after[k])]
    assert changed == ["embed.identity.weight"]
    w0, w1 = before["embed.identity.weight"], after["embed.identity.weight"]
    moved = (w0 != w1).any(dim=1).nonzero().flatten().tolist()
    assert moved == [row]


def test_unknown_players_of_a_named_model_play_as_the_players_mean(toy):
    named, _, vocab = module_and_batch(toy)
    w = named.model.embed.identity.weight
    assert vocab.players and average_generic_identity(named.model, vocab)
    torch.testing.assert_close(w[GENERIC_ID], w[N_SPECIAL_IDS:].mean(dim=0))
    model, _, row = add_player(named.model, vocab, "Somebody New")
    assert torch.equal(model.embed.identity.weight[row], w[GENERIC_ID])
    generic, _, gvocab = module_and_batch(toy, generic=True)   # its generic row is trained
    before = generic.model.embed.identity.weight.detach().clone()
    assert not average_generic_identity(generic.model, gvocab)
    assert torch.equal(generic.model.embed.identity.weight, before)


def test_nan_in_a_batch_raises_naming_the_rally(toy):
    mod, batch, _ = module_and_batch(toy)
    batch["vel_mps"][3, 2, 1, 0] = float("nan")
    with pytest.raises(ValueError, match=f"rally {int(batch['rally_id'][3])}"):
        mod.training_step(batch, 0)


def test_data_sources(tmp_path, toy):
    assert len(load_rally_data({"source": "toy", "n_rallies": 3, "seed": 0})) == 3
    toy.save(tmp_path / "tr")
    back = load_rally_data({"source": "folder", "path": str(tmp_path / "tr")})
    assert back.frames.equals(toy.frames)
    with pytest.raises(ValueError, match="data.source must be one of"):
        load_rally_data({"source": "csv"})
    with pytest.raises(ValueError, match="set data.source=synthetic"):
        load_rally_data({"source": "toy", "n_rallies": 3, "players": ["x"]})


def test_data_mismatch_is_a_clear_error(toy):
    vocab = Vocab.from_data(toy)
    cfg = build_model_config(TINY, toy.fps, vocab)
    check_data_matches(cfg, vocab, toy)
    with pytest.raises(ValueError, match="trained at 25 Hz but the data is 50 Hz"):
        check_data_matches(cfg, vocab, make_toy_rallies(2, 0, fps=50.0))
    with pytest.raises(ValueError, match="model.fps is 50"):
        build_model_config({**TINY, "fps": 50.0}, 25.0, vocab)
    with pytest.raises(ValueError, match="unknown model config keys"):
        ModelConfig.from_dict({**TINY, "layers": 3})


def _compose(overrides):
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base=None):
        return compose(config_name="train", overrides=overrides)


def test_train_py_through_hydra_resume_mismatch_and_finetune(tmp_path, monkeypatch):
    fast = ["experiment=tiny", "data=toy", "data.n_rallies=16", "trainer.max_steps=4",
            "trainer.val_check_interval=2", "trainer.limit_val_batches=1",
            "trainer.enable_progress_bar=false", "events.max_steps=2",
            "model.generic_identity=true"]
    out = tmp_path / "run"
    summary = train_from_config(_compose([*fast, "trainer.limit_val_batches=1.0"]), out)
    assert {"val/nll_ball", "val/cv_nll_ball", "val/acc_player", "val/acc_ball_flight",
            "val/acc_ball_contact", "val/cv_nll_ball_contact"} <= set(summary["decoder"])
    # The evaluation script's held-out rallies are the validation split: same figures.
    held = evaluate_held_out(out / "model.pt", batch_size=5)
    assert held["n_rallies"] == 2 and held["data"] == "toy"  # round(16 * 0.1)
    for k in ("nll_ball", "nll_player", "acc_ball_flight", "cv_nll_ball", "loss"):
        assert held[k] == pytest.approx(summary["decoder"][f"val/{k}"], rel=1e-5, abs=1e-6), k
    assert len(metrics_table(held)) == 6
    with pytest.warns(UserWarning, match="differ from the data the model was trained on"):
        evaluate_held_out(out / "model.pt", {"source": "toy", "n_rallies": 16, "seed": 5})
    assert (out / "decoder" / "metrics.csv").exists() and (out / "summary.json").exists()
    model, ec, vocab, cfg = load_model(out / "model.pt")
    assert ec is not None and vocab.players == () and cfg.generic_identity
    import sportsngen.train.evaluate as evaluate

    with monkeypatch.context() as mp:  # regenerated data that changed: refuse, say why
        mp.setattr(evaluate, "data_fingerprint", lambda data: "0" * 16)
        with pytest.raises(ValueError, match="differ from the data the model was trained on"):
            evaluate_held_out(out / "model.pt")
    last = out / "checkpoints_decoder" / "last.ckpt"
    # The state the run ended in, whatever its last validation said.
    assert torch.load(last, weights_only=False, map_location="cpu")["global_step"] == 4

    # Resume to more steps from the last checkpoint.
    summary2 = train_from_config(
        _compose([*fast, "trainer.max_steps=6", f"resume={last}", "events.enabled=false"]),
        tmp_path / "resumed")
    assert "val/loss" in summary2["decoder"]
    # A checkpoint made with another config cannot be resumed.
    with pytest.raises(ValueError, match=r"different model config \(differs in \['d_model'"):
        train_from_config(_compose([*fast, "model.d_model=16", f"resume={last}"]),
                          tmp_path / "bad")

    # Fine-tune a player's identity on the generic model (everything else frozen). It samples
    # as its base: the base's simulation defaults are carried over.
    defaults = {"top_p_player": 1.0, "top_p_ball": 0.45, "contact_odds": True}
    speeds = {"pooled_mps": 6.5, "players_mps": {"Toy Beta": 6.1}}
    update_extra(out / "model.pt", sim_defaults=defaults, top_speed=speeds)
    ft = train_from_config(_compose([
        "experiment=finetune_player", "player=Toy Alpha", f"init={out / 'model.pt'}",
        "data=toy", "data.n_rallies=16", "finetune.n_sequences=4", "trainer.max_steps=3",
        "trainer.val_check_interval=3", "trainer.limit_val_batches=1",
        "trainer.enable_progress_bar=false", "windows.val_fraction=0.25"]), tmp_path / "ft")
    m2, ec2, vocab2, cfg2 = load_model(ft["model_file"])
    assert vocab2.players == ("Toy Alpha",) and cfg2.n_ids == 3 and not cfg2.generic_identity
    assert ec2 is not None  # the event classifier of `init` is carried over
    assert ft["player_tables"] == []   # the base has no per-player tables to fit his rows of
    w_old, w_new = model.embed.identity.weight, m2.embed.identity.weight
    assert torch.equal(w_old, w_new[:2]) and not torch.equal(w_new[2], w_old[GENERIC_ID])
    for k, v in model.state_dict().items():
        if k != "embed.identity.weight":
            assert torch.equal(v, m2.state_dict()[k]), k
    # Without freezing, the rest of the model trains too.
    ft3 = train_from_config(_compose([
        "experiment=finetune_player", "player=Toy Alpha", f"init={out / 'model.pt'}",
        "data=toy", "data.n_rallies=16", "finetune.n_sequences=4", "finetune.freeze=false",
        "trainer.max_steps=2", "trainer.val_check_interval=2", "trainer.limit_val_batches=1",
        "trainer.enable_progress_bar=false", "windows.val_fraction=0.25"]), tmp_path / "ft3")
    m3 = load_model(ft3["model_file"])[0]
    assert not torch.equal(m3.ln_f.weight, model.ln_f.weight)

    # Retrain the event classifier alone: no decoder steps, a new g.
    g = train_from_config(_compose([*fast, f"init={out / 'model.pt'}", "trainer.max_steps=0",
                                    "events.retrain=true", "events.max_steps=2"]),
                          tmp_path / "g")
    m4, ec4 = load_model(g["model_file"])[:2]
    # Serve starts: a player's fine-tune adds his to the base pool; a fine-tune on whole
    # data (here the same data) keeps that data's pool alone, never the base's beside it.
    pool = {name: len(read_extra(run["model_file"])["initial_conditions"]["server"])
            for name, run in (("base", summary), ("player", ft), ("data", g))}
    assert pool["data"] == pool["base"] and pool["player"] > pool["base"]
    assert read_extra(ft["model_file"])["sim_defaults"] == defaults
    # ... and its rules' tables (16 toy rallies are too few frames for his own top speed).
    assert read_extra(ft["model_file"])["top_speed"] == speeds
    assert "top_speed" not in read_extra(g["model_file"])
    assert "sim_defaults" not in read_extra(g["model_file"])   # a new model: its own choice
    for k, v in model.state_dict().items():
        assert torch.equal(v, m4.state_dict()[k]), k
    assert not all(torch.equal(v, ec4.state_dict()[k]) for k, v in ec.state_dict().items())

    # Re-centre the ball's bins while fine-tuning: the same weights start, the new centre
    # is saved; a wrong name is refused.
    assert cfg.ball_centre == "velocity"
    rc = train_from_config(_compose([*fast, f"init={out / 'model.pt'}", "trainer.max_steps=0",
                                     "init_ball_centre=physics", "events.enabled=false"]),
                           tmp_path / "rc")
    m5, _, _, cfg5 = load_model(rc["model_file"])
    assert cfg5.ball_centre == "physics" and cfg5.bin_centre == cfg.bin_centre
    for k, v in model.state_dict().items():
        assert torch.equal(v, m5.state_dict()[k]), k
    with pytest.raises(ValueError, match="ball_centre"):
        train_from_config(_compose([*fast, f"init={out / 'model.pt'}", "trainer.max_steps=0",
                                    "init_ball_centre=spin"]), tmp_path / "rc2")


@pytest.mark.parametrize("head", ["ball_sub_head", "strike_head", "serve_head"])
def test_a_head_added_to_a_trained_model_trains_alone(tmp_path, tiny_model_file, head):
    add = {"ball_sub_head": "init_ball_sub_bins=4", "strike_head": "init_strike_head=true",
           "serve_head": "init_serve_head=true"}[head]
    fast = ["experiment=tiny", "data=toy", "data.n_rallies=16", "trainer.val_check_interval=3",
            "trainer.limit_val_batches=1", "trainer.enable_progress_bar=false",
            "events.enabled=false", f"init={tiny_model_file}", add]
    base = load_model(tiny_model_file)[0].state_dict()
    runs = {}
    for steps in (0, 3):
        s = train_from_config(_compose([*fast, f"trainer.max_steps={steps}",
                                        f"train_only={head}"]), tmp_path / f"s{steps}")
        runs[steps] = load_model(s["model_file"])
    m0, m3 = runs[0][0].state_dict(), runs[3][0].state_dict()
    # The decoder and its heads as they were; the new head trained.
    for k, v in base.items():
        assert torch.equal(v, m3[k]), k
    new = [k for k in m3 if k.startswith(f"{head}.")]
    assert new and not all(torch.equal(m0[k], m3[k]) for k in new)
    if head == "ball_sub_head":
        assert runs[3][3].ball_sub_bins == 4
        assert 0 < s["decoder"]["val/sub_nll_ball_flight"] < 3 * math.log(4) + 1.0
    elif head == "strike_head":
        assert runs[3][3].strike_head
        # Toy rallies' balls are struck too; four dimensions of 96 bins, barely trained.
        assert 0 < s["decoder"]["val/strike_nll"] < 4 * math.log(96) + 1.0
    else:
        assert runs[3][3].serve_head and not runs[3][3].strike_head
        # Toy rallies start with a toss and a serve (NaN if none were found).
        assert 0 < s["decoder"]["val/serve_nll"] < 4 * math.log(96) + 1.0
    if head == "ball_sub_head":      # the same check for both heads: run it once
        with pytest.raises(ValueError, match="names no parameter"):
            train_from_config(_compose([*fast, "trainer.max_steps=1", "train_only=nothing"]),
                              tmp_path / "bad")


def test_same_seed_same_weights(tmp_path):
    over = ["experiment=tiny", "data=toy", "data.n_rallies=12", "trainer.max_steps=3",
            "trainer.val_check_interval=3", "trainer.limit_val_batches=1",
            "trainer.enable_progress_bar=false", "events.enabled=false", "seed=7"]
    a = train_from_config(_compose(over), tmp_path / "a")
    b = train_from_config(_compose(over), tmp_path / "b")
    wa = load_model(a["model_file"])[0].state_dict()
    wb = load_model(b["model_file"])[0].state_dict()
    assert all(torch.equal(wa[k], wb[k]) for k in wa)
    c = train_from_config(_compose([*over[:-1], "seed=8"]), tmp_path / "c")
    wc = load_model(c["model_file"])[0].state_dict()
    assert not all(torch.equal(wa[k], wc[k]) for k in wa)


def test_training_windows_of_two_model_windows(tmp_path, monkeypatch):
    from sportsngen.train import run as run_module

    seen = []
    real = run_module.TrackingDataModule

    def spy(data, vocab, window_frames, **kw):
        seen.append(window_frames)
        return real(data, vocab, window_frames, **kw)

    monkeypatch.setattr(run_module, "TrackingDataModule", spy)
    over = ["experiment=tiny", "data=toy", "data.n_rallies=12", "trainer.max_steps=2",
            "trainer.val_check_interval=2", "trainer.limit_val_batches=1",
            "trainer.enable_progress_bar=false", "events.enabled=false",
            "windows.length_windows=2"]
    out = train_from_config(_compose(over), tmp_path / "a")
    cfg = load_model(out["model_file"])[3]
    # The model keeps its window (the band of its mask); only the training windows grow.
    assert seen == [2 * cfg.window_frames]
    assert np.isfinite(out["decoder"]["val/loss"])


@pytest.mark.skipif(sys.platform == "win32", reason="gloo DDP test on POSIX only")
def test_ddp_two_cpu_processes_slow(tmp_path):
    """SLOW (~20-30 s): trainer=ddp runs Lightning's DDP (gloo) on 2 CPU processes."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    cmd = [sys.executable, str(REPO / "train.py"), "experiment=tiny", "trainer=ddp",
           "trainer.max_steps=3", "trainer.val_check_interval=3", "trainer.limit_val_batches=1",
           "trainer.enable_progress_bar=false", "events.enabled=false", "data=toy",
           "data.n_rallies=16", "windows.batch_size=4", "model.window_s=1.0",
           f"hydra.run.dir={tmp_path}"]
    res = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=180)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "distributed_backend=gloo" in res.stderr + res.stdout
    assert "All distributed processes registered" in res.stderr + res.stdout
    assert (tmp_path / "model.pt").exists()


def test_metrics_are_token_sums_not_means_of_batch_means(toy):
    """Two batches' metrics equal those of the two concatenated; the ball splits into flight
    and contact tokens; `vector()` round-trips (the all-reduce layout)."""
    mod, batch, _ = module_and_batch(toy)
    model = mod.model.eval()
    assert batch["near_contact"].any()
    a, b = {k: v[:3] for k, v in batch.items()}, {k: v[3:] for k, v in batch.items()}
    split, whole = NextFrameMetrics(), NextFrameMetrics()
    split.update(model, a)
    split.update(model, b)
    whole.update(model, batch)
    s, w = split.compute(), whole.compute()
    for k, v in w.items():
        # float32 forward, batch shapes differ; NaN where a part is absent (no strike head)
        assert s[k] == pytest.approx(v, rel=1e-6, nan_ok=True), k
    m, near = batch["has_next"], batch["near_contact"]
    assert w["n_ball_contact"] == int((m & near).sum())
    assert w["n_ball_flight"] == int((m & ~near).sum())
    assert w["n_player_tokens"] == 2 * int(m.sum())
    with torch.no_grad():
        _, _, _, p_nll, b_nll = mod._forward(batch)
    assert w["nll_ball"] == pytest.approx(float(b_nll[m].double().mean()), rel=1e-6)
    assert w["nll_ball_contact"] == pytest.approx(float(b_nll[m & near].double().mean()),
                                                  rel=1e-6)
    assert w["nll_player"] == pytest.approx(float(p_nll[m].double().mean()), rel=1e-6)
    assert whole.from_vector(whole.vector()).compute() == w


def test_cv_reference_on_constant_velocity_tracks():
    """Players walking at constant velocity: the CV bin is right at every frame but a rally's
    first (whose backward-difference velocity is 0), and nowhere else."""
    data = make_toy_rallies(3, seed=2)
    vocab = Vocab.from_data(data)
    cfg = build_model_config(TINY, data.fps, vocab)
    arrays = rally_arrays(data, vocab)
    t = arrays.pos_m.shape[0]
    arrays.pos_m[:, :2, 0] = (np.arange(t) * 0.1)[:, None]  # 2.5 m/s along x, every rally
    arrays.pos_m[:, :2, 1] = 1.0
    batch = default_collate([WindowDataset(arrays, 25)[i] for i in range(6)])
    torch.manual_seed(0)
    met = NextFrameMetrics()
    met.update(SportsNGEN(cfg).eval(), batch)
    out = met.compute()
    m = batch["has_next"]
    first = int((m & (batch["t_s"] == 0)).sum())
    assert first >= 1
    assert out["cv_acc_player"] == pytest.approx(1 - first / int(m.sum()), abs=1e-12)


def test_data_configs_of_train_yaml_and_evaluate():
    assert _compose([]).data.name == "synthetic_small"  # the default is the generator's data
    tiny = _compose(["experiment=tiny"])
    assert tiny.data.name == "synthetic_tiny" and tiny.data.source == "synthetic"
    assert _compose(["experiment=tiny", "data=toy"]).data.source == "toy"
    assert data_config("synthetic_tiny")["n_points"] == 300
    assert data_config("toy") == {"source": "toy", "n_rallies": 300, "seed": 0, "fps": 25.0}
    assert data_config(str(REPO / "tests"))["source"] == "folder"
    with pytest.raises(ValueError, match="neither a config in conf/data"):
        data_config("no_such_data")


def _weighted_tokens(kind: str, batch: dict, fps: float) -> torch.Tensor:
    """The tokens a loss weight applies to: the ball's near a contact, the players' starts."""
    if kind == "contact_weight":
        return batch["near_contact"] & batch["has_next"]
    find = PLAYER_TOKEN_WEIGHTS[kind]
    return find(batch["vel_mps"], batch["pos_m"], batch["next_pos_m"], fps) \
        & batch["has_next"][..., None]


@pytest.mark.parametrize("kind", ["contact_weight", *PLAYER_TOKEN_WEIGHTS])
def test_loss_weights_count_only_their_tokens_more(toy, kind):
    mod, batch, _ = module_and_batch(toy)
    tokens = _weighted_tokens(kind, batch, mod.cfg.fps)
    assert tokens.any()
    with torch.no_grad():
        _, _, _, p_nll, b_nll = mod._forward(batch)
        base = mod.loss(p_nll, b_nll, batch)
        mod.hparams[kind] = 4.0
        weighted = mod.loss(p_nll, b_nll, batch)
    # Only those tokens change, each by (4 - 1) times its NLL.
    nll = b_nll if kind == "contact_weight" else p_nll
    extra = 3.0 * (nll * tokens).sum() / batch["has_next"].sum() / 3.0
    torch.testing.assert_close(weighted - base, extra, rtol=1e-5, atol=1e-6)
    with pytest.raises(ValueError, match=kind):
        module_and_batch(toy, **{kind: 0.0})


def test_movement_onsets_are_the_frames_that_start_a_run():
    fps = 25.0
    x = torch.tensor([0.0, 0.0, 0.0, 0.008, 0.024, 0.048, 0.048, 0.048])  # still, runs, stops
    pos = torch.zeros(1, 8, 3, 3)
    pos[0, :, 1, 0] = x
    vel = torch.zeros_like(pos)
    vel[:, 1:] = (pos[:, 1:] - pos[:, :-1]) * fps
    nxt = torch.cat([pos[:, 1:], pos[:, -1:]], dim=1)
    starts = movement_onsets(vel, pos, nxt, fps)
    assert starts[0, :, 1].tolist() == [False, False, True, False, False, False, False, False]
    assert not starts[..., 0].any()         # the server never moves
    # Velocity 0, 0, 0, 0.2, 0.4, 0.6, 0, 0 m/s: the acceleration jumps where the run starts
    # (frame 2: +0.2 a frame after 0), where it stops dead (frame 5: -0.6 after +0.2) and
    # where the stop ends (frame 6: 0 after -0.6).
    changes = movement_changes(vel, pos, nxt, fps)
    assert changes[0, :, 1].tolist() == [False, False, True, False, False, True, True, False]


def test_logger_and_callback_groups_build_each_stage(tmp_path):
    """conf/logger and conf/callbacks: CSV metrics in <run>/<stage> (TensorBoard's only where
    tensorboard is installed), checkpoints in <run>/checkpoints_<stage>, the decoder's best
    by validation loss."""
    from lightning.pytorch.callbacks import ModelCheckpoint
    from lightning.pytorch.loggers import CSVLogger

    from sportsngen.train.run import _callbacks, _installed, _loggers

    cfg = _compose(["experiment=tiny", "data=toy"])
    for stage, monitor in (("decoder", "val/loss"), ("events", None)):
        loggers = _loggers(cfg, tmp_path, stage)
        assert isinstance(loggers[0], CSVLogger)
        assert Path(loggers[0].log_dir) == tmp_path / stage
        assert len(loggers) == 1 + _installed(cfg.logger[stage].tensorboard)
        (ckpt,) = _callbacks(cfg, tmp_path, stage)
        assert isinstance(ckpt, ModelCheckpoint) and ckpt.monitor == monitor
        assert ckpt.dirpath == str(tmp_path / f"checkpoints_{stage}") and ckpt.save_last
    no_tb = _loggers(_compose(["logger.decoder.tensorboard=null"]), tmp_path, "decoder")
    assert [type(x) for x in no_tb] == [CSVLogger]
