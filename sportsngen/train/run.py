"""`train_from_config(cfg)`: what `python train.py` does, callable from Python and tests.

It reads top to bottom: seed; load rallies (`data.source`); build the model, from scratch
(`build_from_scratch`) or from a model file or checkpoint (`build_from_init`: fine-tuning, with
`player` a new identity, changed by the `init_*` options); fit the decoder with Lightning
(checkpoints, resume, logs, progress bar) and then the event classifier; export a
self-contained model file (`export_model`). Each stage's trainer is `conf/trainer`, its
loggers `conf/logger` and its callbacks `conf/callbacks`, built by `hydra.utils.instantiate`.
"""

from __future__ import annotations

import importlib.util
import json
import logging
from dataclasses import dataclass
from pathlib import Path

import lightning as L
import pandas as pd
import torch
from hydra.utils import instantiate
from lightning.pytorch.callbacks import EMAWeightAveraging
from omegaconf import DictConfig, OmegaConf

from sportsngen.data.serve_starts import InitialConditions
from sportsngen.data.tokens import RallyArrays, Vocab
from sportsngen.data.tracking import RallyData
from sportsngen.errors import ModelFileError
from sportsngen.model.config import ModelConfig
from sportsngen.model.embedding import widen_for_extra
from sportsngen.model.event_classifier import EventClassifier
from sportsngen.model.export import is_model_file, read_extra, save_model
from sportsngen.model.forecast import FORECAST_FEATURES, INTERCEPT_FEATURES
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
from sportsngen.train.windows import Augment

log = logging.getLogger(__name__)


def _installed(logger: DictConfig) -> bool:
    """Whether a logger's package is there: TensorBoard's needs tensorboard, which is not a
    dependency (without it the run logs to CSV alone); the others come with Lightning."""
    return not logger._target_.endswith(".TensorBoardLogger") or \
        importlib.util.find_spec("tensorboard") is not None


def _loggers(cfg: DictConfig, out_dir: Path, stage: str) -> list:
    """The loggers of `stage` ("decoder" or "events") in `cfg.logger`, saving in the run
    directory."""
    return [instantiate(node, save_dir=str(out_dir))
            for node in (cfg.logger.get(stage) or {}).values()
            if node is not None and _installed(node)]


def _callbacks(cfg: DictConfig, out_dir: Path, stage: str) -> list:
    """The callbacks of `stage` in `cfg.callbacks`; a `dirpath` is a folder of the run
    directory."""
    out = []
    for node in (cfg.callbacks.get(stage) or {}).values():
        if node is not None:
            where = {"dirpath": str(out_dir / node.dirpath)} if node.get("dirpath") else {}
            out.append(instantiate(node, **where))
    return out


def _container(node) -> dict | None:
    return OmegaConf.to_container(node, resolve=True) if node is not None else None


def _trainer(cfg: DictConfig, out_dir: Path, stage: str, max_steps: int,
             ema_decay: float | None = None) -> L.Trainer:
    """The Lightning trainer of one stage (`cfg.trainer`, its loggers and callbacks) and, with
    `ema_decay`, an exponential moving average of the weights, which then is what validation
    scores, checkpoints hold and the run exports (Lightning's `EMAWeightAveraging`; the live
    weights stay in the checkpoint for resuming)."""
    callbacks = _callbacks(cfg, out_dir, stage)
    if ema_decay is not None:
        if not 0.0 < float(ema_decay) < 1.0:
            raise ValueError(f"ema_decay must be in (0, 1), got {ema_decay}")
        callbacks.append(EMAWeightAveraging(decay=float(ema_decay)))
    return instantiate(cfg.trainer, max_steps=max_steps, default_root_dir=str(out_dir),
                       logger=_loggers(cfg, out_dir, stage), callbacks=callbacks)


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


