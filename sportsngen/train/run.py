"""`train_from_config(cfg)`: what `python train.py` does, callable from Python and tests.

Steps: seed; load rallies (`data.source`); build or load the model (fine-tuning when `init` is
set); fit the decoder with Lightning (checkpoints, resume, CSV/TensorBoard logs, progress bar);
optionally fit the event classifier; export a self-contained model file.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import lightning as L
import torch
from lightning.pytorch.callbacks import EMAWeightAveraging, ModelCheckpoint
from lightning.pytorch.loggers import CSVLogger
from omegaconf import DictConfig, OmegaConf

from sportsngen.data.tokens import Augment, RallyArrays, Vocab
from sportsngen.errors import ModelFileError
from sportsngen.model.config import ModelConfig
from sportsngen.model.embedding import widen_for_extra
from sportsngen.model.export import is_model_file, read_extra, save_model
from sportsngen.model.forecast import FORECAST_FEATURES, INTERCEPT_FEATURES
from sportsngen.sim.initial import InitialConditions
from sportsngen.train.datamodule import TrackingDataModule, data_fingerprint, load_rally_data
from sportsngen.train.expert import load_expert
from sportsngen.train.finetune import (
    add_player,
    average_generic_identity,
    check_data_matches,
    load_pretrained,
    player_rallies,
    read_torch_file,
)
from sportsngen.train.module import TOKEN_WEIGHTS, DecoderModule, EventModule
from sportsngen.train.player_tables import fit_player_tables, player_rule_tables

log = logging.getLogger(__name__)


def _loggers(out_dir: Path, name: str) -> list:
    loggers = [CSVLogger(str(out_dir), name=name, version="")]
    try:
        import tensorboard  # noqa: F401
        from lightning.pytorch.loggers import TensorBoardLogger

        loggers.append(TensorBoardLogger(str(out_dir), name=f"tb_{name}", version=""))
    except ImportError:
        pass
    return loggers


def _container(node) -> dict | None:
    return OmegaConf.to_container(node, resolve=True) if node is not None else None


def _trainer(cfg: DictConfig, out_dir: Path, name: str, max_steps: int,
             ema_decay: float | None = None) -> L.Trainer:
    """The Lightning trainer of one stage: checkpoints (last and best), loggers and, with
    `ema_decay`, an exponential moving average of the weights, which then is what validation
    scores, checkpoints hold and the run exports (Lightning's `EMAWeightAveraging`; the live
    weights stay in the checkpoint for resuming)."""
    kw = OmegaConf.to_container(cfg.trainer, resolve=True)
    kw["max_steps"] = max_steps
    callbacks = [ModelCheckpoint(dirpath=str(out_dir / f"checkpoints_{name}"), save_last=True,
                                 save_top_k=1, monitor="val/loss" if name == "decoder" else None)]
    if ema_decay is not None:
        if not 0.0 < float(ema_decay) < 1.0:
            raise ValueError(f"ema_decay must be in (0, 1), got {ema_decay}")
        callbacks.append(EMAWeightAveraging(decay=float(ema_decay)))
    return L.Trainer(default_root_dir=str(out_dir), logger=_loggers(out_dir, name),
                     callbacks=callbacks, **kw)


def _check_resume(path: str, model_cfg: ModelConfig, vocab: Vocab) -> None:
    """A resumed checkpoint must have been made with this model config and vocabulary."""
    blob = read_torch_file(path, "training checkpoint")
    if is_model_file(blob):
        raise ModelFileError(f"resume={path} is a model file, not a training checkpoint: "
                             "resume takes a checkpoint (<run>/checkpoints_decoder/last.ckpt); "
                             "to train on from a model file, use init=<model file>")
    hp = blob.get("hyper_parameters", {}) if isinstance(blob, dict) else {}
    if "model_cfg" not in hp:
        raise ModelFileError(f"resume={path} is not a DecoderModule training checkpoint (no "
                             "model_cfg hyper-parameters)")
    old = hp.get("model_cfg", {})
    old = ModelConfig.from_dict(old).to_dict() if old else {}   # fields added since: defaults
    diff = sorted(k for k in set(old) | set(model_cfg.to_dict())
                  if old.get(k) != model_cfg.to_dict().get(k))
    if diff:
        raise ValueError(f"checkpoint {path} was trained with a different model config "
                         f"(differs in {diff}); it cannot be resumed on this data/config")
    if hp.get("vocab") != vocab.to_dict():
        raise ValueError(f"checkpoint {path} has a different vocabulary of players/surfaces/"
                         "tournaments than this data")


def build_model_config(model: dict, data_fps: float, vocab: Vocab) -> ModelConfig:
    """The ModelConfig from the Hydra `model` node, the data's frame rate and the vocab."""
    d = dict(model)
    if d.get("fps") is None:
        d["fps"] = data_fps
    elif abs(float(d["fps"]) - data_fps) > 1e-9:
        raise ValueError(f"model.fps is {d['fps']} Hz but the data is {data_fps:g} Hz")
    d["n_ids"] = vocab.n_ids
    d["n_tournaments"] = len(vocab.tournaments) + 1
    d["n_surfaces"] = len(vocab.surfaces)
    return ModelConfig.from_dict(d)


