"""A shift of the ball's odds of a racket contact by where the ball is from the player due to
strike it.

The decoder sees both players and the ball, but its odds of a contact hardly read the hitter's
reach. Teacher-forced on 600 training rallies of the bundled file (docs/evaluation.md,
twenty-sixth part), a ball coming to a player 2-3 m beside him (sideways) and a frame or less
from his line is struck on 0 % of the recorded frames and the model gives 22-27 % a frame; at
1.6-2 m, 0-10 % against 27-35 %; a ball 2-3 frames short of him (within 1.3 m aside), 1-11 %
against 8-20 %. Over a serve's approach those frames add up: the model's odds of a return over
a recorded ace were 0.69, over a returned serve 0.71, and a rule that strikes every ball in
reach had to decide the returns (`sim.constraints.StrikeInReach`), returning Serena Williams'
aces with the rest.

`ModelConfig.contact_reach` adds a table of logit shifts, one per cell of (frames until the
ball reaches the hitter's line across the court, how far beside him it is) and per kind of
contact bin, added to the ball head's first axis on every ball coming toward the player on its
end: a strike's bins (the frame they put down sends the ball back toward the net,
`strike.is_strike`) and a jolt's (the other contact bins, more than `CONTACT_OFFSET_M` from the
centre: the ball brakes or leaps on in the air; the record's jolts are contacts struck late in
a frame's interval, a rollout's let serves beside the receiver dribble on as aces). Adding s to
a kind's logits turns its odds p into p e^s / (1 - p + p e^s) (with both kinds, a softmax over
strike, jolt and the rest) and leaves the shape of a strike and of a flight as the head draws
them. `sportsngen.train.contact_reach` fits the table by matching each cell's mean odds of
either kind to the record's share. Where the ball is measured from: the current frame (ball and
player positions, the ball's velocity along the court), the state a rollout has.
"""

from __future__ import annotations

import torch

from sportsngen.model.inputs import BALL
from sportsngen.model.strike_heads import ball_on_receivers_end

# Frames until the ball reaches the hitter's line across the court (negative: past it), and
# its distance from him along that line, in metres: the cells' inner edges. The record's share
# of contacts falls from 0.6-0.8 a frame near (0-1 frames, < 1.3 m) to 0 beyond 2 m aside and
# beyond 3 frames short.
FRAMES_EDGES = (-1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 5.0, 10.0)
ASIDE_EDGES_M = (0.5, 1.0, 1.3, 1.6, 2.0, 2.5, 3.0)
N_FRAMES_CELLS = len(FRAMES_EDGES) + 1
N_ASIDE_CELLS = len(ASIDE_EDGES_M) + 1
N_CELLS = N_FRAMES_CELLS * N_ASIDE_CELLS
# The table's two kinds of contact: bins that send the ball back (a strike) and the other
# contact bins (the ball brakes or leaps on in the air: in a rollout a serve that braked beside
# the receiver flew on as an ace).
STRIKE, JOLT = 0, 1
N_KINDS = 2
# A ball moving toward the hitter's baseline at least this fast along the court is coming to
# him (`model.strike.MIN_INCOMING_MPS`: a strike meets a ball at least this fast).
MIN_INCOMING_MPS = 2.0


def hitter_index(pos_m: torch.Tensor) -> torch.Tensor:
    """Frames' positions (..., 3, 3) -> (...) int64: the player on the ball's end of the court
    (0 the server, 1 the receiver; `strike_heads.ball_on_receivers_end`)."""
    return ball_on_receivers_end(pos_m).long()


def reach_geometry(pos_m: torch.Tensor, vel_mps: torch.Tensor, fps: float
                   ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Frames' positions and velocities (..., 3, 3) -> (frames until the ball reaches the
    hitter's line across the court, negative past it (...); its distance from him along that
    line in metres (...); (...) bool: the ball comes toward his baseline at least
    `MIN_INCOMING_MPS`). The hitter is `hitter_index`'s."""
    hitter = hitter_index(pos_m)
    player = torch.gather(pos_m[..., :BALL, :2], -2,
                          hitter[..., None, None].expand(*hitter.shape, 1, 2))[..., 0, :]
    ball = pos_m[..., BALL, :2]
    end = torch.sign(ball[..., 0])
    vx = vel_mps[..., BALL, 0]
    incoming = (vx * end >= MIN_INCOMING_MPS)
    frames = (player[..., 0] - ball[..., 0]) * end * fps / vx.abs().clamp_min(MIN_INCOMING_MPS)
    aside_m = (player[..., 1] - ball[..., 1]).abs()
    return frames, aside_m, incoming


