"""A per-server shift of the receiver's odds of starting his run at the serve.

In the generator a receiver reads a serve from its flight, later against a server who
disguises it (`serve_disguise_s`: Serena Williams +0.11 s, Nadal -0.20 s): facing Williams the
truth's receivers stand still until 5 frames after the contact, facing Sharapova until 3. The
model's receivers start 2-4 frames after every server's contact alike: the decoder sees the
server's identity but its loss hardly weighs a frame or two of one player's serves. (Righting
the start did not bring back Williams' missing aces, 3 % against 13 %: the rule for balls in
reach returns them; docs/evaluation.md, twenty-fifth part. The bundled file does not carry the
table.) `ModelConfig.receiver_start` adds a table of logit shifts, per server identity and
serve (first, second) and frames he has waited so far, added to the receiver's centre bin (no
change of velocity) on both axes while he waits: the serve struck and flying toward his end,
he standing still, the return not yet struck. `sportsngen.train.receiver_start` fits it by
matching his odds of starting at each frame of his wait, on the recorded frames of each
server's serves, to the record's: a start time per server, where one shift for the whole wait
(tried first) made the standing receiver stickier at every frame, so doubled it froze half of
Williams' receivers for good instead of starting them two frames later.
"""

from __future__ import annotations

import torch

from sportsngen.model.inputs import BALL

N_SERVES = 2                   # first, second
N_WAIT = 13                    # waits of 1..12 frames, and 13 or more
RECEIVER = 1                   # the receiver's object index (the server is 0)
STAND_MPS = 0.1                # a receiver slower than this is standing (a start: 0.2 m/s a frame)
SERVE_MIN_HSPEED_MPS = 12.0    # a ball this fast toward the receiver's end is a struck serve
WAIT_FRAMES = 30               # the recorded frames read after a serve's contact (its return
                               # comes later than 0.8 s, the next ball toward him later still)


def receiver_waiting(pos_m: torch.Tensor, vel_mps: torch.Tensor) -> torch.Tensor:
    """Frames (..., 3, 3) positions and velocities -> (...) bool: the ball flies toward the
    receiver's end faster than `SERVE_MIN_HSPEED_MPS` and the receiver stands
    (`STAND_MPS`). The caller says that the return has not been struck."""
    ball_v = vel_mps[..., BALL, :]
    toward = ball_v[..., 0] * torch.sign(pos_m[..., RECEIVER, 0]) > 0
    fast = torch.hypot(ball_v[..., 0], ball_v[..., 1]) > SERVE_MIN_HSPEED_MPS
    standing = torch.hypot(vel_mps[..., RECEIVER, 0], vel_mps[..., RECEIVER, 1]) < STAND_MPS
    return toward & fast & standing


def wait_frames(count: torch.Tensor, waiting: torch.Tensor) -> torch.Tensor:
    """The receivers' waits after one more frame: `count` (...) frames waited so far, 1 more
    where `waiting` (...) bool, 0 where not (the wait is over, or has not begun)."""
    return torch.where(waiting, count + 1, torch.zeros_like(count))


def wait_counts(waiting: torch.Tensor) -> torch.Tensor:
    """(B, T) bool waiting frames -> (B, T) int64 frames waited up to and including each."""
    count = torch.zeros(waiting.shape[0], dtype=torch.long, device=waiting.device)
    out = torch.zeros(waiting.shape, dtype=torch.long, device=waiting.device)
    for t in range(waiting.shape[1]):
        count = wait_frames(count, waiting[:, t])
        out[:, t] = count
    return out


def wait_bin(count: torch.Tensor) -> torch.Tensor:
    """Frames waited (>= 1) -> the table's wait index (0 .. N_WAIT - 1)."""
    return count.long().clamp(1, N_WAIT) - 1


def player_dim_bias(table: torch.Tensor, server_id: torch.Tensor, serve: torch.Tensor,
                    count: torch.Tensor, n_bins: int) -> torch.Tensor:
    """The players' head's logit shifts (B, 2, 2, n_bins) for rallies of server `server_id`
    (B,) on serve `serve` (B,; 0 first, 1 second) whose receivers have waited `count` (B,)
    frames (0: not waiting): the receiver's centre bin on both axes shifted by `table`
    (n_ids, N_SERVES, N_WAIT) at his wait, everything else 0."""
    out = torch.zeros(len(server_id), 2, 2, n_bins, dtype=table.dtype, device=table.device)
    shift = table[server_id.long(), serve.long().clamp(0, N_SERVES - 1), wait_bin(count)]
    out[:, RECEIVER, :, n_bins // 2] = (shift * (count > 0).to(table.dtype))[:, None]
    return out


def start_probability(first_logits: torch.Tensor, second_logits: torch.Tensor,
                      shift: torch.Tensor) -> torch.Tensor:
    """P(the receiver leaves his centre bin) under each candidate `shift` (S,), from his head's
    logits of the first axis (N, n_bins) and of the second given the first's centre bin
    (N, n_bins) -> (S, N): 1 - p(x centre) p(y centre | x centre), the centre bins shifted."""
    c = first_logits.shape[-1] // 2
    out = []
    for lg in (first_logits, second_logits):
        z = lg[None].expand(len(shift), -1, -1).clone()
        z[..., c] = z[..., c] + shift[:, None]
        out.append(z.softmax(-1)[..., c])
    return 1.0 - out[0] * out[1]