def _expert_arrays(cfg: DictConfig, vocab: Vocab) -> RallyArrays | None:
    """The expert rallies of `expert.path` (scripts/expert_data.py), checked against the
    vocabulary they must have been made with."""
    path = (cfg.get("expert") or {}).get("path")
    if not path:
        return None
    arrays = load_expert(path)
    if int(arrays.ident.max()) >= vocab.n_ids:
        raise ValueError(f"expert rallies {path} name identity {int(arrays.ident.max())}, "
                         f"beyond this model's {vocab.n_ids}: make them with the model "
                         "trained on (scripts/expert_data.py --model = init)")
    targets = int((arrays.length - arrays.learn_from_frames() - 1).clip(0).sum())
    log.info("expert: %d rallies from %s, %d frames to learn", len(arrays.length), path, targets)
    return arrays


def _load_init(model: torch.nn.Module, state: dict) -> None:
    """The `init` model's weights into `model`; only a sub-bin, strike or serve head the init
    lacks (added by `init_ball_sub_bins`, `init_strike_head`, `init_serve_head`) or the strike
    head's role shift (`model.strike_roles`, zero) may be missing, and nothing may be left
    over."""
    missing, unexpected = model.load_state_dict(state, strict=False)
    bad = [k for k in missing
           if not k.startswith(("ball_sub_head.", "strike_head.", "serve_head.",
                                "strike_role."))]
    if bad or unexpected:
        raise ValueError(f"init weights do not fit this model: missing {bad}, unexpected "
                         f"{list(unexpected)}")


