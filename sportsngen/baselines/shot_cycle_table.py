"""The shot table of the shot-cycle model: one row per racket contact, in the hitter's frame.

Every quantity the behaviour model, the style graphs and the heatmaps need is read once here
from a `RallyData`: both players' positions at the contact (from the frames), the incoming ball
(the previous shot's contact and bounce), the speed the hitter needed to reach the ball, the shot
(type, speed, placement, outcome) and the hitter's recovery position (where he stood when the
opponent next hit the ball).

Hitter's frame: positions are rotated 180 degrees about the vertical when needed so that the
hitter's baseline is at x = -11.885 m and he faces +x; a rotation keeps handedness, so his right
hand points to -y and his deuce court is the y < 0 side. The opponent's position and the incoming
ball's start are described in the opponent's own frame (regions are "his" deuce/ad), every other
position in the hitter's.

Regions (Vid2Player's point-state grid): lateral thirds of the singles court (deuce / centre /
ad, |y| <= 1.372 m is centre) by front / back. A player is "front" closer to the net than
`PLAYER_FRONT_X_M` (midway between service line and baseline, so an approach or a step into a
short ball counts); a bounce is "front" inside the service line.

Speed needed: distance from where the hitter stood at the opponent's contact to this contact
point, over the time between the two contacts (m/s); five bins with edges `SPEED_BIN_EDGES_MPS`
(below a walk, jog, run, fast run, sprint).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.data.tracking import RallyData
from sportsngen.tennis.court import BASELINE_X_M, SERVICE_LINE_X_M, THIRD_WIDTH_M

PLAYER_FRONT_X_M = 0.5 * (SERVICE_LINE_X_M + BASELINE_X_M)
BOUNCE_FRONT_X_M = SERVICE_LINE_X_M
LATERAL = ("deuce", "centre", "ad")
DEPTH = ("front", "back")
REGIONS = tuple(f"{d}_{lat}" for d in DEPTH for lat in LATERAL)  # codes 0..5
NO_REGION = len(REGIONS)          # code 6: no incoming ball (the serve)
SPEED_BIN_EDGES_MPS = (1.0, 2.5, 4.0, 5.5)
N_SPEED_BINS = len(SPEED_BIN_EDGES_MPS) + 1
NO_SPEED_BIN = N_SPEED_BINS       # code 5: the serve
NET_APPROACH_X_M = SERVICE_LINE_X_M + 1.0   # recovered closer to the net than this: at the net

SHOT_TABLE_COLUMNS = (
    "rally_id", "shot_index", "frame", "match_id", "hitter", "opponent", "end", "is_serve",
    "serve_number", "side", "surface", "shot_type", "stroke", "spin", "direction",
    "own_x", "own_y", "opp_x", "opp_y", "contact_x", "contact_y", "contact_z",
    "own_region", "opp_region", "in_start_region", "in_bounce_region", "speed_needed_mps",
    "speed_bin", "speed_mps", "place_x", "place_y", "result", "error_kind",
    "recovery_x", "recovery_y", "net_approach", "next_frame",
)


def region(x_m, y_m) -> np.ndarray:
    """Region code 0..5 (`REGIONS`) of positions already in their player's frame (baseline at
    -x). Front is closer to the net than `PLAYER_FRONT_X_M`. NaN positions get `NO_REGION`."""
    return _region(x_m, y_m, PLAYER_FRONT_X_M)


def bounce_region(x_m, y_m) -> np.ndarray:
    """Region code of bounces in the receiving player's frame: front = inside the service line."""
    return _region(x_m, y_m, BOUNCE_FRONT_X_M)


def _region(x_m, y_m, front_x_m: float) -> np.ndarray:
    x = np.asarray(x_m, dtype=float)
    y = np.asarray(y_m, dtype=float)
    half = THIRD_WIDTH_M / 2.0
    # The deuce court is the player's right: y < 0 in his own frame.
    lateral = np.where(y < -half, 0, np.where(y > half, 2, 1))
    depth = np.where(np.abs(x) < front_x_m, 0, 1)
    code = depth * len(LATERAL) + lateral
    return np.where(np.isfinite(x) & np.isfinite(y), code, NO_REGION).astype(np.int64)


def speed_bin(speed_mps) -> np.ndarray:
    """Bin code 0..4 of the speed needed to reach the ball; NaN (a serve) -> `NO_SPEED_BIN`."""
    s = np.asarray(speed_mps, dtype=float)
    b = np.searchsorted(np.asarray(SPEED_BIN_EDGES_MPS), s, side="right")
    return np.where(np.isfinite(s), b, NO_SPEED_BIN).astype(np.int64)


def player_positions(data: RallyData) -> pd.DataFrame:
    """Player rows of the frames (rally_id, frame, object, x, y), indexed for lookups."""
    f = data.frames
    p = f.loc[f["object"] != "ball", ["rally_id", "frame", "object", "x", "y"]]
    return p.astype({"object": "object"}).set_index(["rally_id", "object", "frame"]).sort_index()


def _lookup(pos: pd.DataFrame, rally: np.ndarray, who: np.ndarray,
            frame: np.ndarray) -> np.ndarray:
    """(n, 2) positions of players `who` at `frame` of `rally`; NaN where a frame is missing
    (or `frame` is -1)."""
    idx = pd.MultiIndex.from_arrays([rally, who.astype(object), frame])
    return pos.reindex(idx)[["x", "y"]].to_numpy(float)


