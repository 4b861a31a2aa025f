"""The model's input schema: the objects of a frame and their order, the eight numbers of an
object token (position 3, velocity 3 as a backward difference, so a token never sees the future,
distance to the ball, time since the rally began) and the constants of the sport that normalise
them, the identity rows reserved before the named players, and the numeric score vector of a
window's context. What `data.tokens` fills from tracking and the decoder reads."""

from __future__ import annotations

import numpy as np
import torch

from sportsngen.tennis.court import BASELINE_X_M, SINGLES_HALF_WIDTH_M

OBJECTS = ("server", "receiver", "ball")
N_OBJECTS = len(OBJECTS)
BALL = 2                     # index of the ball among the objects of a frame
BALL_ID, GENERIC_ID = 0, 1   # identity indices reserved before the named players
N_SPECIAL_IDS = 2
N_FEATURES = 8               # position 3, velocity 3, distance to ball 1, elapsed time 1

# Normalising constants (sport scale, so features are O(1)).
POS_SCALE_M = (BASELINE_X_M, SINGLES_HALF_WIDTH_M, 3.0)
VEL_SCALE_MPS = 10.0
DIST_SCALE_M = 10.0
TIME_SCALE_S = 10.0

SCORE_FIELDS = ("server_sets", "receiver_sets", "server_games", "receiver_games",
                "server_points", "receiver_points", "in_tiebreak")
SCORE_SCALE = (3.0, 3.0, 6.0, 6.0, 4.0, 4.0, 1.0)


def score_vector(server_sets, receiver_sets, server_games, receiver_games, server_points,
                 receiver_points, in_tiebreak) -> np.ndarray:
    """Normalised score features (order `SCORE_FIELDS`, server's view); scalars or arrays.

    The same quantities as the first seven of `MatchState.score_vector()` (see
    `score_features`): points are deuce-reduced (a long deuce game maps onto 40-40 or
    advantage, a long tie-break onto 6-6 or one point more) so they stay bounded.
    """
    sp = np.asarray(server_points, dtype=np.float32)
    rp = np.asarray(receiver_points, dtype=np.float32)
    tb = np.asarray(in_tiebreak, dtype=np.float32)
    excess = np.maximum(np.minimum(sp, rp) - np.where(tb > 0, 6.0, 3.0), 0.0)
    cols = [server_sets, receiver_sets, server_games, receiver_games, sp - excess, rp - excess, tb]
    out = np.stack([np.asarray(c, dtype=np.float32) / s for c, s in zip(cols, SCORE_SCALE)],
                   axis=-1)
    return out.astype(np.float32)


def score_features(match_score_vector) -> np.ndarray:
    """Model score features from `MatchState.score_vector()` (its first seven fields, raw
    counts from the server's view, already deuce-reduced): for the simulator."""
    v = np.asarray(match_score_vector, dtype=np.float32)[..., :len(SCORE_FIELDS)]
    return (v / np.asarray(SCORE_SCALE, dtype=np.float32)).astype(np.float32)


def object_features(pos_m: torch.Tensor, vel_mps: torch.Tensor, t_s: torch.Tensor) -> torch.Tensor:
    """(..., T, 3, 3) positions and velocities, (..., T) times -> (..., T, 3, N_FEATURES)."""
    scale = torch.tensor(POS_SCALE_M, dtype=pos_m.dtype, device=pos_m.device)
    dist = torch.linalg.vector_norm(pos_m - pos_m[..., BALL:BALL + 1, :], dim=-1, keepdim=True)
    t = (t_s / TIME_SCALE_S)[..., None, None].expand(*pos_m.shape[:-1], 1)
    return torch.cat([pos_m / scale, vel_mps / VEL_SCALE_MPS, dist / DIST_SCALE_M, t], dim=-1)


def flip_xy(arr):
    """Rotate by 180 degrees about the vertical through the net centre: (x, y) -> (-x, -y).
    A numpy array or a torch tensor (a collated batch's); a new one either way."""
    out = arr.clone() if torch.is_tensor(arr) else arr.copy()
    out[..., :2] *= -1
    return out