@dataclass
class Built:
    """What a run trains: its data, vocabulary and model config and, fine-tuning from `init`,
    the weights it starts from and what it keeps of them."""

    data: RallyData
    vocab: Vocab
    model_cfg: ModelConfig
    init: str | None = None            # the model file or checkpoint fine-tuned (cfg.init)
    player: str | None = None          # with init: the player whose identity is learned
    init_state: dict | None = None     # with init: the weights training starts from
    event_model: EventClassifier | None = None   # with init: its classifier, kept by default
    trainable_rows: list[int] | None = None      # with player: the only identity rows trained


def build_from_scratch(cfg: DictConfig, data: RallyData) -> Built:
    """A new model of `cfg.model` on `data`'s vocabulary."""
    if cfg.get("player"):
        raise ValueError("player=... fine-tunes an existing model: also set init=<model "
                         "file or checkpoint>")
    generic = bool(cfg.model.get("generic_identity", False))
    vocab = Vocab.from_data(data, generic=generic)
    model_cfg = build_model_config(OmegaConf.to_container(cfg.model, resolve=True),
                                   data.fps, vocab)
    return Built(data, vocab, model_cfg)


def build_from_init(cfg: DictConfig, data: RallyData, init: str) -> Built:
    """The model of `init` (a model file or checkpoint) to fine-tune: with `player`, one more
    identity learned on his rallies of `data`; changed as the `init_*` options say
    (`extend_init`)."""
    ft = cfg.get("finetune") or {}
    model, event_model, vocab, model_cfg = load_pretrained(init)
    player = cfg.get("player") or None
    trainable_rows = None
    if player:
        data = player_rallies(data, player, ft.get("n_sequences"))
        model, vocab, row = add_player(model, vocab, player)
        model_cfg = model.cfg
        trainable_rows = [row] if ft.get("freeze", True) else None
    model_cfg, init_state = extend_init(cfg, model_cfg, model.state_dict())
    check_data_matches(model_cfg, vocab, data)
    return Built(data, vocab, model_cfg, init=init, player=player, init_state=init_state,
                 event_model=event_model, trainable_rows=trainable_rows)


def _replaced(model_cfg: ModelConfig, **fields) -> ModelConfig:
    return ModelConfig.from_dict({**model_cfg.to_dict(), **fields})


def extend_init(cfg: DictConfig, model_cfg: ModelConfig, state: dict
                ) -> tuple[ModelConfig, dict]:
    """The `init_*` options applied to the init's config and weights -> (config, weights)."""
    # Fine-tuning to a new ball bin centre or in another court frame: same weights and shapes,
    # new targets. A model trained with the flip augmentation already plays both ends alike.
    if cfg.get("init_ball_centre"):
        model_cfg = _replaced(model_cfg, ball_centre=cfg.init_ball_centre)
    if cfg.get("init_frame"):
        model_cfg = _replaced(model_cfg, frame=cfg.init_frame)
    # A head added to a trained model: the rest of the weights as they were, the new head from
    # its initialisation (`_load_init`).
    if cfg.get("init_ball_sub_bins") is not None:
        model_cfg = _replaced(model_cfg, ball_sub_bins=int(cfg.init_ball_sub_bins))
    if cfg.get("init_strike_head"):
        model_cfg = _replaced(model_cfg, strike_head=True)
    if cfg.get("init_serve_head"):
        model_cfg = _replaced(model_cfg, serve_head=True)
    # New input columns join the object embedding with zero weights: training starts from the
    # init's function and learns how much to use them.
    if cfg.get("init_ball_forecast") and not model_cfg.ball_forecast:
        model_cfg = _replaced(model_cfg, ball_forecast=True)
        state = widen_for_extra(state, "embed.", FORECAST_FEATURES)
    if cfg.get("init_ball_intercept") and not model_cfg.ball_intercept:
        if not model_cfg.ball_forecast:
            raise ValueError("init_ball_intercept=true adds columns to the ball's forecast: "
                             "the init needs model.ball_forecast (or init_ball_forecast=true)")
        model_cfg = _replaced(model_cfg, ball_intercept=True)
        state = widen_for_extra(state, "embed.", INTERCEPT_FEATURES)
    if cfg.get("init_clock_s") and not model_cfg.clock_s:
        # The clock's column joins last.
        model_cfg = _replaced(model_cfg, clock_s=float(cfg.init_clock_s))
        state = widen_for_extra(state, "embed.", 1)
    return model_cfg, state