def reach_cells(pos_m: torch.Tensor, vel_mps: torch.Tensor, fps: float) -> torch.Tensor:
    """(..., 3, 3) positions and velocities -> (...) int64 the table's cell of each frame's ball
    (frames cell * N_ASIDE_CELLS + aside cell), -1 where the ball is not coming to the player
    on its end."""
    frames, aside_m, incoming = reach_geometry(pos_m, vel_mps, fps)
    fe = torch.tensor(FRAMES_EDGES, dtype=frames.dtype, device=frames.device)
    ae = torch.tensor(ASIDE_EDGES_M, dtype=aside_m.dtype, device=aside_m.device)
    cell = torch.bucketize(frames, fe, right=True) * N_ASIDE_CELLS \
        + torch.bucketize(aside_m, ae, right=True)
    return torch.where(incoming, cell, torch.full_like(cell, -1))


def cell_shift(table: torch.Tensor, cells: torch.Tensor) -> torch.Tensor:
    """A (N_FRAMES_CELLS, N_ASIDE_CELLS) table's logit shift at `cells` (...) (0 at -1)."""
    flat = table.reshape(-1)
    got = flat[cells.clamp_min(0)]
    return torch.where(cells >= 0, got, torch.zeros_like(got))


def bin_kinds(pos_m: torch.Tensor, step_x_m: torch.Tensor, bin_x_m: torch.Tensor,
              contact_bins: torch.Tensor, fps: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Which of the ball's first-axis bins strike it and which only jolt it, per frame:
    positions (..., 3, 3), the ball's physics step along x this frame (...), the bins' x
    offsets in the world (..., n_bins) (a bin's centre, turned with the model's frame),
    the contact bins (n_bins,) -> (strike (..., n_bins), jolt (..., n_bins)) bool. A strike
    bin sends the ball back toward the net faster than `MIN_INCOMING_MPS` (`strike.is_strike`
    on the frame the bin puts down); a jolt bin is a contact bin that does not (the ball
    brakes or leaps on in the air)."""
    side = torch.sign(pos_m[..., BALL, 0])[..., None]
    v_out = (step_x_m[..., None] + bin_x_m) * fps
    strike = (side * v_out < -MIN_INCOMING_MPS) & contact_bins
    return strike, contact_bins & ~strike


def ball_dim_bias(table: torch.Tensor, pos_m: torch.Tensor, vel_mps: torch.Tensor,
                  strike: torch.Tensor, jolt: torch.Tensor, fps: float) -> torch.Tensor:
    """The ball head's logit shifts (..., 3, n_bins) for frames (..., 3, 3) whose strike and
    jolt bins are `strike` and `jolt` (..., n_bins) (`bin_kinds`): each frame's cell shift of
    a strike (`table[STRIKE]`) on its strike bins and of a jolt (`table[JOLT]`) on its jolt
    bins, on the first axis; 0 elsewhere."""
    cells = reach_cells(pos_m, vel_mps, fps)
    shift = (cell_shift(table[STRIKE], cells)[..., None] * strike.to(table.dtype)
             + cell_shift(table[JOLT], cells)[..., None] * jolt.to(table.dtype))
    out = torch.zeros(*shift.shape[:-1], 3, shift.shape[-1], dtype=table.dtype,
                      device=table.device)
    out[..., 0, :] = shift
    return out


def kind_probabilities(logits: torch.Tensor, shift: torch.Tensor) -> torch.Tensor:
    """Each frame's log-mass of (strike, jolt, the rest) (..., 3) and the shifts of the first
    two (..., 2) -> their probabilities after the shifts (..., 3)."""
    z = torch.cat([logits[..., :2] + shift, logits[..., 2:]], dim=-1)
    return z.softmax(-1)
