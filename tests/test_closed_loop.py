"""Closed-loop training windows (closest-of-K): the expert's target, drift, the record taking
over, the loss mask, and training through train.py with closed_loop and an EMA."""

from pathlib import Path

import pytest
import torch
from hydra import compose, initialize_config_dir
from torch.utils.data import default_collate

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.data.toy import make_toy_rallies
from sportsngen.model import load_model
from sportsngen.model.inputs import BALL
from sportsngen.train.closed_loop import (
    ClosedLoopConfig,
    closest_of_k,
    drift_m,
    expert_next_m,
    mix_closed_loop,
)
from sportsngen.train.module import DecoderModule
from sportsngen.train.run import build_model_config, train_from_config
from sportsngen.train.windows import WindowDataset

torch.set_num_threads(1)
REPO = Path(__file__).resolve().parents[1]
TINY = dict(d_model=32, n_layers=2, n_heads=2, ff_mult=2, dropout=0.1, id_dim=8,
            embed_hidden=(32,), score_hidden=16, n_bins=11, head="factorised", head_hidden=16,
            bin_centre="cv", window_s=1.0)


@pytest.fixture(scope="module")
def module_batch():
    toy = make_toy_rallies(10, seed=1)
    vocab = Vocab.from_data(toy)
    cfg = build_model_config(TINY, toy.fps, vocab)
    torch.manual_seed(0)
    mod = DecoderModule(cfg.to_dict(), vocab.to_dict())
    arrays = rally_arrays(toy, vocab)
    ds = WindowDataset(arrays, cfg.window_frames)
    # The last window of a rally is padded: rows with and without a next frame at the end.
    batch = default_collate([ds[i] for i in range(len(ds))][:12])
    assert not batch["has_next"].all()
    return mod, batch


def _roll(mod, batch, seed=0, **kw):
    g = torch.Generator()
    g.manual_seed(seed)
    return closest_of_k(mod.model, batch, ClosedLoopConfig(fraction=1.0, **kw), g)


def test_expert_target_is_the_recorded_change_of_velocity():
    fps = 25.0
    rec_pos = torch.zeros(3, 3)
    rec_pos[BALL] = torch.tensor([1.0, 2.0, 1.0])
    rec_vel = torch.zeros(3, 3)
    rec_vel[0] = torch.tensor([2.5, 0.0, 0.0])
    rec_vel[BALL] = torch.tensor([25.0, 0.0, 5.0])
    rec_next = rec_pos + rec_vel / fps
    rec_next[0, 0] += 0.004                 # the server accelerates: +0.1 m/s this frame
    rec_next[BALL, 2] -= 0.0157             # gravity's step on the ball
    # The record's own state: its own next frame, exactly.
    torch.testing.assert_close(expert_next_m(rec_pos, rec_vel, rec_pos, rec_vel, rec_next, fps),
                               rec_next)
    # Shifted 5 cm and 1 m/s slower in x: the same change of velocity from there.
    pos = rec_pos + torch.tensor([0.05, 0.0, 0.0])
    vel = rec_vel - torch.tensor([1.0, 0.0, 0.0])
    out = expert_next_m(pos, vel, rec_pos, rec_vel, rec_next, fps)
    torch.testing.assert_close(out, rec_next + torch.tensor([0.05 - 0.04, 0.0, 0.0]))
    # The ball is never sent below the ground.
    low = rec_pos.clone()
    low[BALL, 2] = 0.001
    assert expert_next_m(low, rec_vel * 0, rec_pos, rec_vel, rec_next, fps)[BALL, 2] == 0.0


def test_drift_is_planar_for_players_and_3d_for_the_ball():
    a = torch.zeros(3, 3)
    b = torch.zeros(3, 3)
    b[0] = torch.tensor([3.0, 4.0, 7.0])      # a player's z is not his position
    b[BALL] = torch.tensor([0.0, 3.0, 4.0])
    torch.testing.assert_close(drift_m(b, a), torch.tensor([5.0, 0.0, 5.0]))


