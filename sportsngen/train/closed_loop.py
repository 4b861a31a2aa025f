"""Closed-loop training windows: the model rolls a recorded window out itself, closest-of-K.

Teacher forcing only ever shows the decoder recorded states, so in a rollout, where its inputs
are its own samples, it meets states it never saw (a ball 0.4 m from where a recorded receiver
would have hit it) and does not know what to do there. Closest-of-K (after CAT-K, the
closed-loop fine-tuning of traffic agents) shows it its own states while keeping them near the
record, so that the recorded next state stays a sensible answer:

1. the window's first `start_frames` frames are the record (the model must see a velocity and
   an acceleration before its first sample);
2. from there the model draws K next frames (nucleus `top_p`, uniform inside the bin, exactly as
   a rollout does) and each object moves to the candidate nearest its recorded next position
   (objects are sampled independently given the decoder's state, so each picks its own);
3. an object whose nearest candidate still lies further from its recorded next position than
   `max_player_drift_m` / `max_ball_drift_m` goes back onto the record there (position and
   velocity: the record takes over, as an expert would), so no state strays further than that;
4. the window's inputs become those rolled-out positions (velocities and the previous
   velocities from them, as a rollout computes them); the target of each token is the
   recorded frame's *change of velocity* applied to the model's own state
   (`expert_next_m`): the player starts, brakes or turns when the recorded one did, the ball
   is struck, bounces or flies as the recorded ball was, from where they are now. Where
   nothing has drifted that is the recorded next frame itself.

Why not the recorded next position as the target (CAT-K's "go back to the record"): from a
state 16 mm off, it asks the ball in free flight to jump 16 mm in a frame and a player 0.2 m
off to change speed by 5 m/s, which no physics allows. Tried first (half of each batch rolled
out, K = 8), its training loss read 13.2 nats at step 19 of the fine-tune where the
teacher-forced run read 5.5, and the run was stopped. Drift is kept small by choosing the
nearest candidate and by the record taking over, not by the targets.

Why the record takes over instead of masking the rest of the window (`on_drift="mask"`, kept as
an option): on the bundled model's own windows most of the drift is the ball after a racket
contact, where a candidate one frame early or 0.3 m off sends the ball elsewhere for good;
masked, only 5-12 % of the rolled tokens were left to train on (K = 1-16, 16 windows of
`synthetic_small`, docs/evaluation.md), the contacts themselves among the lost ones.

`closest_of_k` is plain torch on a collated `WindowDataset` batch; `DecoderModule` applies it to
a share of each training batch (`closed_loop.fraction` in conf/train.yaml).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.inputs import BALL, N_OBJECTS, object_features

ON_DRIFT = ("snap", "mask")


@dataclass(frozen=True)
class ClosedLoopConfig:
    """How much of a batch is rolled out and how (conf/train.yaml `closed_loop`)."""

    fraction: float = 0.0           # share of a batch's windows rolled out (0: teacher forcing)
    k: int = 8                      # candidates a frame; each object keeps its nearest
    start_frames: int = 3           # recorded frames a rollout starts from
    top_p: float = 1.0              # nucleus of the candidates (players and ball)
    max_player_drift_m: float = 0.3
    max_ball_drift_m: float = 0.1
    on_drift: str = "snap"          # "snap": the record takes over; "mask": drop the frames

    def __post_init__(self) -> None:
        if self.on_drift not in ON_DRIFT:
            raise ValueError(f"closed_loop.on_drift must be one of {ON_DRIFT}, "
                             f"got {self.on_drift!r}")
        if not 0.0 <= self.fraction <= 1.0:
            raise ValueError(f"closed_loop.fraction must be in [0, 1], got {self.fraction}")
        if self.k < 1:
            raise ValueError(f"closed_loop.k must be at least 1, got {self.k}")
        if self.start_frames < 1:
            raise ValueError(f"closed_loop.start_frames must be at least 1, "
                             f"got {self.start_frames}")
        if not 0.0 < self.top_p <= 1.0:
            raise ValueError(f"closed_loop.top_p must be in (0, 1], got {self.top_p}")
        if not (self.max_player_drift_m > 0 and self.max_ball_drift_m > 0):
            raise ValueError("closed_loop drift limits must be positive")

    def limits_m(self, like: torch.Tensor) -> torch.Tensor:
        """(3,) drift limits of the server, the receiver and the ball."""
        return torch.tensor([self.max_player_drift_m] * BALL + [self.max_ball_drift_m],
                            dtype=like.dtype, device=like.device)

    def n_rows(self, batch_size: int) -> int:
        """How many windows of a batch of `batch_size` are rolled out (at least one when the
        fraction is above 0)."""
        if self.fraction <= 0:
            return 0
        return min(batch_size, max(1, round(self.fraction * batch_size)))


def expert_next_m(pos_m: torch.Tensor, vel_mps: torch.Tensor, rec_pos_m: torch.Tensor,
                  rec_vel_mps: torch.Tensor, rec_next_m: torch.Tensor, fps: float) -> torch.Tensor:
    """The recorded step's change of velocity applied to another state (..., 3, 3):
    ``pos + vel dt + (rec_next - rec_pos - rec_vel dt)``, velocities backward differences.
    The same state as the record's gives the recorded next position; the ball stays above
    the ground."""
    dt = 1.0 / fps
    nxt = pos_m + vel_mps * dt + (rec_next_m - rec_pos_m - rec_vel_mps * dt)
    nxt[..., BALL, 2] = nxt[..., BALL, 2].clamp_min(0.0)
    return nxt


def drift_m(pos_m: torch.Tensor, recorded_m: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) positions against the record -> (..., 3) distances: players on the ground,
    the ball in 3-D."""
    d = pos_m - recorded_m
    return torch.cat([torch.linalg.vector_norm(d[..., :BALL, :2], dim=-1),
                      torch.linalg.vector_norm(d[..., BALL:, :], dim=-1)], dim=-1)


