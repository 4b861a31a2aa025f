"""Rallies of a `RallyData` as the compact JSON the report's rally viewer plays.

Positions go in as integer centimetres (a third of the text of floats, and finer than any
tracking); players are indexed 0/1 as in the report (the match's player 1 and 2), not as
server/receiver, so each keeps his colour from rally to rally. Bounces are the rally-end
rules' own (`sportsngen.eval.rules`), the ones that decided the rally; contacts and their
labels come from the shots table.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.data.tracking import RallyData


def _cm(a) -> list[int]:
    return np.rint(np.asarray(a, dtype=float) * 100.0).astype(np.int64).ravel().tolist()


def _label(v) -> str:
    return "" if pd.isna(v) else str(v)


def rally_payload(data: RallyData, players: tuple[str, str]) -> dict[str, dict]:
    """rally_id (as a string) -> the viewer's record of that rally (see the module)."""
    from sportsngen.eval.rules import analyse_rally_data  # torch via the token code

    f = data.frames
    extra = sorted(set(f["object"].astype(str)) - {"ball", *players})
    if extra:
        raise ValueError(f"frames hold objects {extra[:5]} that are neither the ball nor "
                         f"the players {players}")
    role = np.select([f["object"] == "ball", f["object"] == players[0]], [2, 0], 1)
    wide = pd.DataFrame({"rally_id": f["rally_id"].to_numpy(), "frame": f["frame"].to_numpy(),
                         "role": role, "x": f["x"].to_numpy(float), "y": f["y"].to_numpy(float),
                         "z": f["z"].to_numpy(float)})
    wide = wide.pivot_table(index=["rally_id", "frame"], columns="role",
                            values=["x", "y", "z"]).sort_index()
    # A frame where some object is untracked keeps its last known position.
    wide = wide.groupby(level=0).ffill().groupby(level=0).bfill()
    rules = analyse_rally_data(data)
    shots = data.shots.sort_values(["rally_id", "shot_index"], kind="stable")
    shots_by = dict(tuple(shots.groupby("rally_id", sort=False)))
    index = {p: i for i, p in enumerate(players)}
    out = {}
    for row in data.rallies.itertuples(index=False):
        rid = int(row.rally_id)
        tr = wide.loc[rid]
        f0 = int(tr.index[0])
        ball = tr[[("x", 2), ("y", 2), ("z", 2)]].to_numpy()
        bounces = rules.at[rid, "bounces_m"] if rid in rules.index else []
        b_frames = rules.at[rid, "bounce_frames"] if rid in rules.index else []
        sh = shots_by.get(rid, shots.iloc[:0])
        out[str(rid)] = {
            "id": rid, "point": int(row.point), "serve": int(row.serve_number),
            "server": index.get(str(row.server), 0), "end": int(row.server_end),
            "side": str(row.side), "score": str(row.score), "f0": f0, "n": len(tr),
            "ball": _cm(ball),
            "p": [_cm(tr[[("x", k), ("y", k)]].to_numpy()) for k in (0, 1)],
            "bounces": [[int(fr) - f0, *_cm(xy)] for fr, xy in zip(b_frames, bounces)],
            "shots": [{"f": int(s.frame) - f0, "hitter": index.get(str(s.hitter), 0),
                       "stroke": _label(s.stroke), "direction": _label(s.direction),
                       "outcome": _label(s.outcome), "error": _label(s.error_kind),
                       "kmh": None if pd.isna(s.speed_mps) else round(float(s.speed_mps) * 3.6),
                       "c": _cm([s.contact_x, s.contact_y, s.contact_z])}
                      for s in sh.itertuples(index=False)],
            "end_reason": _label(row.end_reason), "end_detail": _label(row.end_detail),
            "winner": index.get(_label(row.winner), -1),
        }
    return out