def test_rollout_keeps_the_prefix_limits_drift_and_computes_velocities(module_batch):
    mod, batch = module_batch
    mod.train()
    cfg = dict(k=4, start_frames=3, max_player_drift_m=0.05, max_ball_drift_m=0.02)
    out = _roll(mod, batch, **cfg)
    assert mod.training                                 # the mode it was in
    fps = mod.cfg.fps
    torch.testing.assert_close(out["pos_m"][:, :3], batch["pos_m"][:, :3], rtol=0, atol=0)
    torch.testing.assert_close(out["vel_mps"][:, :3], batch["vel_mps"][:, :3], rtol=0, atol=0)
    hn, valid = batch["has_next"], batch["valid"]
    # Snapping: no object further from the record than its limit, anywhere.
    limit = torch.tensor([0.05, 0.05, 0.02])
    assert (out["drift_m"] <= limit + 1e-6).all()
    assert out["token_mask"].equal(hn[..., None].expand_as(out["token_mask"]))
    # The untrained model drifts, so the record took over somewhere, and not everywhere.
    snapped = out["snapped"]
    assert snapped.any() and not snapped[hn].all()
    # Where the model's own sample stands, the velocity is its backward difference.
    own = valid[:, 1:, None] & ~snapped[:, 1:] & (torch.arange(1, hn.shape[1]) >= 3)[:, None]
    diff = (out["pos_m"][:, 1:] - out["pos_m"][:, :-1]) * fps
    torch.testing.assert_close(out["vel_mps"][:, 1:][own], diff[own], rtol=1e-5, atol=1e-4)
    # Where the record took over, position and velocity are the record's.
    torch.testing.assert_close(out["pos_m"][snapped], batch["pos_m"][snapped], rtol=0, atol=0)
    torch.testing.assert_close(out["vel_mps"][snapped], batch["vel_mps"][snapped],
                               rtol=0, atol=0)
    # Players stay on the ground; padding frames are left as they were.
    assert (out["pos_m"][..., :BALL, 2] == 0).all()
    torch.testing.assert_close(out["pos_m"][~valid], batch["pos_m"][~valid], rtol=0, atol=0)
    # On the recorded prefix the targets are the record's next frames.
    torch.testing.assert_close(out["next_pos_m"][:, :2], batch["next_pos_m"][:, :2])


def test_more_candidates_stay_nearer_the_record(module_batch):
    mod, batch = module_batch
    hn = batch["has_next"]
    wide = dict(max_player_drift_m=50.0, max_ball_drift_m=50.0)   # no snapping
    one = _roll(mod, batch, k=1, **wide)["drift_m"][hn].mean()
    many = _roll(mod, batch, k=16, **wide)["drift_m"][hn].mean()
    assert many < 0.5 * one, (float(one), float(many))
    # Masking instead of snapping: the drifted frames leave the loss.
    masked = _roll(mod, batch, k=1, on_drift="mask", max_player_drift_m=0.05,
                   max_ball_drift_m=0.02)
    assert not masked["snapped"].any()
    far = (masked["drift_m"] > torch.tensor([0.05, 0.05, 0.02])).any(-1) & hn
    assert far.any()
    assert not masked["token_mask"][far].any() and masked["token_mask"][hn & ~far].all()


def test_same_seed_same_rollout(module_batch):
    mod, batch = module_batch
    a, b = _roll(mod, batch, seed=3, k=4), _roll(mod, batch, seed=3, k=4)
    assert torch.equal(a["pos_m"], b["pos_m"])
    c = _roll(mod, batch, seed=4, k=4)
    assert not torch.equal(a["pos_m"], c["pos_m"])