def _datamodule(cfg: DictConfig, built: Built) -> TrackingDataModule:
    w = cfg.windows
    return TrackingDataModule(
        built.data, built.vocab, built.model_cfg.window_frames * int(w.get("length_windows", 1)),
        batch_size=int(w.batch_size),
        val_fraction=float(w.val_fraction), seed=int(cfg.seed),
        augment=Augment(**OmegaConf.to_container(w.augment, resolve=True)),
        num_workers=int(w.num_workers), unknown=built.model_cfg.unknown,
        extra_train=_expert_arrays(cfg, built.vocab))


def fit_decoder(cfg: DictConfig, built: Built, dm: TrackingDataModule, out_dir: Path
                ) -> tuple[DecoderModule, L.Trainer, pd.DataFrame | None]:
    """Fit the decoder (resuming from `resume`), and a fine-tuned player's rows of the
    per-player tables -> (module, trainer, his table rows or None)."""
    opt = cfg.optim
    module = DecoderModule(built.model_cfg.to_dict(), built.vocab.to_dict(), lr=float(opt.lr),
                           weight_decay=float(opt.weight_decay),
                           warmup_steps=int(opt.warmup_steps),
                           trainable_id_rows=built.trainable_rows,
                           closed_loop=_container(cfg.get("closed_loop")),
                           train_only=cfg.get("train_only"),
                           **{k: float(opt.get(k, 1.0)) for k in TOKEN_WEIGHTS})
    if built.init_state is not None:
        _load_init(module.model, built.init_state)
    resume = cfg.get("resume")
    if resume:
        _check_resume(resume, built.model_cfg, built.vocab)
    trainer = _trainer(cfg, out_dir, "decoder", int(cfg.trainer.max_steps),
                       ema_decay=cfg.get("ema_decay"))
    trainer.fit(module, dm, ckpt_path=resume or None)
    ft = cfg.get("finetune") or {}
    player_tables = None
    if built.player and ft.get("fit_tables", True):
        # His rows of the per-player tables, on the rallies his identity row learned from
        # (`train.player_tables`): zero rows would leave him the average player's errors.
        player_tables = fit_player_tables(
            module.model, built.vocab, built.data, built.player,
            prior_serves=float(ft.get("prior_serves", 100.0)),
            prior_strikes=float(ft.get("prior_strikes", 200.0)))
        log.info("%s's table rows:\n%s", built.player, player_tables.round(3).to_string())
    # The checkpoint callback writes last.ckpt only at a validation, and a run whose last step
    # is not one left last.ckpt at an earlier step (a stage resumed from it repeated steps).
    # Written again here, the state the run ended in (his table rows included), for `resume=`.
    # Not with an average of the weights: by now it has replaced the live weights a resume
    # needs (the callback's own last.ckpt holds both).
    if cfg.get("ema_decay") is None:
        trainer.save_checkpoint(str(out_dir / "checkpoints_decoder" / "last.ckpt"))
    return module, trainer, player_tables


def fit_events(cfg: DictConfig, built: Built, dm: TrackingDataModule, out_dir: Path
               ) -> tuple[EventClassifier | None, dict | None]:
    """The event classifier g on the decoder's windows -> (g, its metrics). From `init` the
    base model's g is kept (metrics None) unless asked to retrain it (`events.retrain=true`,
    e.g. with trainer.max_steps=0 to retrain g alone)."""
    ev = cfg.get("events") or {}
    if not ev.get("enabled", False) or (built.init and not ev.get("retrain", False)):
        return built.event_model, None
    em = EventModule(built.model_cfg.to_dict(), lr=float(ev.get("lr", 1e-3)))
    trainer = _trainer(cfg, out_dir, "events", int(ev.get("max_steps", 100)))
    trainer.fit(em, dm)
    return em.model, {k: float(v) for k, v in trainer.callback_metrics.items()}


