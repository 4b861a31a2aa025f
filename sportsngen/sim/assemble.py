"""Simulated tracks + rally-end rules + event labels -> a `RallyData` (frames, rallies, shots).

The rallies table is the schema's plus the simulator's own columns:

- ``realistic`` (bool) and ``failed_checks`` (the rules' names, ";"-joined): rallies breaking
  physics are kept and flagged, never dropped; statistics leave them out (`realistic_points`);
- ``rules_winner`` / ``classifier_winner`` (0 server, 1 receiver, -1 none): the point winner by
  the rally-end rules (the one used) and by the event classifier's reading of the last shot;
- ``n_shots`` (racket contacts the rules found).

`end_reason` is the rules' (fault, ace, double fault, winner, error), with an error's kind
(forced / unforced) from the event classifier's label of the last shot (unforced when it says
neither); a rally the rules could not decide (duration cap, no serve) has end_reason "none" and
no winner. Speeds (serve_kmh, speed_mps) are finite differences over the frame after contact.

The shots table's `outcome` and `error_kind` follow the rules as the generator's do
(`rules_shot_outcome`): every shot but the last in play, the last one the rally's end. They
were the event classifier's labels, which disagreed with the rules' end on most decided
rallies of the bundled model (1,500-point check: 392 of 394 aces' serves and 474 of 759
winners labelled errors, 590 shots before the last labelled errors), so a report said "error"
under an ace. The frames keep the classifier's per-frame labels.

A serve's `direction` is its bounce's third of the box (`tennis.court.serve_zone`), the
classifier's label only for a serve without a bounce. The classifier reads a serve well on a
track that goes on past the return but not on one the rules cut at a fault or an ace: on a
500-point check of the bundled model 296 of 297 faults were labelled "T" (170 bouncing wide)
and 57 of 93 wide aces "T" (on the generator's full tracks it called 513 of 534 wide serves
wide). The leak check stratifies by this label, so its serve cells compared wide aces with
returned T serves.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.data.tracking import (
    DIRECTIONS,
    ERROR_KINDS,
    FRAME_COLUMNS,
    OUTCOMES,
    RALLY_COLUMNS,
    SHOT_COLUMNS,
    STROKES,
    RallyData,
)
from sportsngen.sim.events import LABEL_NAMES, classifier_winner, shot_labels
from sportsngen.tennis.court import serve_zone

PLAN_COLUMNS = [c for c in RALLY_COLUMNS if c not in
                ("winner", "end_reason", "end_detail", "serve_kmh", "rally_length")]
_VOCABS = {"stroke": STROKES, "direction": DIRECTIONS, "outcome": OUTCOMES,
           "error_kind": ERROR_KINDS}


# The last shot's (outcome, error_kind) by the rules' end_reason; "none" (undecided): in play.
_LAST_SHOT = {"ace": ("winner", "none"), "winner": ("winner", "none"),
              "fault": ("error", "fault"), "double_fault": ("error", "fault"),
              "forced_error": ("error", "forced"), "unforced_error": ("error", "unforced"),
              "none": ("in_play", "none")}


def rules_shot_outcome(end_reason: str, shot_index: int, n_shots: int) -> tuple[str, str]:
    """(outcome, error_kind) of shot `shot_index` of a rally of `n_shots` contacts that ended by
    `end_reason` (the rules', an error's kind already resolved), as the generator labels its
    shots: a shot that is not the last was in play."""
    if end_reason not in _LAST_SHOT:
        raise ValueError(f"unknown end_reason {end_reason!r}; known: {sorted(_LAST_SHOT)}")
    if not 0 <= shot_index < n_shots:
        raise ValueError(f"shot_index {shot_index} outside a rally of {n_shots} shots")
    return _LAST_SHOT[end_reason] if shot_index == n_shots - 1 else ("in_play", "none")


def _speed_after_mps(track: np.ndarray, frame: int, length: int, fps: float) -> float:
    """Ball speed over one to two frame times after a contact struck on `frame`, as the
    statistics read any track (`tennis.contact_speed`; NaN near the end)."""
    a, b = frame + 1, frame + 2
    if b >= length:
        return float("nan")
    return float(np.linalg.norm(track[b] - track[a]) * fps)


def assemble(plan: pd.DataFrame, pos_m: np.ndarray, length: np.ndarray,
             results: pd.DataFrame, labels: np.ndarray | None, fps: float) -> RallyData:
    """`plan` one row a rally (`PLAN_COLUMNS`), `pos_m` (B, T, 3, 3), `length` (B,), `results`
    the tracker's rows (`RallyTracker.results`), `labels` (B, T, 4) event classifier indices or
    None -> `RallyData` (not validated: simulated rallies may leave the court)."""
    b = len(plan)
    plan = plan.reset_index(drop=True)
    if labels is None:
        labels = np.zeros(pos_m.shape[:2] + (len(LABEL_NAMES),), dtype=np.int64)
    winners, reasons, details, kmh, rally_len, g_win = [], [], [], [], [], []
    shot_rows: list[dict] = []
    names = plan[["server", "receiver"]].to_numpy(dtype=object)
    for i in range(b):
        res = results.iloc[i]
        n = int(length[i])
        frames = [int(f) for f in res["contact_frames"]]
        hitters = [int(h) for h in res["hitters"]]
        lab = shot_labels(labels[i], frames, n)
        reason = str(res["end_reason"])
        if reason == "error":
            kind = ERROR_KINDS[lab[-1, 3]] if len(lab) else "none"
            reason = "forced_error" if kind == "forced" else "unforced_error"
        w = int(res["winner"])
        winners.append(names[i, w] if w in (0, 1) else "")
        reasons.append(reason)
        details.append(str(res["end_detail"]))
        track = pos_m[i, :, 2]
        kmh.append(_speed_after_mps(track, frames[0], n, fps) * 3.6 if frames else np.nan)
        n_shots = len(frames)
        rally_len.append({"fault": 0, "double_fault": 0, "ace": 1, "winner": n_shots,
                          "none": max(n_shots - 1, 0)}.get(reason, max(n_shots - 1, 0)))
        last_outcome = OUTCOMES[lab[-1, 2]] if len(lab) else "none"
        g_win.append(classifier_winner(last_outcome, hitters[-1] if hitters else -1))
        bounces = [(int(f), xy) for f, xy in zip(res["bounce_frames"], res["bounces_m"])]
        for k, (f, h) in enumerate(zip(frames, hitters)):
            nxt = frames[k + 1] if k + 1 < n_shots else n
            bx, by = next(((xy[0], xy[1]) for bf, xy in bounces if f < bf < nxt),
                          (np.nan, np.nan))
            c = res["contacts_m"][k]
            outcome, error_kind = rules_shot_outcome(reason, k, n_shots)
            labels_k = {name: _VOCABS[name][lab[k, j]] for j, name in enumerate(LABEL_NAMES)}
            if k == 0 and np.isfinite(by):
                labels_k["direction"] = str(serve_zone(by))
            shot_rows.append({
                "rally_id": int(plan["rally_id"].iat[i]), "shot_index": k, "frame": f,
                "hitter": names[i, h] if h in (0, 1) else "",
                **labels_k,
                "outcome": outcome, "error_kind": error_kind,
                "spin": "none", "contact_x": c[0], "contact_y": c[1], "contact_z": c[2],
                "speed_mps": _speed_after_mps(track, f, n, fps), "bounce_x": bx,
                "bounce_y": by})
    rallies = plan[PLAN_COLUMNS].copy()
    rallies["winner"] = winners
    rallies["end_reason"] = reasons
    rallies["end_detail"] = details
    rallies["serve_kmh"] = np.asarray(kmh, dtype=float)
    rallies["rally_length"] = np.asarray(rally_len, dtype=np.int64)
    rallies["realistic"] = results["realistic"].to_numpy(dtype=bool)
    rallies["failed_checks"] = [";".join(c) for c in results["failed_checks"]]
    rallies["rules_winner"] = results["winner"].to_numpy(dtype=np.int64)
    rallies["classifier_winner"] = np.asarray(g_win, dtype=np.int64)
    rallies["n_shots"] = results["n_shots"].to_numpy(dtype=np.int64)
    shots = pd.DataFrame(shot_rows, columns=list(SHOT_COLUMNS))
    return RallyData.from_tables(_frames(plan, pos_m, length, labels, fps), rallies, shots,
                                 fps=fps, validate=False)


def _frames(plan: pd.DataFrame, pos_m: np.ndarray, length: np.ndarray, labels: np.ndarray,
            fps: float) -> pd.DataFrame:
    """Frames rows of every rally (per rally: ball, server, receiver blocks), vectorised."""
    length = np.asarray(length, dtype=np.int64)
    rid = np.repeat(plan["rally_id"].to_numpy(np.int64), 3 * length)
    frame = np.concatenate([np.tile(np.arange(n), 3) for n in length]) if len(length) else \
        np.zeros(0, np.int64)
    ri = np.repeat(np.arange(len(plan)), 3 * length)
    slot = np.concatenate([np.repeat([2, 0, 1], n) for n in length]) if len(length) else \
        np.zeros(0, np.int64)
    xyz = pos_m[ri, frame, slot].astype(float)
    obj = np.where(slot == 2, "ball", np.where(slot == 0, plan["server"].to_numpy(str)[ri],
                                               plan["receiver"].to_numpy(str)[ri]))
    out = {"rally_id": rid, "frame": frame, "t": frame / fps, "object": obj,
           "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]}
    lab = labels[ri, frame]
    for j, name in enumerate(LABEL_NAMES):
        out[name] = np.asarray(_VOCABS[name], dtype=object)[lab[:, j]]
    return pd.DataFrame(out, columns=list(FRAME_COLUMNS))


def realistic_points(data: RallyData) -> RallyData:
    """Only the points all of whose rallies are realistic and decided (for statistics)."""
    r = data.rallies
    bad = ~r["realistic"].astype(bool) | (r["end_reason"] == "none")
    bad_points = set(zip(r.loc[bad, "match_id"], r.loc[bad, "point"]))
    keep = [rid for rid, m, p in zip(r["rally_id"], r["match_id"], r["point"])
            if (m, p) not in bad_points]
    return data.subset(keep)