def shot_table(data: RallyData) -> pd.DataFrame:
    """One row per shot with the columns `SHOT_TABLE_COLUMNS` (positions in the hitter's frame).

    ``result`` is "in" (landed in or a winner), "out" or "net" (an error without a bounce);
    ``place_x/y`` the first bounce (NaN for a net ball); ``recovery_x/y`` where the hitter
    stood at the opponent's next contact (NaN when the rally ended first); ``net_approach``
    whether that recovery is closer to the net than `NET_APPROACH_X_M` (NaN without recovery).
    ``shot_type`` is "stroke/spin".
    """
    shots = data.shots.sort_values(["rally_id", "shot_index"], kind="stable").reset_index(
        drop=True)
    r = data.rallies.set_index("rally_id")
    rid = shots["rally_id"].to_numpy(np.int64)
    server = r["server"].reindex(rid).to_numpy(object)
    receiver = r["receiver"].reindex(rid).to_numpy(object)
    hitter = shots["hitter"].to_numpy(object)
    by_server = hitter == server
    opponent = np.where(by_server, receiver, server)
    server_end = r["server_end"].reindex(rid).to_numpy(np.int64)
    end = np.where(by_server, server_end, -server_end)
    c = -end.astype(float)  # multiply x and y by c: the hitter's baseline moves to -x
    frame = shots["frame"].to_numpy(np.int64)

    same_prev = np.r_[False, rid[1:] == rid[:-1]]
    same_next = np.r_[rid[1:] == rid[:-1], False]
    prev_frame = np.where(same_prev, np.r_[-1, frame[:-1]], -1)
    next_frame = np.where(same_next, np.r_[frame[1:], -1], -1)

    pos = player_positions(data)
    own = _lookup(pos, rid, hitter, frame) * c[:, None]
    opp = _lookup(pos, rid, opponent, frame) * -c[:, None]        # in the opponent's frame
    own_prev = _lookup(pos, rid, hitter, prev_frame) * c[:, None]
    recovery = _lookup(pos, rid, hitter, next_frame) * c[:, None]

    cx_w, cy_w = shots["contact_x"].to_numpy(float), shots["contact_y"].to_numpy(float)
    bx_w, by_w = shots["bounce_x"].to_numpy(float), shots["bounce_y"].to_numpy(float)
    cx, cy, bx, by = cx_w * c, cy_w * c, bx_w * c, by_w * c

    def prev(a: np.ndarray) -> np.ndarray:
        return np.where(same_prev, np.r_[np.nan, a[:-1]], np.nan)

    # The incoming ball started at the opponent's contact (described in his frame, -c) and
    # bounced on our side (our frame, c).
    in_start_x, in_start_y = prev(cx_w) * -c, prev(cy_w) * -c
    in_bounce_x, in_bounce_y = prev(bx_w) * c, prev(by_w) * c

    dt_s = (frame - prev_frame) / data.fps
    gap = np.hypot(cx - own_prev[:, 0], cy - own_prev[:, 1])
    needed = np.where(same_prev & (dt_s > 0), gap / np.where(dt_s > 0, dt_s, 1.0), np.nan)

    outcome = shots["outcome"].to_numpy(object)
    result = np.where(outcome == "error", np.where(np.isfinite(bx), "out", "net"), "in")
    stroke = shots["stroke"].astype(str).to_numpy(object)
    spin = shots["spin"].astype(str).to_numpy(object)
    has_rec = np.isfinite(recovery[:, 0])
    net_app = np.where(has_rec, np.abs(recovery[:, 0]) < NET_APPROACH_X_M, np.nan)
    out = pd.DataFrame({
        "rally_id": rid, "shot_index": shots["shot_index"].to_numpy(np.int64), "frame": frame,
        "match_id": r["match_id"].reindex(rid).to_numpy(object),
        "hitter": hitter, "opponent": opponent, "end": end, "is_serve": stroke == "serve",
        "serve_number": r["serve_number"].reindex(rid).to_numpy(np.int64),
        "side": r["side"].reindex(rid).to_numpy(object),
        "surface": r["surface"].reindex(rid).to_numpy(object),
        "shot_type": stroke + "/" + spin, "stroke": stroke, "spin": spin,
        "direction": shots["direction"].astype(str).to_numpy(object),
        "own_x": own[:, 0], "own_y": own[:, 1], "opp_x": opp[:, 0], "opp_y": opp[:, 1],
        "contact_x": cx, "contact_y": cy, "contact_z": shots["contact_z"].to_numpy(float),
        "own_region": region(own[:, 0], own[:, 1]), "opp_region": region(opp[:, 0], opp[:, 1]),
        "in_start_region": region(in_start_x, in_start_y),
        "in_bounce_region": bounce_region(in_bounce_x, in_bounce_y),
        "speed_needed_mps": needed, "speed_bin": speed_bin(needed),
        "speed_mps": shots["speed_mps"].to_numpy(float), "place_x": bx, "place_y": by,
        "result": result, "error_kind": shots["error_kind"].astype(str).to_numpy(object),
        "recovery_x": recovery[:, 0], "recovery_y": recovery[:, 1], "net_approach": net_app,
        "next_frame": next_frame,
    })
    return out.loc[:, list(SHOT_TABLE_COLUMNS)]


def infer_handedness(table: pd.DataFrame) -> dict[str, str]:
    """Each hitter's handedness from where his forehands are struck: a right-hander (facing +x
    in his frame) hits forehands on his right, y below his centre of mass. Majority vote over
    forehand groundstrokes; "right" when a player has none."""
    fh = table[(table["stroke"] == "forehand") & np.isfinite(table["own_y"])]
    side = np.sign(fh["contact_y"] - fh["own_y"])
    vote = side.groupby(fh["hitter"]).mean()
    out = {str(p): "right" for p in table["hitter"].unique()}
    out.update({str(p): ("right" if v <= 0 else "left") for p, v in vote.items()})
    return out
