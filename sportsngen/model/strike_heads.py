"""The strike and serve heads' targets in training and their draws in rollouts.

`model.strike` describes a strike as where its ball goes and solves the launch; here the
decoder's windows are read for the strikes a head learns (`strike_targets`) and a rollout's
sampled frames get the heads' draws in place of the ball's bins (`place_strikes`). Both work
on the ball's track alone, so they take the heads as arguments (`SportsNGEN` calls them with
its own).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch

from sportsngen.model import strike
from sportsngen.model.inputs import BALL, OBJECTS
from sportsngen.model.sampling import uniform_in_bin

SERVER = OBJECTS.index("server")
FORCED_DRAWS = 8       # draws of the strike head for a forced strike until one launches
VETO_DRAWS = 1000      # the most draws a vetoed row gets (the veto gives up well before)
N_STRIKE_ROLES = 4     # (server, receiver) x (first serve, second serve)
# Shots 1 (the return) to 6 each, then the receiver's (odd) and the server's (even) pooled.
N_SHOT_BUCKETS = 8


def ball_on_receivers_end(pos_m: torch.Tensor) -> torch.Tensor:
    """Frames' positions (..., 3, 3) -> (...) bool: the ball is on the receiver's end. Players
    stay on their ends, so the end the ball is struck on names the hitter."""
    return torch.sign(pos_m[..., BALL, 0]) != torch.sign(pos_m[..., SERVER, 0])


def role_index(receiver: torch.Tensor, serve: torch.Tensor) -> torch.Tensor:
    """(...) the hitter is the receiver, (...) the serve (0 first, 1 second) -> (...) the
    strike role's row: 2 * receiver + serve."""
    return 2 * receiver.long() + serve.long()


def shot_bucket(shot: torch.Tensor) -> torch.Tensor:
    """(...) a rally strike's number (1 the return, 2 the server's first rally ball, ...) ->
    (...) its row of the strike head's shot shift: shots 1-6 rows 0-5, later shots the
    receiver's (odd) row 6 and the server's (even) row 7. A number under 1 counts as the
    return."""
    shot = shot.long().clamp_min(1)
    late = torch.where(shot % 2 == 1, torch.full_like(shot, 6), torch.full_like(shot, 7))
    return torch.where(shot <= 6, shot - 1, late)


def strike_role_index(pos_m: torch.Tensor, serve: torch.Tensor) -> torch.Tensor:
    """Frames' positions (..., 3, 3) and their rallies' serve (...) (0 first, 1 second) -> (...)
    whose strike it would be, and on which serve's point (`role_index`)."""
    return role_index(ball_on_receivers_end(pos_m), serve)