def test_mixed_batch_and_the_token_masked_loss(module_batch):
    mod, batch = module_batch
    cfg = ClosedLoopConfig(fraction=0.25, k=2)
    assert cfg.n_rows(12) == 3 and cfg.n_rows(1) == 1 and ClosedLoopConfig().n_rows(12) == 0
    g = torch.Generator()
    g.manual_seed(0)
    out = mix_closed_loop(mod.model, batch, cfg, g)
    assert out["closed_loop"].tolist() == [True] * 3 + [False] * 9
    for key in ("pos_m", "vel_mps", "next_pos_m"):
        assert torch.equal(out[key][3:], batch[key][3:]), key
    assert not torch.equal(out["pos_m"][:3], batch["pos_m"][:3])
    with torch.no_grad():
        _, _, _, p_nll, b_nll = mod._forward(batch)
        plain = mod.loss(p_nll, b_nll, batch)
        full = dict(batch, token_mask=batch["has_next"][..., None].expand(-1, -1, 3))
        torch.testing.assert_close(mod.loss(p_nll, b_nll, full), plain)
        # Dropping one object's tokens leaves its NLL out of the loss.
        drop = full["token_mask"].clone()
        drop[..., BALL] = False
        only_players = mod.loss(p_nll, b_nll, dict(batch, token_mask=drop))
        m = batch["has_next"].float()
        expect = 2.0 * (p_nll * m[..., None]).sum() / (2 * m.sum()) / 3.0
        torch.testing.assert_close(only_players, expect)


@pytest.mark.parametrize("bad, match", [({"fraction": 1.5}, "fraction"), ({"k": 0}, "k"),
                                        ({"start_frames": 0}, "start_frames"),
                                        ({"top_p": 0.0}, "top_p"),
                                        ({"max_ball_drift_m": 0.0}, "drift"),
                                        ({"on_drift": "ignore"}, "on_drift")])
def test_bad_closed_loop_settings_are_refused(bad, match):
    with pytest.raises(ValueError, match=match):
        ClosedLoopConfig(**bad)


def _compose(overrides):
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base=None):
        return compose(config_name="train", overrides=overrides)


def test_train_py_with_closed_loop_and_ema_resumes(tmp_path, monkeypatch):
    monkeypatch.setenv("SPORTSNGEN_CACHE", str(tmp_path / "cache"))
    fast = ["experiment=tiny", "data=toy", "data.n_rallies=12", "trainer.max_steps=3",
            "trainer.val_check_interval=3", "trainer.limit_val_batches=1",
            "trainer.enable_progress_bar=false", "events.enabled=false",
            "closed_loop.fraction=0.5", "closed_loop.k=2", "ema_decay=0.5"]
    out = tmp_path / "run"
    summary = train_from_config(_compose(fast), out)
    assert 0.0 < summary["decoder"]["train/cl_kept"] <= 1.0
    ckpt = torch.load(out / "checkpoints_decoder" / "last.ckpt", weights_only=False)
    # The checkpoint holds the average for export and the live weights for resuming.
    assert "current_model_state" in ckpt and "averaging_state" in ckpt
    exported = load_model(out / "model.pt")[0].state_dict()
    key = "ln_f.weight"
    assert torch.equal(exported[key], ckpt["state_dict"][f"model.{key}"])
    assert not torch.equal(exported[key], ckpt["current_model_state"][f"model.{key}"])
    resumed = train_from_config(_compose([*fast, "trainer.max_steps=5",
                                          f"resume={out / 'checkpoints_decoder' / 'last.ckpt'}"]),
                                tmp_path / "resumed")
    assert "train/loss" in resumed["decoder"]
    again = torch.load(tmp_path / "resumed" / "checkpoints_decoder" / "last.ckpt",
                       weights_only=False)
    assert again["global_step"] == 5 and "averaging_state" in again
    with pytest.raises(ValueError, match="ema_decay"):
        train_from_config(_compose([*fast, "ema_decay=1.5"]), tmp_path / "bad")


def test_rollout_summary_counts_tokens_with_a_next_frame(module_batch):
    from sportsngen.train.closed_loop import rollout_summary

    mod, batch = module_batch
    out = _roll(mod, batch, k=2, max_player_drift_m=0.05, max_ball_drift_m=2.0)
    s = rollout_summary(out)
    hn = batch["has_next"]
    assert s["kept"] == 1.0
    assert s["snapped_ball"] == pytest.approx(float(out["snapped"][hn][:, BALL].float().mean()))
    # Frames the record took over have no drift; the others stay within the limit.
    assert 0 <= s["drift_ball_p50_m"] <= s["drift_ball_p90_m"] <= 2.0 + 1e-6
    assert s["drift_ball_p90_m"] > 0
    assert rollout_summary(dict(out, has_next=torch.zeros_like(hn))) == {}
