"""Who reaches the ball: each good rally ball's demand on the player due to play it, and whether
he did.

For every good ball, the player due to answer it is measured from the hitter's contact on: a
rally ball (a contact after the serve, shot >= 1) whose first bounce is in the court, or a serve
(shot 0, answered by the return) whose first bounce is in its service box:

- ``need_m``: how close the ball comes, after its bounce and below `REACH_MAX_Z_M`, to where
  that player stood at the contact (how far he had to go);
- ``gap_m``: how close it came to him as he moved (0.8-1.2 m is a racket's reach);
- ``answered``: whether the next contact came (his);
- ``time_s`` and ``need_speed_mps``: the time from the contact to the ball's point nearest where
  he stood, and the mean speed that asks of him (a fast ball gives less time for the same run);
- ``toward_mps``: his mean speed toward the point where the ball came nearest to where he stood,
  in bins of `BIN_FRAMES` frames from the contact.

Read by `need_m`, the answered share says whether a model's players lose balls by where they
stand (balls that come close are lost too) or by how they run (only the far ones): the
generator's players answer 0.92-0.99 of the good balls at every need up to 5 m; the bundled
model's lose the far ones (docs/evaluation.md, fifteenth part). The tables read rally balls
or serves (`shots="rally"` / `"serve"`): a model whose receivers miss serves they could reach
concedes aces (sixteenth part). `contact_rows` and `contact_states` read where the balls that
are answered get struck: how far behind the baseline, how high, how far from the hitter's
centre, and how fast the ball comes and goes (seventeenth part). Runs on any `RallyData`
(a simulation's realistic rallies, or generated truth) in seconds.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.data.tracking import RallyData
from sportsngen.eval.physical import iter_tracks
from sportsngen.tennis.court import (
    BASELINE_X_M,
    SINGLES_HALF_WIDTH_M,
    is_in_service_box,
)
from sportsngen.tennis.rally import BALL, RECEIVER, SERVER

REACH_MAX_Z_M = 2.2          # a ball above this is not yet playable (the rules' reach: 2.3 m)
BIN_FRAMES = 5
TOWARD_FRAMES = 40
NEED_BINS_M = (0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 7.0, 30.0)
# Bins of the mean speed a ball asks for (need over the time it gives, m/s).
NEED_SPEED_BINS_MPS = (0.0, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 100.0)
# Bins of how close the ball came to him as he moved (m): within a racket's reach (0.8-1.2 m
# at the truth's contacts) to out of any player's (the generator's reach 1.7-1.95 m).
GAP_BINS_M = (0.0, 0.8, 1.2, 1.5, 1.8, 2.2, 3.0, 30.0)
SHOTS = {"rally": lambda shot: shot >= 1, "serve": lambda shot: shot == 0}


def _xy_tracks(tracks: dict, names: tuple[str, str]):
    """A rally's tracks (`_realistic`) -> the ball (T, 3) and each named player's (T, 2)."""
    return tracks["ball"], {n: tracks[n][:, :2] for n in names}


def _realistic(data: RallyData) -> tuple[pd.DataFrame, dict, pd.DataFrame]:
    """The rallies not flagged unrealistic (a simulation's flag; all of a recording's):
    their table by rally_id, their tracks by rally (object -> (T, 3) from the rally's first
    frame, `eval.physical.iter_tracks`), and their shots in order."""
    r = data.rallies.set_index("rally_id")
    if "realistic" in r:
        r = r[r["realistic"].astype(bool)]
    frames: dict = {}
    for tr in iter_tracks(data, r.index):
        for b, row in enumerate(tr.rallies.itertuples(index=False)):
            pos = tr.pos_m[b, :tr.length[b]]
            frames[row.rally_id] = {"ball": pos[:, BALL], str(row.server): pos[:, SERVER],
                                    str(row.receiver): pos[:, RECEIVER]}
    shots = data.shots[data.shots["rally_id"].isin(r.index)].sort_values(
        ["rally_id", "shot_index"])
    return r, frames, shots


def reach_rows(data: RallyData) -> pd.DataFrame:
    """One row per good ball (module doc): rally_id, shot (0 the serve, 1 the return), role of
    the player due ("server" / "receiver"), answered, need_m, gap_m, toward_mps_k for bins k.
    Rallies flagged not realistic (a simulation's) are left out."""
    r, frames, shots = _realistic(data)
    rows = []
    for rid, s in shots.groupby("rally_id", sort=False):
        names = (str(r.at[rid, "server"]), str(r.at[rid, "receiver"]))
        ball, players = _xy_tracks(frames[rid], names)
        contact = s["frame"].to_numpy(int)
        hitter = s["hitter"].to_numpy(str)
        bounce = s[["bounce_x", "bounce_y"]].to_numpy(float)
        for k in range(len(s)):
            bx, by = bounce[k]
            a = contact[k]
            if not np.isfinite(bx) or a + 2 >= len(ball):
                continue
            side = -np.sign(ball[a, 0])       # the half the ball is sent to
            if k == 0:
                # The ball's centre decides, as in the generator and the rules
                # (`tennis.rally.LINE_ALLOWANCE_M`): a ball-radius allowance counted serves
                # the generator had called faults as good.
                good = bool(is_in_service_box(bx, by, int(r.at[rid, "server_end"]),
                                              str(r.at[rid, "side"])))
            else:
                good = (np.sign(bx) == side and abs(bx) <= BASELINE_X_M
                        and abs(by) <= SINGLES_HALF_WIDTH_M)
            if not good:
                continue
            end = contact[k + 1] + 1 if k + 1 < len(s) else len(ball)
            seg = np.arange(a + 2, min(end, len(ball)))
            post = seg[(np.sign(ball[seg, 0]) == side) & (np.abs(ball[seg, 0]) >= abs(bx) - 0.01)
                       & (ball[seg, 2] < REACH_MAX_Z_M)]
            if len(post) == 0:
                continue
            due = names[1] if hitter[k] == names[0] else names[0]
            p = players[due]
            post = post[post < len(p)]
            if len(post) == 0:
                continue
            from_start = np.linalg.norm(ball[post, :2] - p[a], axis=1)
            nearest = post[int(np.argmin(from_start))]
            target = ball[nearest, :2]
            time_s = (nearest - a) / data.fps
            heading = (target - p[a]) / max(float(np.linalg.norm(target - p[a])), 1e-6)
            n = min(TOWARD_FRAMES, len(p) - 1 - a)
            toward = (np.diff(p[a:a + n + 1], axis=0) * data.fps) @ heading
            row = {"rally_id": rid, "shot": k, "role": "server" if due == names[0] else "receiver",
                   "answered": k + 1 < len(s), "need_m": float(from_start.min()),
                   "time_s": time_s, "need_speed_mps": float(from_start.min()) / time_s,
                   "gap_m": float(np.linalg.norm(ball[post, :2] - p[post], axis=1).min())}
            for j in range(0, TOWARD_FRAMES, BIN_FRAMES):
                part = toward[j:j + BIN_FRAMES]
                row[f"toward_mps_{j}"] = float(part.mean()) if len(part) == BIN_FRAMES else np.nan
            rows.append(row)
    return pd.DataFrame(rows)


def _pick(rows: pd.DataFrame, shots: str) -> pd.DataFrame:
    if shots not in SHOTS:
        raise ValueError(f"shots must be one of {sorted(SHOTS)}, got {shots!r}")
    return rows[SHOTS[shots](rows["shot"])] if len(rows) else rows


def answered_by_need(rows: pd.DataFrame, by: str = "need_m",
                     shots: str = "rally") -> pd.DataFrame:
    """Share answered and count per bin of `by` ("need_m": `NEED_BINS_M`, "need_speed_mps":
    `NEED_SPEED_BINS_MPS`, "gap_m": `GAP_BINS_M`) and role of the player due, over rally balls
    or serves (`shots`). By `gap_m` it separates where the players are (how many balls pass
    beyond a racket's reach) from whether the ball is struck when they are there."""
    bins = {"need_m": NEED_BINS_M, "need_speed_mps": NEED_SPEED_BINS_MPS, "gap_m": GAP_BINS_M}
    if by not in bins:
        raise ValueError(f"by must be one of {sorted(bins)}, got {by!r}")
    rows = _pick(rows, shots)
    if rows.empty:
        raise ValueError(f"no good {'serves' if shots == 'serve' else 'rally balls'} to read "
                         "(no rally reached a contact after them)")
    need = pd.cut(rows[by], bins[by])
    t = rows.groupby([need, "role"], observed=True)["answered"].agg(["mean", "count"])
    t = t.unstack("role")
    t["count"] = t["count"].fillna(0).astype(int)      # a role with no ball in a bin: 0
    t.columns = [f"{'answered' if a == 'mean' else 'n'} ({b})" for a, b in t.columns]
    t.index = [f"{iv.left:g}-{iv.right:g}" for iv in t.index]
    names = {"need_m": "need (m)", "need_speed_mps": "need (m/s)", "gap_m": "gap (m)"}
    return t.rename_axis(names[by]).reset_index()


def toward_speeds(rows: pd.DataFrame, need_m: tuple[float, float] = (3.0, 7.0),
                  shots: str = "rally") -> pd.DataFrame:
    """Mean speed toward the ball's nearest point (m/s) by role, frame bins from the contact,
    over the rally balls or serves (`shots`) whose need lies in `need_m`."""
    rows = _pick(rows, shots)
    cols = [c for c in rows.columns if c.startswith("toward_mps_")]
    sel = rows[(rows["need_m"] > need_m[0]) & (rows["need_m"] <= need_m[1])]
    out = sel.groupby("role")[cols].mean()
    out.columns = [f"{c.rsplit('_', 1)[1]}-{int(c.rsplit('_', 1)[1]) + BIN_FRAMES - 1}"
                   for c in cols]
    return out.rename_axis("frames after the contact").reset_index()


CONTACT_COLUMNS = ("behind_m", "height_m", "gap_m", "in_mps", "out_mps")


def contact_rows(data: RallyData) -> pd.DataFrame:
    """One row per rally contact after the serve (shot >= 1) of the realistic rallies: rally_id,
    shot, role of the hitter, `behind_m` (how far behind his baseline the ball was struck;
    negative inside the court), `height_m`, `gap_m` (ball to the hitter's centre,
    horizontally), `in_mps` and `out_mps` (the ball's speed over the frame before the contact's
    frame and over the second frame after it). Read off the tracks at the shots table's frame,
    not its contact columns (the generator's exact contact, between frames), so simulated and
    recorded points are measured alike. `shot_profile` describes the same strikes pooled over
    both players (where they land, from the strike's first frames); this reads where they are
    struck, player by player. Where the players meet the ball: teacher-forced
    on recorded states the bundled strike head draws the record's errors and speeds shot by
    shot, so strikes that fly slower in rollouts come from the states (docs/evaluation.md,
    seventeenth part)."""
    r, frames, shots = _realistic(data)
    shots = shots[shots["shot_index"] >= 1]
    rows = []
    for rid, s in shots.groupby("rally_id", sort=False):
        names = (str(r.at[rid, "server"]), str(r.at[rid, "receiver"]))
        ball, players = _xy_tracks(frames[rid], names)
        for k, a, hitter in zip(s["shot_index"], s["frame"].astype(int), s["hitter"].astype(str)):
            if a < 2 or a + 3 > len(ball) or hitter not in players or a >= len(players[hitter]):
                continue
            rows.append({"rally_id": rid, "shot": int(k), "player": hitter,
                         "role": "server" if hitter == names[0] else "receiver",
                         "behind_m": abs(float(ball[a, 0])) - BASELINE_X_M,
                         "height_m": float(ball[a, 2]),
                         "gap_m": float(np.linalg.norm(ball[a, :2] - players[hitter][a])),
                         "in_mps": float(np.linalg.norm(ball[a - 1] - ball[a - 2]) * data.fps),
                         "out_mps": float(np.linalg.norm(ball[a + 2] - ball[a + 1]) * data.fps)})
    return pd.DataFrame(rows, columns=["rally_id", "shot", "player", "role", *CONTACT_COLUMNS])


def contact_states(rows: pd.DataFrame, max_shot: int = 4) -> pd.DataFrame:
    """Medians of `contact_rows` by shot (1 the return) up to `max_shot` and hitter, with the
    hitter's role and the contacts counted. By player, not pooled: players differ by metres
    (the generator's Nadal returns first serves from 3.3 m behind his baseline, Federer from
    0.1 m), so a pooled median says who returned more often."""
    rows = rows[rows["shot"] <= max_shot]
    if rows.empty:
        raise ValueError("no rally contact after the serve to read")
    keys = ["shot", "player"]
    t = rows.groupby(keys)[list(CONTACT_COLUMNS)].median()
    t.insert(0, "n", rows.groupby(keys).size())
    t.insert(0, "role", ["receiver" if k % 2 else "server" for k, _ in t.index])
    return t.reset_index()