def strike_targets(pos_m: torch.Tensor, vel_mps: torch.Tensor, next_pos_m: torch.Tensor,
                   has_next: torch.Tensor, fps: float,
                   serves: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
    """Windows' rally strikes (`strike.is_strike_across`: struck in a frame's step, or in a
    step that barely moves and sent back by the next; `serves`: the serves, `strike.is_serve`,
    read as `serve_labels`) whose three next frames are in the window and whose flight crosses
    the net and lands (a rally ball also where it comes down before the net: an error into the
    net, `strike.strike_labels`): (B, T) bool, and their bins (B, T, 4) (0 elsewhere). Positions
    (B, T, 3, 3), `has_next` (B, T)."""
    edges = strike.serve_edges() if serves else None
    b, t = has_next.shape
    mask = torch.zeros(b, t, dtype=torch.bool, device=has_next.device)
    bins = torch.zeros(b, t, 4, dtype=torch.long, device=has_next.device)
    if t < 3:
        return mask, bins
    ball = pos_m[..., BALL, :].detach().double().cpu().numpy()
    nxt = next_pos_m[..., BALL, :].detach().double().cpu().numpy()
    vel = vel_mps[..., BALL, :].detach().double().cpu().numpy()
    ok = has_next.bool().cpu().numpy()
    cand = np.zeros((b, t), dtype=bool)
    found = (strike.is_serve(ball[:, :-2], vel[:, :-2], nxt[:, :-2], fps) if serves else
             strike.is_strike_across(ball[:, :-2], vel[:, :-2], nxt[:, :-2], nxt[:, 1:-1], fps))
    cand[:, :-2] = ok[:, :-2] & ok[:, 1:-1] & ok[:, 2:] & found
    rb, rt = np.nonzero(cand)
    if len(rb) == 0:
        return mask, bins
    after = np.stack([nxt[rb, rt], nxt[rb, rt + 1], nxt[rb, rt + 2]], axis=1)
    side = np.sign(ball[rb, rt, 0])
    # A serve's speed is read at one frame time after its contact, which the toss's last
    # frame before it stands for (a few cm away at the toss's top).
    labels = (strike.serve_labels(after, side, fps, contact_m=ball[rb, rt]) if serves
              else strike.strike_labels(after, side, fps))
    good = np.isfinite(labels).all(-1)
    rb, rt = rb[good], rt[good]
    mask[rb, rt] = True
    bins[rb, rt] = torch.as_tensor(strike.strike_bin_index(labels[good], edges),
                                   device=bins.device)
    return mask, bins


@torch.no_grad()
def place_strikes(strike_head, serve_head, h: torch.Tensor, pos_m: torch.Tensor,
                  vel_mps: torch.Tensor, nxt: torch.Tensor, fps: float,
                  generator: torch.Generator | None = None, top_p: float = 1.0,
                  allowed: torch.Tensor | None = None, forced: torch.Tensor | None = None,
                  top_p_serve: float = 1.0,
                  strike_h: torch.Tensor | Callable[[], torch.Tensor] | None = None,
                  serve_bias: Callable[[torch.Tensor], torch.Tensor] | None = None,
                  strike_bias: Callable[[torch.Tensor], torch.Tensor] | None = None,
                  veto: Callable[[np.ndarray, np.ndarray, bool], np.ndarray] | None = None
                  ) -> tuple[torch.Tensor, torch.Tensor]:
    """Where the sampled next frames `nxt` (B, 3, 3) hold a rally strike (the ball sent back,
    or stopped: `strike.is_strike_begun`), or in the rows `forced` (B,) bool whatever they
    hold (in the rows `allowed`, (B,) bool, default all), `strike_head`'s draw from the
    decoder's states `h` (B, 3, D) instead: its bins (nucleus `top_p`), uniform inside them,
    the launch solved from the current ball and its first frame put in `nxt`; where they hold
    a serve, `serve_head`'s draw the same way (nucleus `top_p_serve`; `strike.solve_serve`).
    Either head may be None. Returns (nxt, the launch's next two frames (B, 2, 3), NaN for
    rows without a strike or whose launch was not found).
    `strike_h` (B, D): the strike head's input where it is not the ball token's state
    (`SportsNGEN.strike_input`), or a callable that makes it, asked only on a frame that holds
    a strike (most frames hold none); `serve_bias`: the served rows (R,) -> the shifts of the serve
    head's logits for them (R, 4, bins) (`SportsNGEN.serve_head_bias`), asked only on a frame
    that holds a serve; `strike_bias` the same for the strike head's rows
    (`SportsNGEN.strike_head_bias`). `veto(rows, landing_xy (R, 2) m in the world, serve) ->
    (R,) bool`: whether each found launch may stand; a rejected one is drawn again from its
    head (a counterfactual's shot, `sim.whatif.ShotConstraint.judge_strikes`), until the veto
    passes it (it must give up in time: at most `VETO_DRAWS` draws)."""
    plan = torch.full((len(nxt), 2, 3), float("nan"), device=nxt.device)
    if strike_head is None and serve_head is None:
        return nxt, plan
    ball = pos_m[:, BALL].double().cpu().numpy()
    vel = vel_mps[:, BALL].double().cpu().numpy()
    nxt_ball = nxt[:, BALL].double().cpu().numpy()
    allow = np.ones(len(nxt), dtype=bool) if allowed is None else allowed.cpu().numpy()
    parts = []
    must = np.zeros(len(nxt), dtype=bool) if forced is None else forced.cpu().numpy().copy()
    if strike_head is not None:
        # A draw that stops the incoming ball is a strike struck inside the step, as the head
        # was trained on (`strike_targets`): left to the decoder, it let 10 of 29 such balls
        # in 1,037 own serves fall dead beside a receiver in reach, 4 of them called aces
        # (docs/evaluation.md, seventy-sixth part). Out of reach, `sim.constraints`'
        # `PhysicalLimits` rejects such a draw as a jolt.
        begun = strike.is_strike_begun(ball, vel, nxt_ball, fps) & allow
        struck = strike.is_strike(ball, vel, nxt_ball, fps) | begun
        must |= begun                            # a stopped ball is no frame to fall back on
        if forced is not None:
            struck |= forced.cpu().numpy()
        parts.append((struck & allow, strike_head, None, strike.solve_launch, top_p,
                      h[:, BALL] if strike_h is None else strike_h, strike_bias))
    if serve_head is not None:
        served = strike.is_serve(ball, vel, nxt_ball, fps) & allow
        parts.append((served, serve_head, strike.serve_edges(), strike.solve_serve, top_p_serve,
                      h[:, BALL], serve_bias))
    for struck, head, edges, solve, p, states, bias in parts:
        rows = np.flatnonzero(struck)
        # A forced strike (or a stopped ball) has no sampled frame to fall back on: a draw
        # whose launch is not found is drawn again (from 4 m behind the baseline 3 % were not,
        # and the ball flew past a receiver who had it in reach: docs/evaluation.md,
        # twenty-sixth part).
        draws = (FORCED_DRAWS if edges is None else 1) if veto is None else VETO_DRAWS
        for attempt in range(draws):
            if len(rows) == 0:
                break
            r = torch.as_tensor(rows, device=h.device)
            if callable(states):
                states = states()
            idx = (head.sample(states[r], p, generator) if bias is None
                   else head.sample(states[r], p, generator, dim_bias=bias(r)))
            u = uniform_in_bin(idx.shape, h.device, generator)
            values = strike.strike_bin_value(idx.cpu().numpy(), u.double().cpu().numpy(),
                                             edges)
            contact = ball[rows]                  # the contact is taken on the struck frame
            side = np.sign(ball[rows, 0])
            v0, found = solve(contact, side, values, fps)
            again = ~found & must[rows] & (attempt < draws - 1)
            if veto is not None and found.any():
                # The head's values put the landing point on the far side of the contact.
                land = -side[found, None] * values[found, :2]
                vetoed = np.zeros(len(rows), dtype=bool)
                vetoed[found] = ~veto(rows[found], land, edges is not None)
                found &= ~vetoed
                must[rows[vetoed]] = True     # its sampled frame is no fallback either
                again |= vetoed
            frames = strike.launch_frames(contact, v0, values[:, 3], fps)
            keep = torch.as_tensor(rows[found], device=h.device)
            frames = torch.as_tensor(frames[found], dtype=nxt.dtype, device=nxt.device)
            nxt = nxt.clone()
            nxt[keep, BALL] = frames[:, 0]
            plan[keep] = frames[:, 1:]
            rows = rows[again]
    return nxt, plan