def _nearest(candidates: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """candidates (K, B, 3, 3), target (B, 3, 3) -> (B, 3, 3): each object's candidate nearest
    its target."""
    best = drift_m(candidates, target[None]).argmin(dim=0)             # (B, 3)
    idx = best[None, :, :, None].expand(1, *candidates.shape[1:])
    return candidates.gather(0, idx)[0]


@torch.no_grad()
def closest_of_k(model: SportsNGEN, batch: dict, cfg: ClosedLoopConfig,
                 generator: torch.Generator | None = None) -> dict:
    """The batch's windows rolled out by `model`, closest-of-K (module doc) -> a new batch:
    `pos_m`, `vel_mps`, `prev_vel_mps` rolled out; `next_pos_m` the recorded steps applied to
    them (`expert_next_m`: the record's own next frame where nothing drifted); `token_mask`
    (B, T, 3) bool, the tokens to train on; `drift_m` (B, T, 3), each object's distance from
    the record; `snapped` (B, T, 3) bool, the frames where the record took over an object.

    The model is run in eval mode (no dropout) and left in the mode it was in."""
    pos, vel = batch["pos_m"], batch["vel_mps"]
    prev_vel = batch.get("prev_vel_mps")
    if prev_vel is None:
        prev_vel = torch.zeros_like(vel)
    nxt, has_next, valid, t_s = (batch["next_pos_m"], batch["has_next"], batch["valid"],
                                 batch["t_s"])
    b, t_total = pos.shape[:2]
    s0 = min(cfg.start_frames, t_total)
    fps = model.cfg.fps
    rolled, rvel, rprev = pos.clone(), vel.clone(), prev_vel.clone()
    limit = cfg.limits_m(pos)
    snapped = torch.zeros(pos.shape[:3], dtype=torch.bool, device=pos.device)
    was_training = model.training
    model.eval()
    try:
        ctx = model.context_tokens(batch["surface"], batch["tournament"], batch["serve"],
                                   batch["score"])
        feats = object_features(pos[:, :s0], vel[:, :s0], t_s[:, :s0])
        hs, cache = model(feats, batch["ident"], ctx, return_cache=True)
        h = hs[:, -1]
        k = cfg.k
        for t in range(s0 - 1, t_total - 1):
            cand = model.sample_next(h.repeat(k, 1, 1), rolled[:, t].repeat(k, 1, 1),
                                     rvel[:, t].repeat(k, 1, 1), cfg.top_p, cfg.top_p,
                                     generator, rprev[:, t].repeat(k, 1, 1))
            chosen = _nearest(cand.view(k, b, N_OBJECTS, 3), nxt[:, t])
            # The record where the window has no next frame (padding) and, snapping, where
            # even the nearest candidate is too far from it.
            record = ~has_next[:, t, None].expand(b, N_OBJECTS).clone()
            if cfg.on_drift == "snap":
                far = (drift_m(chosen, nxt[:, t]) > limit) & has_next[:, t, None]
                snapped[:, t + 1] = far
                record |= far
            rec = record[..., None]
            rolled[:, t + 1] = torch.where(rec, pos[:, t + 1], chosen)
            live = valid[:, t + 1, None, None] & ~rec
            rvel[:, t + 1] = torch.where(live, (rolled[:, t + 1] - rolled[:, t]) * fps,
                                         vel[:, t + 1])
            rprev[:, t + 1] = torch.where(live, rvel[:, t], prev_vel[:, t + 1])
            if t + 1 < t_total - 1:
                step = object_features(rolled[:, t + 1:t + 2], rvel[:, t + 1:t + 2],
                                       t_s[:, t + 1:t + 2])[:, 0]
                h = model.forward_step(step, cache)[0]
    finally:
        model.train(was_training)
    drift = drift_m(rolled, pos)
    frame_ok = (drift <= limit).all(dim=-1) & has_next
    out = dict(batch)
    target = expert_next_m(rolled, rvel, pos, vel, nxt, fps)
    target = torch.where(has_next[..., None, None], target, nxt)
    out.update(pos_m=rolled, vel_mps=rvel, prev_vel_mps=rprev, next_pos_m=target,
               token_mask=frame_ok[..., None].expand(b, t_total, N_OBJECTS).clone(),
               drift_m=drift, snapped=snapped)
    return out


def rollout_summary(out: dict) -> dict[str, float]:
    """Figures of a `closest_of_k` batch over its tokens with a next frame: the share kept in
    the loss, the share of frames where the record took over (players, ball) and the median
    and 90th-percentile drift from the record (m)."""
    live = out["has_next"]
    if not live.any():
        return {}
    drift, snapped = out["drift_m"][live], out["snapped"][live].float()
    players, ball = drift[:, :BALL].reshape(-1), drift[:, BALL]
    return {"kept": float(out["token_mask"][live].float().mean()),
            "snapped_player": float(snapped[:, :BALL].mean()),
            "snapped_ball": float(snapped[:, BALL].mean()),
            "drift_player_p50_m": float(players.median()),
            "drift_player_p90_m": float(players.quantile(0.9)),
            "drift_ball_p50_m": float(ball.median()),
            "drift_ball_p90_m": float(ball.quantile(0.9))}


def mix_closed_loop(model: SportsNGEN, batch: dict, cfg: ClosedLoopConfig,
                    generator: torch.Generator | None = None) -> dict:
    """The first `cfg.n_rows(B)` windows of a (shuffled) batch rolled out by `closest_of_k`,
    the rest teacher-forced as they are -> one batch with `token_mask` for all rows and
    `closed_loop` (B,) bool marking the rolled rows and `closed_loop_summary`
    (`rollout_summary` of the rolled rows; empty when none)."""
    b = batch["pos_m"].shape[0]
    n = cfg.n_rows(b)
    mask = batch["has_next"][..., None].expand(*batch["has_next"].shape, N_OBJECTS).clone()
    rolled_rows = torch.zeros(b, dtype=torch.bool, device=mask.device)
    out = dict(batch)
    if n:
        part = {key: v[:n] if isinstance(v, torch.Tensor) and v.shape[:1] == (b,) else v
                for key, v in batch.items()}
        rolled = closest_of_k(model, part, cfg, generator)
        for key in ("pos_m", "vel_mps", "prev_vel_mps", "next_pos_m"):
            full = (batch[key] if key in batch else torch.zeros_like(batch["vel_mps"])).clone()
            full[:n] = rolled[key]
            out[key] = full
        mask[:n] = rolled["token_mask"]
        rolled_rows[:n] = True
        out["closed_loop_summary"] = rollout_summary(rolled)
    else:
        out["closed_loop_summary"] = {}
    out["token_mask"] = mask
    out["closed_loop"] = rolled_rows
    return out