def train_from_config(cfg: DictConfig, out_dir: str | Path) -> dict:
    """Train (or fine-tune) as `cfg` says; write checkpoints, logs and `model.pt` in out_dir.
    Returns a summary dict (also written as summary.json)."""
    out_dir = Path(out_dir)
    L.seed_everything(int(cfg.seed), workers=True)
    torch.set_num_threads(int(cfg.get("threads") or torch.get_num_threads()))
    data = load_rally_data(OmegaConf.to_container(cfg.data, resolve=True))
    ft = cfg.get("finetune") or {}
    trainable_rows = None
    init_state = None
    event_model = None
    if cfg.get("init"):
        model, event_model, vocab, model_cfg = load_pretrained(cfg.init)
        if cfg.get("player"):
            data = player_rallies(data, cfg.player, ft.get("n_sequences"))
            model, vocab, row = add_player(model, vocab, cfg.player)
            model_cfg = model.cfg
            trainable_rows = [row] if ft.get("freeze", True) else None
        if cfg.get("init_ball_centre"):
            # Fine-tuning to a new ball bin centre: same weights and shapes, new targets.
            model_cfg = ModelConfig.from_dict({**model_cfg.to_dict(),
                                               "ball_centre": cfg.init_ball_centre})
        if cfg.get("init_frame"):
            # Fine-tuning in another court frame: same weights and shapes. A model trained
            # with the flip augmentation already plays both ends alike.
            model_cfg = ModelConfig.from_dict({**model_cfg.to_dict(), "frame": cfg.init_frame})
        if cfg.get("init_ball_sub_bins") is not None:
            # A sub-bin head added to a trained model: the rest of the weights as they were,
            # the new head from its initialisation (`_load_init`).
            model_cfg = ModelConfig.from_dict({**model_cfg.to_dict(),
                                               "ball_sub_bins": int(cfg.init_ball_sub_bins)})
        if cfg.get("init_strike_head"):
            model_cfg = ModelConfig.from_dict({**model_cfg.to_dict(), "strike_head": True})
        if cfg.get("init_serve_head"):
            model_cfg = ModelConfig.from_dict({**model_cfg.to_dict(), "serve_head": True})
        init_state = model.state_dict()
        if cfg.get("init_ball_forecast") and not model_cfg.ball_forecast:
            # The forecast's columns join the object embedding with zero weights: training
            # starts from the init's function and learns how much to use them.
            model_cfg = ModelConfig.from_dict({**model_cfg.to_dict(), "ball_forecast": True})
            init_state = widen_for_extra(init_state, "embed.", FORECAST_FEATURES)
        if cfg.get("init_ball_intercept") and not model_cfg.ball_intercept:
            if not model_cfg.ball_forecast:
                raise ValueError("init_ball_intercept=true adds columns to the ball's forecast: "
                                 "the init needs model.ball_forecast (or init_ball_forecast=true)")
            model_cfg = ModelConfig.from_dict({**model_cfg.to_dict(), "ball_intercept": True})
            init_state = widen_for_extra(init_state, "embed.", INTERCEPT_FEATURES)
        if cfg.get("init_clock_s") and not model_cfg.clock_s:
            # The clock's column joins the object embedding last, with zero weights.
            model_cfg = ModelConfig.from_dict({**model_cfg.to_dict(),
                                               "clock_s": float(cfg.init_clock_s)})
            init_state = widen_for_extra(init_state, "embed.", 1)
        check_data_matches(model_cfg, vocab, data)
    else:
        if cfg.get("player"):
            raise ValueError("player=... fine-tunes an existing model: also set init=<model "
                             "file or checkpoint>")
        generic = bool(cfg.model.get("generic_identity", False))
        vocab = Vocab.from_data(data, generic=generic)
        model_cfg = build_model_config(OmegaConf.to_container(cfg.model, resolve=True),
                                       data.fps, vocab)
    w = cfg.windows
    dm = TrackingDataModule(
        data, vocab, model_cfg.window_frames * int(w.get("length_windows", 1)),
        batch_size=int(w.batch_size),
        val_fraction=float(w.val_fraction), seed=int(cfg.seed),
        augment=Augment(**OmegaConf.to_container(w.augment, resolve=True)),
        num_workers=int(w.num_workers), unknown=model_cfg.unknown,
        extra_train=_expert_arrays(cfg, vocab))
    opt = cfg.optim
    module = DecoderModule(model_cfg.to_dict(), vocab.to_dict(), lr=float(opt.lr),
                           weight_decay=float(opt.weight_decay),
                           warmup_steps=int(opt.warmup_steps), trainable_id_rows=trainable_rows,
                           closed_loop=_container(cfg.get("closed_loop")),
                           train_only=cfg.get("train_only"),
                           **{k: float(opt.get(k, 1.0)) for k in TOKEN_WEIGHTS})
    if init_state is not None:
        _load_init(module.model, init_state)
    resume = cfg.get("resume")
    if resume:
        _check_resume(resume, model_cfg, vocab)
    trainer = _trainer(cfg, out_dir, "decoder", int(cfg.trainer.max_steps),
                       ema_decay=cfg.get("ema_decay"))
    trainer.fit(module, dm, ckpt_path=resume or None)
    player_tables = None
    if cfg.get("init") and cfg.get("player") and ft.get("fit_tables", True):
        # His rows of the per-player tables, on the rallies his identity row learned from
        # (`train.player_tables`): zero rows would leave him the average player's errors.
        player_tables = fit_player_tables(
            module.model, vocab, data, cfg.player,
            prior_serves=float(ft.get("prior_serves", 100.0)),
            prior_strikes=float(ft.get("prior_strikes", 200.0)))
        log.info("%s's table rows:\n%s", cfg.player, player_tables.round(3).to_string())
    # The checkpoint callback writes last.ckpt only at a validation, and a run whose last step
    # is not one left last.ckpt at an earlier step (a stage resumed from it repeated steps).
    # Written again here, the state the run ended in, for `resume=`. Not with an average of
    # the weights: by now it has replaced the live weights a resume needs (the callback's own
    # last.ckpt holds both).
    if cfg.get("ema_decay") is None:
        trainer.save_checkpoint(str(out_dir / "checkpoints_decoder" / "last.ckpt"))
    summary = {"decoder": {k: float(v) for k, v in trainer.callback_metrics.items()},
               "throughput": module.throughput(), "n_rallies": len(data),
               "n_params": sum(p.numel() for p in module.model.parameters()),
               "out_dir": str(out_dir)}
    if player_tables is not None:
        summary["player_tables"] = player_tables.to_dict("records")
    ev = cfg.get("events") or {}
    # From `init` the base model's classifier is kept unless asked to retrain it
    # (`events.retrain=true`, e.g. with trainer.max_steps=0 to retrain g alone).
    if ev.get("enabled", False) and (not cfg.get("init") or ev.get("retrain", False)):
        em = EventModule(model_cfg.to_dict(), lr=float(ev.get("lr", 1e-3)))
        et = _trainer(cfg, out_dir, "events", int(ev.get("max_steps", 100)))
        et.fit(em, dm)
        event_model = em.model
        summary["events"] = {k: float(v) for k, v in et.callback_metrics.items()}
    if trainer.is_global_zero:
        # The split is recorded so that scripts/evaluate_model.py scores the same held-out
        # rallies (split_rallies(arrays, val_fraction, seed) on the same data).
        split = {"seed": int(cfg.seed), "val_fraction": float(w.val_fraction),
                 "data": OmegaConf.to_container(cfg.data, resolve=True),
                 "player": cfg.get("player"), "n_sequences": ft.get("n_sequences"),
                 "fingerprint": data_fingerprint(data)}
        # The simulator starts its rallies from real first frames of the training data. A
        # player's fine-tune adds his serves to the base model's pool; any other fine-tune
        # learns the data it is given, so its pool is that data's alone: serve starts of the
        # data the base model saw (an older generator version) left 34 % of a version-6
        # fine-tune's service points without a serve struck, 12 % with its own starts
        # (docs/evaluation.md).
        init = InitialConditions.from_rally_data(data)
        base_extra: dict = {}
        if cfg.get("init") and cfg.get("player"):
            try:
                base_extra = read_extra(cfg.init)
            except ValueError:   # a Lightning checkpoint carries no extras
                base_extra = {}
        if base_extra.get("initial_conditions") is not None:
            init = InitialConditions.from_dict(base_extra["initial_conditions"]).merged(init)
        init = init.to_dict()
        extra = {"summary": summary, "split": split, "initial_conditions": init}
        # A player's fine-tune is the base model with one more identity: it samples as the
        # base does (without its defaults it fell back to top-p 1, and the fine-tuning study
        # compared identities at different nuclei).
        if base_extra.get("sim_defaults"):
            extra["sim_defaults"] = base_extra["sim_defaults"]
        if cfg.get("init") and cfg.get("player"):
            # ... and its rules' tables, with his own rows (`train.player_tables`).
            extra.update(player_rule_tables(base_extra, data, cfg.player))
        if not cfg.get("init"):   # from `init`, the generic row is the base model's
            average_generic_identity(module.model, vocab)   # unknown players: the average
        path = save_model(out_dir / "model.pt", module.model.cpu(), vocab, event_model,
                          extra=extra)
        summary["model_file"] = str(path)
        (out_dir / "summary.json").write_text(json.dumps(summary, indent=2))
        log.info("summary: %s", json.dumps(summary, indent=2))
    return summary
