"""How a rollout draws one frame (`FrameDraws.draw`): the decoder's sample (`sample_next`), the
players' physical limits, frames a constraint rejects drawn again (`redraw_rejected`), the strike
and serve heads' launches placed and followed for their three frames (`follow_strikes`), and the
surface's bounces; with the protocols a rollout's rally tracker and constraint follow."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import torch

from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.inputs import BALL
from sportsngen.sim.bounce import place_bounces
from sportsngen.sim.kinematics import PlayerLimits, limit_player_acceleration, limit_player_speed
from sportsngen.tennis.rally import awaiting_return


class Tracker(Protocol):
    """Rally-end rules over the whole batch: `update(pos_m (B, 3, 3), active (B,) bool)` feeds
    one frame to the active rallies and returns which rallies are over, (B,) bool."""

    def update(self, pos_m: np.ndarray, active: np.ndarray | None = None) -> np.ndarray: ...


class Constraint(Protocol):
    """`accept(rows, frame, pos_m, next_pos_m, vel_mps) -> (B,) bool` for the live rallies
    `rows` (indices into the batch as first given), the frame index being sampled, the current
    and the sampled positions and the current velocities (B, 3, 3) tensors. `max_tries`
    bounds the resampling of a frame; rows still rejected then keep their last sample
    (`give_up(rows)` is told which), unless an optional `strike_rows(rows) -> (rows,) bool`
    asks for some of them to be struck anyway (the model's strike head places the strike:
    `SportsNGEN.place_strikes`)."""

    max_tries: int

    def accept(self, rows: np.ndarray, frame: int, pos_m: torch.Tensor,
               next_pos_m: torch.Tensor, vel_mps: torch.Tensor) -> torch.Tensor: ...

    def give_up(self, rows: np.ndarray) -> None: ...


def redraw_rejected(model, constraint, alive, n, h, pos, vel, prev_vel, nxt, top_p_player,
                    top_p_ball, generator, contact_odds=False, top_p_contact=None,
                    player_bias=None, player_limits=None, player_top_speed_mps=None,
                    player_quantiles=None, frame=None):
    """Resample the rows `constraint` rejects: up to its max_tries from the nucleus, then as
    many from the whole distribution; with parts (`AllOf`), a row only while a part that
    rejects it has tries of its own left (each draw within `player_limits`, where given, and
    every row's final frame within its players' `player_top_speed_mps` (B, 2), where given). ->
    (frames, redraws per live row, (B,) bool: the rows given up on whose ball the constraint
    wants struck anyway). `frame`: the model's `sampling_frame` of all rows, whose rows the
    redraws reuse."""
    bad = ~constraint.accept(alive, n, pos, nxt, vel)
    redo = _asked(constraint, bad)
    tries = 0
    drawn = np.zeros(len(alive), dtype=np.int64)
    while bool(redo.any()) and tries < 2 * constraint.max_tries:
        idx = torch.nonzero(redo).squeeze(1)
        # When the nucleus holds no acceptable frame, the rest of the distribution may.
        wide = tries >= constraint.max_tries
        given = {} if frame is None else \
            {"frame": (frame[0][idx], None if frame[1] is None else frame[1][idx])}
        again = model.sample_next(h[idx], pos[idx], vel[idx],
                                  1.0 if wide else top_p_player, 1.0 if wide else top_p_ball,
                                  generator, prev_vel[idx], contact_odds,
                                  1.0 if wide else top_p_contact,
                                  None if player_bias is None else player_bias[idx],
                                  player_quantiles, **given)
        if player_limits is not None:
            again = limit_player_acceleration(again, pos[idx], vel[idx], model.cfg.fps,
                                              player_limits)
        if player_top_speed_mps is not None:
            again = limit_player_speed(again, pos[idx], model.cfg.fps,
                                       player_top_speed_mps[idx])
        nxt[idx] = again
        drawn[idx.cpu().numpy()] += 1
        ok = constraint.accept(alive[idx.cpu().numpy()], n, pos[idx], again, vel[idx])
        bad[idx] = ~ok
        redo[idx] = _asked(constraint, ~ok)
        tries += 1
    strike = np.zeros(len(alive), dtype=bool)
    if bool(bad.any()):
        idx = torch.nonzero(bad).squeeze(1)
        given = idx.cpu().numpy()
        constraint.give_up(alive[given])
        if hasattr(constraint, "project"):       # e.g. the net stops a ball it cannot pass
            nxt[idx] = constraint.project(pos[idx], nxt[idx])
        if hasattr(constraint, "strike_rows"):
            strike[given] = constraint.strike_rows(alive[given])
    if hasattr(constraint, "settle"):            # e.g. rows accepted once their tries ran out
        nxt = constraint.settle(alive, pos, nxt)
        if player_top_speed_mps is not None:
            nxt = limit_player_speed(nxt, pos, model.cfg.fps, player_top_speed_mps)
    return nxt, drawn, strike


def _asked(constraint, bad: torch.Tensor) -> torch.Tensor:
    """The rejected rows `bad` to draw again: those a part with tries left rejects (`AllOf.asks`
    of the last judgement); every one for a constraint without parts."""
    asks = getattr(constraint, "asks", None)
    return bad.clone() if asks is None else bad & torch.as_tensor(asks, device=bad.device)


def follow_strikes(model: SportsNGEN, h: torch.Tensor, pos: torch.Tensor, vel: torch.Tensor,
                   nxt: torch.Tensor, plan: torch.Tensor, generator: torch.Generator,
                   forced: np.ndarray | None = None, top_p_serve: float = 1.0,
                   serve: torch.Tensor | None = None,
                   server_ident: torch.Tensor | None = None,
                   receiver_ident: torch.Tensor | None = None,
                   returning: torch.Tensor | None = None,
                   shot: torch.Tensor | None = None,
                   surface: torch.Tensor | None = None,
                   veto: Callable[[np.ndarray, np.ndarray, bool], np.ndarray] | None = None
                   ) -> tuple[torch.Tensor, torch.Tensor]:
    """With a strike head: a ball in the frames after its strike flies the launch solved at the
    strike (`plan`, (B, 2, 3), NaN where none), so the physics centre reads the strike's spin
    from them; a new strike is drawn by the head (`SportsNGEN.place_strikes`), also in the
    rows `forced` (B,) bool whatever the sampled frame; a serve by the serve head, with one
    (nucleus `top_p_serve`). `serve` (B,): the rallies' serve (0 first, 1 second), which a
    strike head with `cfg.strike_roles` reads, and with `server_ident` (B,) a serve head's
    per-server shift (`cfg.serve_bias`), with `receiver_ident` (B,) too the strike head's
    per-hitter shift (`cfg.strike_bias`), with `returning` (B,) bool (only the serve struck
    so far) the returns' (`cfg.strike_return`), with `shot` (B,) (the contacts so far) the
    strike's number (`cfg.strike_shots`, `cfg.strike_late`), with `surface` (B,) the
    surfaces' indices (`cfg.strike_return_surface`). `veto`: which of the heads' launches may
    stand (`strike_heads.place_strikes`)."""
    planned = ~torch.isnan(plan[:, 0, 0])
    if bool(planned.any()):
        nxt = nxt.clone()
        nxt[planned, BALL] = plan[planned, 0]
    plan = torch.cat([plan[:, 1:], torch.full_like(plan[:, :1], float("nan"))], dim=1)
    force = None if forced is None or not forced.any() else torch.as_tensor(forced,
                                                                           device=nxt.device)
    nxt, new = model.place_strikes(h, pos, vel, nxt, generator, allowed=~planned, forced=force,
                                   top_p_serve=top_p_serve, serve=serve,
                                   server_ident=server_ident, receiver_ident=receiver_ident,
                                   returning=returning, shot=shot, surface=surface,
                                   veto=veto)
    return nxt, torch.where(torch.isnan(new[:, :1, :1]), plan, new)


@dataclass
class FrameDraws:
    """How `rollout` draws a frame (its sampling arguments) and what the redraws counted."""

    model: SportsNGEN
    tracker: Tracker
    generator: torch.Generator
    top_p_player: float
    top_p_ball: float
    contact_odds: bool
    top_p_contact: float | None
    top_p_serve: float
    constraint: Constraint | None
    bounce_surfaces: np.ndarray | None
    player_limits: PlayerLimits | None
    player_quantiles: torch.Tensor | None
    resampled: np.ndarray        # (B,) frames drawn again (a constraint rejected them)
    forced_strikes: np.ndarray   # (B,) strikes asked for where a constraint gave up

    def draw(self, rows, n, h, pos, vel, prev_vel, p_bias, top, plan, serve, ident, surface):
        """The next frame of the batch rows `rows` (indices as first given), drawn by the
        decoder with every rule applied -> (frames, their strike plans)."""
        model, constraint, fps = self.model, self.constraint, self.model.cfg.fps
        frame = model.sampling_frame(pos, vel, prev_vel)
        nxt = model.sample_next(h, pos, vel, self.top_p_player, self.top_p_ball, self.generator,
                                prev_vel, self.contact_odds, self.top_p_contact, p_bias,
                                self.player_quantiles, frame=frame)
        if self.player_limits is not None:
            nxt = limit_player_acceleration(nxt, pos, vel, fps, self.player_limits)
        if top is not None:
            nxt = limit_player_speed(nxt, pos, fps, top)
        forced = None
        if constraint is not None:
            nxt, drawn, forced = redraw_rejected(
                model, constraint, rows, n, h, pos, vel, prev_vel, nxt, self.top_p_player,
                self.top_p_ball, self.generator, self.contact_odds, self.top_p_contact, p_bias,
                self.player_limits, top, self.player_quantiles, frame)
            self.resampled[rows] += drawn
            if model.strike_head is not None:
                self.forced_strikes[rows] += forced
        planned = ~torch.isnan(plan[:, 0, 0])     # this frame is a launch's or a bounce's
        if model.strike_head is not None or model.serve_head is not None:
            shots = getattr(self.tracker, "n_shots", None)
            returning = None if shots is None or model.strike_return is None else \
                torch.as_tensor(awaiting_return(np.asarray(shots)[rows]), device=pos.device)
            shot = None if shots is None or (model.strike_shot is None
                                             and model.strike_late is None) else \
                torch.as_tensor(np.asarray(shots)[rows], device=pos.device)
            veto = None
            if getattr(constraint, "judges_strikes", False):
                def veto(r, land_xy, serving):
                    return constraint.judge_strikes(rows[r], n, pos[r], land_xy, serving)
            nxt, plan = follow_strikes(model, h, pos, vel, nxt, plan, self.generator, forced,
                                       self.top_p_serve, serve, ident[:, 0], ident[:, 1],
                                       returning, shot, surface, veto)
        if self.bounce_surfaces is not None and n >= 3:
            nxt, plan = place_bounces(nxt, plan, pos, vel, prev_vel, fps, self.bounce_surfaces,
                                      rows, planned)
        return nxt, plan