def export_model(cfg: DictConfig, built: Built, model: torch.nn.Module,
                 event_model: EventClassifier | None, summary: dict, out_dir: Path) -> Path:
    """Write `out_dir/model.pt`: the model, its vocabulary and classifier, and what simulation
    and evaluation read beside them (the split, the serve starts, the base's defaults and, for
    a player's fine-tune, the rule tables with his rows)."""
    ft = cfg.get("finetune") or {}
    # The split is recorded so that scripts/evaluate_model.py scores the same held-out
    # rallies (split_rallies(arrays, val_fraction, seed) on the same data).
    split = {"seed": int(cfg.seed), "val_fraction": float(cfg.windows.val_fraction),
             "data": OmegaConf.to_container(cfg.data, resolve=True),
             "player": cfg.get("player"), "n_sequences": ft.get("n_sequences"),
             "fingerprint": data_fingerprint(built.data)}
    # The simulator starts its rallies from real first frames of the training data. A
    # player's fine-tune adds his serves to the base model's pool; any other fine-tune
    # learns the data it is given, so its pool is that data's alone: serve starts of the
    # data the base model saw (an older generator version) left 34 % of a version-6
    # fine-tune's service points without a serve struck, 12 % with its own starts
    # (docs/evaluation.md).
    init = InitialConditions.from_rally_data(built.data)
    base_extra: dict = {}
    if built.player:
        try:
            base_extra = read_extra(built.init)
        except ValueError:   # a Lightning checkpoint carries no extras
            base_extra = {}
    if base_extra.get("initial_conditions") is not None:
        init = InitialConditions.from_dict(base_extra["initial_conditions"]).merged(init)
    extra = {"summary": summary, "split": split, "initial_conditions": init.to_dict()}
    # A player's fine-tune is the base model with one more identity: it samples as the
    # base does (without its defaults it fell back to top-p 1, and the fine-tuning study
    # compared identities at different nuclei).
    if base_extra.get("sim_defaults"):
        extra["sim_defaults"] = base_extra["sim_defaults"]
    if built.player:
        # ... and its rules' tables, with his own rows (`train.player_tables`).
        extra.update(player_rule_tables(base_extra, built.data, built.player))
    if not built.init:   # from `init`, the generic row is the base model's
        average_generic_identity(model, built.vocab)   # unknown players: the average
    return save_model(out_dir / "model.pt", model.cpu(), built.vocab, event_model, extra=extra)


def train_from_config(cfg: DictConfig, out_dir: str | Path) -> dict:
    """Train (or fine-tune) as `cfg` says; write checkpoints, logs and `model.pt` in out_dir.
    Returns a summary dict (also written as summary.json)."""
    out_dir = Path(out_dir)
    L.seed_everything(int(cfg.seed), workers=True)
    torch.set_num_threads(int(cfg.get("threads") or torch.get_num_threads()))
    data = load_rally_data(OmegaConf.to_container(cfg.data, resolve=True))
    init = cfg.get("init")
    built = build_from_init(cfg, data, init) if init else build_from_scratch(cfg, data)

    dm = _datamodule(cfg, built)
    module, trainer, player_tables = fit_decoder(cfg, built, dm, out_dir)
    summary = {"decoder": {k: float(v) for k, v in trainer.callback_metrics.items()},
               "throughput": module.throughput(), "n_rallies": len(built.data),
               "n_params": sum(p.numel() for p in module.model.parameters()),
               "out_dir": str(out_dir)}
    if player_tables is not None:
        summary["player_tables"] = player_tables.to_dict("records")
    event_model, events = fit_events(cfg, built, dm, out_dir)
    if events is not None:
        summary["events"] = events

    if trainer.is_global_zero:
        path = export_model(cfg, built, module.model, event_model, summary, out_dir)
        summary["model_file"] = str(path)
        (out_dir / "summary.json").write_text(json.dumps(summary, indent=2))
        log.info("summary: %s", json.dumps(summary, indent=2))
    return summary
