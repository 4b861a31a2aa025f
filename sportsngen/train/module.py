"""LightningModules: the decoder f (`DecoderModule`) and the event classifier g
(`EventModule`). The plain torch models live in `sportsngen.model`."""

from __future__ import annotations

import time

import lightning as L
import torch

from sportsngen.data.tokens import Vocab
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.event_classifier import EventClassifier
from sportsngen.model.forecast import extra_columns
from sportsngen.model.inputs import BALL, object_features
from sportsngen.train.closed_loop import ClosedLoopConfig, mix_closed_loop
from sportsngen.train.metrics import NextFrameMetrics, window_states
from sportsngen.train.windows import check_finite


def _masked_mean(x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    m = mask.to(x.dtype)
    return (x * m).sum() / m.sum().clamp_min(1.0)


def batch_inputs(model_cfg: ModelConfig, batch: dict):
    """Object features of a batch (raises naming the rally on NaN)."""
    check_finite(batch)
    return object_features(batch["pos_m"], batch["vel_mps"], batch["t_s"])


STILL_MPS = 0.05   # a player slower than this is standing
CHANGE_MPS = 0.12  # a jump of a player's velocity change a frame (m/s) that marks a new run


def _player_velocities(vel_mps: torch.Tensor, pos_m: torch.Tensor, next_pos_m: torch.Tensor,
                       fps: float) -> tuple[torch.Tensor, torch.Tensor]:
    """The players' (B, T, 2, 2) horizontal velocity now and over the next frame (m/s)."""
    return vel_mps[..., :2, :2], (next_pos_m[..., :2, :2] - pos_m[..., :2, :2]) * fps


def movement_onsets(vel_mps: torch.Tensor, pos_m: torch.Tensor, next_pos_m: torch.Tensor,
                    fps: float) -> torch.Tensor:
    """(B, T, 2) bool: the player tokens whose next frame starts a run, standing now
    (speed < STILL_MPS) and moving by the next frame."""
    now, nxt = _player_velocities(vel_mps, pos_m, next_pos_m, fps)
    return (torch.linalg.vector_norm(now, dim=-1) < STILL_MPS) & \
        (torch.linalg.vector_norm(nxt, dim=-1) >= STILL_MPS)


def movement_changes(vel_mps: torch.Tensor, pos_m: torch.Tensor, next_pos_m: torch.Tensor,
                     fps: float) -> torch.Tensor:
    """(B, T, 2) bool: the player tokens at which his acceleration jumps (by CHANGE_MPS of
    velocity a frame or more): a new run, braking, a turn. Not known at a window's first frame.
    """
    now, nxt = _player_velocities(vel_mps, pos_m, next_pos_m, fps)
    acc_prev = torch.zeros_like(now)
    acc_prev[:, 1:] = now[:, 1:] - now[:, :-1]
    out = torch.linalg.vector_norm(nxt - now - acc_prev, dim=-1) >= CHANGE_MPS
    out[:, 0] = False
    return out


# Loss weights of player tokens: hyper-parameter -> the tokens it weights.
PLAYER_TOKEN_WEIGHTS = {"onset_weight": movement_onsets, "change_weight": movement_changes}
# Every token-weight hyper-parameter (`optim.<name>` in conf/train.yaml; 1.0: unweighted).
TOKEN_WEIGHTS = ("contact_weight", *PLAYER_TOKEN_WEIGHTS)


# `train_only` name of the ball forecast's input weights alone (`model.ball_forecast`).
FORECAST_ONLY = "forecast"


def freeze_except(model: torch.nn.Module, prefix: str) -> None:
    """Freeze every parameter whose name does not start with `prefix` (`train_only`: e.g. a
    new sub-bin head trained on a trained decoder, which stays as it was); several prefixes
    joined by "+" (Hydra reads a comma as a sweep). `FORECAST_ONLY` stands for the object
    embedding's weights on the ball forecast's columns alone, with `ball_intercept` its
    nearest playable ball's too (the rest of that layer's
    gradient is masked; train them without weight decay, which would move the rest)."""
    parts = [p.strip() for p in prefix.split("+") if p.strip()]
    for p in model.parameters():
        p.requires_grad_(False)
    for part in parts:
        if part == FORECAST_ONLY:
            if not model.cfg.ball_forecast:
                raise ValueError("train_only=forecast needs a model with model.ball_forecast "
                                 "(init_ball_forecast=true)")
            w = model.embed.mlp[0].weight
            mask = torch.zeros_like(w)
            mask[:, -extra_columns(model.cfg):] = 1.0
            w.requires_grad_(True)
            w.register_hook(lambda g, mask=mask: g * mask)
            continue
        names = [n for n, _ in model.named_parameters() if n.startswith(part)]
        if not names:
            tops = sorted({n.split(".")[0] for n, _ in model.named_parameters()})
            raise ValueError(f"train_only={part!r} names no parameter; the model's parts: "
                             f"{tops}")
        for n, p in model.named_parameters():
            if n.startswith(part):
                p.requires_grad_(True)


def training_parts(train_only: str) -> list[str]:
    """The top-level modules that `train_only` trains, run in training mode (dropout) while
    the frozen rest runs as at inference; the forecast's columns run with their layer."""
    return [p.strip().split(".")[0] for p in train_only.split("+")
            if p.strip() and p.strip() != FORECAST_ONLY]


class DecoderModule(L.LightningModule):
    """Trains `SportsNGEN` on next-frame bins; validation reports per object kind NLL, top-1
    bin accuracy (the ball also in flight and at racket contact) and the constant-velocity
    reference on the same frames (`sportsngen.train.metrics`)."""

    def __init__(self, model_cfg: dict, vocab: dict, lr: float = 3e-4,
                 weight_decay: float = 0.01, warmup_steps: int = 50,
                 trainable_id_rows: list[int] | None = None, contact_weight: float = 1.0,
                 onset_weight: float = 1.0, change_weight: float = 1.0,
                 closed_loop: dict | None = None, train_only: str | None = None):
        super().__init__()
        weights = {"contact_weight": contact_weight, "onset_weight": onset_weight,
                   "change_weight": change_weight}
        assert set(weights) == set(TOKEN_WEIGHTS)
        for name, value in weights.items():
            if not value > 0:
                raise ValueError(f"{name} must be positive, got {value}")
        self.save_hyperparameters()
        self.cfg = ModelConfig.from_dict(model_cfg)
        self.vocab = Vocab.from_dict(vocab)
        self.model = SportsNGEN(self.cfg)
        self.trainable_id_rows = trainable_id_rows
        if trainable_id_rows is not None:
            from sportsngen.train.finetune import freeze_except_identity

            freeze_except_identity(self.model, trainable_id_rows)
        if train_only:
            freeze_except(self.model, train_only)
        self._t0: float | None = None
        self._elapsed = 0.0
        self._n_frames = 0
        self._n_tokens = 0
        self._steps_timed = 0
        self._val_metrics = NextFrameMetrics()
        self.closed_loop = ClosedLoopConfig(**(closed_loop or {}))
        self._cl_generator: torch.Generator | None = None

    def _forward(self, batch: dict):
        h = window_states(self.model, batch)
        off = self.model.target_offsets(batch["pos_m"], batch["vel_mps"], batch["next_pos_m"],
                                        batch.get("prev_vel_mps"))
        p_idx, b_idx = self.model.offset_bins(off)
        p_nll, b_nll = self.model.nll(h, p_idx, b_idx)
        if self.model.ball_sub_head is not None:
            b_nll = b_nll + self.model.ball_sub_nll(h, off, b_idx)
        if self.model.strike_head is not None:
            # A strike's token also carries where its ball goes (`model.strike`).
            mask, bins = self.model.strike_targets(batch["pos_m"], batch["vel_mps"],
                                                   batch["next_pos_m"], batch["has_next"])
            b_nll = b_nll + self.model.strike_nll(h, mask, bins, batch["pos_m"], batch["serve"])
        if self.model.serve_head is not None:
            mask, bins = self.model.strike_targets(batch["pos_m"], batch["vel_mps"],
                                                   batch["next_pos_m"], batch["has_next"],
                                                   serves=True)
            b_nll = b_nll + self.model.serve_nll(h, mask, bins)
        return h, p_idx, b_idx, p_nll, b_nll

    def loss(self, p_nll: torch.Tensor, b_nll: torch.Tensor, batch: dict) -> torch.Tensor:
        """Mean NLL over object tokens (2 players + 1 ball a frame); the ball's tokens within a
        frame of a racket contact count `contact_weight` times, a player's tokens that start a
        run from standing (`movement_onsets`) `onset_weight` times, and those where his
        acceleration jumps (`movement_changes`) `change_weight` times.

        Both are rare one-frame decisions (a contact is ~1 ball token in 30, a start one
        receiver token a shot) that a rollout must not miss: a model unsure when the ball will
        be struck lets it fly past the player, and one unsure on which frame the receiver
        reacts leaves him standing (a receiver who has not moved by then is, in the data,
        watching an ace).
        Weighting them spends more of the training on them and raises their probability.

        A batch with a `token_mask` (B, T, 3) (closed-loop windows, `sportsngen.train.
        closed_loop`) counts only the tokens it marks; without one, every token with a next
        frame counts."""
        m = batch["has_next"]
        w = self.hparams.contact_weight
        if w != 1.0:
            b_nll = b_nll * (1.0 + (w - 1.0) * batch["near_contact"].to(b_nll.dtype))
        for name, tokens in PLAYER_TOKEN_WEIGHTS.items():
            w = self.hparams.get(name, 1.0)
            if w != 1.0:
                mask = tokens(batch["vel_mps"], batch["pos_m"], batch["next_pos_m"], self.cfg.fps)
                p_nll = p_nll * (1.0 + (w - 1.0) * mask.to(p_nll.dtype))
        tokens = batch.get("token_mask")
        if tokens is None:
            return (_masked_mean(p_nll.sum(-1), m) + _masked_mean(b_nll, m)) / 3.0
        # Per token: a player's mean times two is the frame's two-player sum, as above.
        return (2.0 * _masked_mean(p_nll, tokens[..., :BALL])
                + _masked_mean(b_nll, tokens[..., BALL])) / 3.0

    def training_step(self, batch: dict, batch_idx: int) -> torch.Tensor | None:
        if self.closed_loop.fraction > 0:
            batch = self._closed_loop_batch(batch)
        _, _, _, p_nll, b_nll = self._forward(batch)
        loss = self.loss(p_nll, b_nll, batch)
        self.log("train/loss", loss, prog_bar=True)
        self._n_frames += int(batch["valid"].sum())
        self._n_tokens += int(batch["valid"].sum()) * 3 + 4 * batch["valid"].shape[0]
        if not loss.requires_grad:
            # Only a part trains (`train_only`) and this batch has nothing for it (a serve
            # head's batch of windows cut after the serves): Lightning skips the step.
            return None
        return loss

    def _closed_loop_batch(self, batch: dict) -> dict:
        """A share of the batch rolled out by the model itself (`closest_of_k`), logged: the
        share of the rolled tokens kept in the loss and of the frames where the record took
        over the players and the ball."""
        if self._cl_generator is None:
            # Its own stream, seeded by the run's seed and rank: resumed runs draw anew, which
            # only changes which candidates are drawn.
            self._cl_generator = torch.Generator(device=self.device)
            self._cl_generator.manual_seed(int(torch.initial_seed() % 2 ** 31)
                                           + 7919 * self.global_rank)
        batch = mix_closed_loop(self.model, batch, self.closed_loop, self._cl_generator)
        summary = batch["closed_loop_summary"]
        for key in ("kept", "snapped_player", "snapped_ball"):
            if key in summary:
                self.log(f"train/cl_{key}", summary[key])
        return batch

    # Throughput: wall time of training batches (data loading included), from the third step
    # on, with validation runs left out.
    def on_train_batch_start(self, batch, batch_idx):
        if self.hparams.get("train_only"):
            # The frozen decoder runs as at inference (no dropout): the part that learns is
            # fitted to the states it will be given.
            self.model.eval()
            for part in training_parts(self.hparams.train_only):
                self.model.get_submodule(part).train()
        if self._t0 is None and self.global_step >= 2:
            self._t0 = time.perf_counter()
            self._elapsed = 0.0
            self._n_frames = self._n_tokens = 0

    def on_validation_start(self):
        if self._t0 is not None:
            self._elapsed += time.perf_counter() - self._t0

    def on_validation_end(self):
        if self._t0 is not None:
            self._t0 = time.perf_counter()

    def throughput(self) -> dict:
        """Training frames/s and tokens/s (forward, backward, optimiser, data loading)."""
        if self._t0 is None:
            return {}
        dt = self._elapsed + (time.perf_counter() - self._t0)
        return {"frames_per_s": self._n_frames / dt, "tokens_per_s": self._n_tokens / dt}

    # Validation: token sums over the whole epoch (all-reduced across DDP ranks), so the
    # figures are exact per-frame means rather than means of batch means.
    def on_validation_epoch_start(self) -> None:
        self._val_metrics = NextFrameMetrics()

    @torch.no_grad()
    def validation_step(self, batch: dict, batch_idx: int) -> None:
        self._val_metrics.update(self.model, batch, window_states(self.model, batch))

    def on_validation_epoch_end(self) -> None:
        m = self._val_metrics
        total = self.trainer.strategy.reduce(m.vector().to(self.device), reduce_op="sum")
        stats = m.from_vector(total).compute()
        for k, v in stats.items():
            if isinstance(v, float) and not k.startswith("n_"):
                self.log(f"val/{k}", v, prog_bar=k == "loss", sync_dist=False)

    def configure_optimizers(self):
        decay, no_decay = [], []
        for name, p in self.model.named_parameters():
            if not p.requires_grad:
                continue
            # No weight decay on embeddings (frozen fine-tuning must not move other players'
            # rows), norms and biases.
            (no_decay if p.ndim < 2 or "identity" in name or "Embedding" in name
             or ".context." in name or name.startswith("context.") else decay).append(p)
        opt = torch.optim.AdamW([{"params": decay, "weight_decay": self.hparams.weight_decay},
                                 {"params": no_decay, "weight_decay": 0.0}],
                                lr=self.hparams.lr)
        warm = max(1, int(self.hparams.warmup_steps))
        sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda s: min(1.0, (s + 1) / warm))
        return {"optimizer": opt, "lr_scheduler": {"scheduler": sched, "interval": "step"}}


class EventModule(L.LightningModule):
    """Trains the event classifier g on the per-frame shot labels."""

    def __init__(self, model_cfg: dict, lr: float = 1e-3, weight_decay: float = 0.01):
        super().__init__()
        self.save_hyperparameters()
        self.cfg = ModelConfig.from_dict(model_cfg)
        self.model = EventClassifier(self.cfg)

    def _step(self, batch: dict, stage: str):
        feats = batch_inputs(self.cfg, batch)
        loss, acc = self.model.loss(feats, batch["labels"], batch["valid"])
        bs = feats.shape[0]
        self.log(f"{stage}/event_loss", loss, prog_bar=True, sync_dist=stage == "val",
                 batch_size=bs)
        for name, a in acc.items():
            self.log(f"{stage}/acc_{name}", a, sync_dist=stage == "val", batch_size=bs)
        return loss

    def training_step(self, batch, batch_idx):
        return self._step(batch, "train")

    def validation_step(self, batch, batch_idx):
        self._step(batch, "val")

    def configure_optimizers(self):
        return torch.optim.AdamW(self.model.parameters(), lr=self.hparams.lr,
                                 weight_decay=self.hparams.weight_decay)
