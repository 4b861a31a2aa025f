"""A tiny deterministic maker of schema-valid tracking, for tests and training smoke runs.

Not tennis physics: the ball flies on drag-free parabolas (serve, then shots that bounce once on
the far side and are met at about hip height), and the players walk towards where the ball will be
met, then back to the middle of their baseline. Enough structure for a model to learn something
(constant-velocity flight, bounces, players chasing the ball) and every column of `RallyData`
filled with valid categories. The real data source is `sportsngen.synth` (the generator).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.data.tracking import FPS_DEFAULT, RallyData
from sportsngen.tennis.court import BASELINE_X_M, SINGLES_HALF_WIDTH_M

GRAVITY_MPS2 = 9.81
TOY_PLAYERS = ("Toy Alpha", "Toy Beta", "Toy Gamma", "Toy Delta")
TOY_TOURNAMENTS = ("Toy Open", "Toy Masters")
TOY_SURFACES = ("hard", "clay", "grass")
PLAYER_SPEED_MPS = 5.0
TOSS_S = 0.8       # from the start of the toss to the serve contact
AFTER_END_S = 0.6  # tracking continues a little after the last bounce


def _arc(p0: np.ndarray, p1: np.ndarray, flight_s: float, t_s: np.ndarray) -> np.ndarray:
    """Positions at times `t_s` (from 0) on the drag-free parabola from p0 to p1 in flight_s."""
    v = (p1 - p0) / flight_s
    v[2] = (p1[2] - p0[2] + 0.5 * GRAVITY_MPS2 * flight_s ** 2) / flight_s
    out = p0[None, :] + t_s[:, None] * v[None, :]
    out[:, 2] -= 0.5 * GRAVITY_MPS2 * t_s ** 2
    return out


def _walk(start: np.ndarray, targets: np.ndarray, dt: float) -> np.ndarray:
    """A 2-D track that steps towards `targets[i]` at frame i at most PLAYER_SPEED_MPS."""
    out = np.empty_like(targets)
    pos = start.astype(float).copy()
    step = PLAYER_SPEED_MPS * dt
    for i, tgt in enumerate(targets):
        d = tgt - pos
        dist = float(np.hypot(d[0], d[1]))
        if dist > step:
            d *= step / dist
        pos = pos + d
        out[i] = pos
    return out


def _one_rally(rng: np.random.Generator, fps: float, server_end: int, side: str,
               serve_number: int) -> dict:
    """Ball and player tracks plus shot list of one rally (server at x = server_end * ...)."""
    dt = 1.0 / fps
    s = float(server_end)
    side_sign = 1.0 if side == "deuce" else -1.0
    # The server stands just behind the baseline on their side of the centre mark; the deuce
    # side is y < 0 for the server at x > 0 (right-handed view from their end).
    server0 = np.array([s * (BASELINE_X_M + 0.3), -s * side_sign * 0.8])
    receiver0 = np.array([-s * (BASELINE_X_M + 1.0), s * side_sign * 2.5])
    n_shots = int(rng.integers(1, 7))
    ending = rng.choice(["winner", "error"]) if n_shots > 1 else "ace"

    # Key points of the ball: contact positions and times; each shot bounces once before the
    # next contact (or, for the last, flies on and bounces again).
    contacts, times, bounces = [], [], []
    toss_start = np.array([server0[0], server0[1], 1.0])
    contact = np.array([server0[0] - s * 0.2, server0[1], 2.7 + 0.2 * rng.random()])
    t = TOSS_S
    hitter_sign = s  # sign of x of the hitter's baseline
    for k in range(n_shots):
        contacts.append(contact)
        times.append(t)
        last = k == n_shots - 1
        if k == 0:  # the serve lands in the diagonal service box
            bx = -hitter_sign * (3.0 + 3.0 * rng.random())
            by = hitter_sign * side_sign * (0.4 + 3.2 * rng.random())
            flight = 0.55 + 0.15 * rng.random()
        else:
            bx = -hitter_sign * (6.0 + 5.0 * rng.random())
            by = (rng.random() * 2 - 1) * (SINGLES_HALF_WIDTH_M - 0.5)
            flight = 0.9 + 0.4 * rng.random()
            if last and ending == "error":
                bx = -hitter_sign * (BASELINE_X_M + 0.5 + rng.random())
        bounce = np.array([bx, by, 0.0])
        bounces.append((bounce, t + flight))
        t_bounce = t + flight
        # Next contact: behind the bounce, at about hip height, 0.5-0.8 s later.
        after = 0.5 + 0.3 * rng.random()
        nxt = bounce + np.array([-hitter_sign * 2.5 * after / 0.6,
                                 (rng.random() * 2 - 1) * 1.0, 0.0])
        nxt[0] = np.clip(nxt[0], -BASELINE_X_M - 3.0, BASELINE_X_M + 3.0)
        nxt[2] = 0.8 + 0.4 * rng.random()
        contact = nxt
        t = t_bounce + after
        hitter_sign = -hitter_sign
    end_s = t - 0.2 + AFTER_END_S  # the last "contact" is never made: the ball flies on
    n_frames = int(np.floor(end_s * fps)) + 1
    t_s = np.arange(n_frames) * dt

    ball = np.empty((n_frames, 3))
    toss = t_s <= TOSS_S
    ball[toss] = _arc(toss_start, contacts[0], TOSS_S, t_s[toss])
    segments = []
    for k in range(n_shots):
        bounce, tb = bounces[k]
        last = k == n_shots - 1
        t_next, nxt = (t, contact) if last else (times[k + 1], contacts[k + 1])
        segments.append((times[k], tb, contacts[k], bounce))
        segments.append((tb, t_next, bounce, nxt))
    for t0, t1, p0, p1 in segments:
        sel = (t_s > t0) & (t_s <= t1)
        ball[sel] = _arc(p0, p1, t1 - t0, t_s[sel] - t0)
    beyond = t_s > segments[-1][1]
    if beyond.any():  # after the final arc, roll along the ground
        ball[beyond] = ball[~beyond][-1] * np.array([1.0, 1.0, 0.0])
    ball[:, 2] = np.maximum(ball[:, 2], 0.0)

    # Players: each walks towards their next contact point, else back to the baseline middle.
    home = {0: np.array([s * (BASELINE_X_M + 0.5), 0.0]),
            1: np.array([-s * (BASELINE_X_M + 0.5), 0.0])}
    targets = {0: np.tile(home[0], (n_frames, 1)), 1: np.tile(home[1], (n_frames, 1))}
    all_times = list(times) + [t]
    all_contacts = list(contacts) + [contact]
    for k in range(1, n_shots + 1):  # shot k (k = n_shots: never made) is the server's if even
        who = k % 2
        sel = (t_s > all_times[k - 1]) & (t_s <= all_times[k])
        targets[who][sel] = all_contacts[k][:2]
    targets[0][toss] = server0  # both stand still during the toss
    targets[1][toss] = receiver0
    server = _walk(server0, targets[0], dt)
    receiver = _walk(receiver0, targets[1], dt)
    return {"t_s": t_s, "ball": ball, "server": server, "receiver": receiver,
            "contact_times": times, "contacts": contacts, "bounces": bounces,
            "ending": ending, "n_shots": n_shots}


def make_toy_rallies(n_rallies: int, seed: int, fps: float = FPS_DEFAULT) -> RallyData:
    """`n_rallies` schema-valid toy rallies (one rally a point), deterministic for `seed`."""
    if n_rallies <= 0:
        raise ValueError(f"n_rallies must be positive, got {n_rallies}")
    if not np.isfinite(fps) or fps <= 0:
        raise ValueError(f"fps must be positive, got {fps}")
    rng = np.random.default_rng(seed)
    frame_parts, rally_rows, shot_rows = [], [], []
    for rid in range(n_rallies):
        a, b = rng.choice(len(TOY_PLAYERS), size=2, replace=False)
        server, receiver = TOY_PLAYERS[a], TOY_PLAYERS[b]
        server_end = int(rng.choice([-1, 1]))
        side = str(rng.choice(["deuce", "ad"]))
        serve_number = int(rng.integers(1, 3))
        r = _one_rally(rng, fps, server_end, side, serve_number)
        n = len(r["t_s"])
        contact_frames = [min(int(round(tc * fps)), n - 1) for tc in r["contact_times"]]
        # Per-frame labels of the shot in progress.
        shot_of_frame = np.searchsorted(np.array(contact_frames), np.arange(n), side="right") - 1
        strokes, directions, outcomes, kinds = [], [], [], []
        for k in range(r["n_shots"]):
            hitter_sign = server_end if k % 2 == 0 else -server_end
            y_hit = r["contacts"][k][1]
            if k == 0:
                stroke, direction = "serve", str(rng.choice(["wide", "body", "T"]))
            else:
                stroke = "forehand" if y_hit * hitter_sign < 0 else "backhand"
                direction = str(rng.choice(["cross_court", "down_the_line", "middle"]))
            last = k == r["n_shots"] - 1
            if not last:
                outcome, kind = "in_play", "none"
            elif r["ending"] == "error":
                outcome, kind = "error", str(rng.choice(["forced", "unforced"]))
            else:
                outcome, kind = "winner", "none"
            strokes.append(stroke)
            directions.append(direction)
            outcomes.append(outcome)
            kinds.append(kind)
            bounce, _ = r["bounces"][k]
            c = r["contacts"][k]
            shot_rows.append({
                "rally_id": rid, "shot_index": k, "frame": contact_frames[k],
                "hitter": server if k % 2 == 0 else receiver, "stroke": stroke,
                "spin": "flat", "direction": direction, "outcome": outcome, "error_kind": kind,
                "contact_x": c[0], "contact_y": c[1], "contact_z": c[2],
                "speed_mps": 30.0 if k else 50.0, "bounce_x": bounce[0], "bounce_y": bounce[1]})
        in_shot = shot_of_frame >= 0
        which = np.maximum(shot_of_frame, 0)
        labels = {col: np.where(in_shot, np.array(vals, dtype=object)[which], "none")
                  for col, vals in (("stroke", strokes), ("direction", directions),
                                    ("outcome", outcomes), ("error_kind", kinds))}
        for obj, track in ((server, r["server"]), (receiver, r["receiver"]), ("ball", r["ball"])):
            xyz = track if track.shape[1] == 3 else np.c_[track, np.zeros(n)]
            frame_parts.append(pd.DataFrame({
                "rally_id": rid, "frame": np.arange(n), "t": r["t_s"], "object": obj,
                "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], **labels}))
        last_hitter_server = (r["n_shots"] - 1) % 2 == 0
        if r["ending"] == "error":
            winner = receiver if last_hitter_server else server
            end_reason = "forced_error" if kinds[-1] == "forced" else "unforced_error"
            end_detail = "out"
        else:
            winner = server if last_hitter_server else receiver
            end_reason, end_detail = ("ace", "unreached") if r["ending"] == "ace" else \
                ("winner", "unreached")
        sp, rp = (int(v) for v in rng.integers(0, 4, size=2))
        rally_rows.append({
            "rally_id": rid, "match_id": f"toy-{rid // 40}", "point": rid % 40 + 1,
            "server": server, "receiver": receiver, "serve_number": serve_number,
            "side": side, "server_end": server_end,
            "surface": TOY_SURFACES[rid % len(TOY_SURFACES)],
            "tournament": TOY_TOURNAMENTS[rid % len(TOY_TOURNAMENTS)],
            "set_no": 1, "server_sets": 0, "receiver_sets": 0,
            "server_games": int(rng.integers(0, 6)), "receiver_games": int(rng.integers(0, 6)),
            "server_points": sp, "receiver_points": rp, "in_tiebreak": False,
            "score": f"{sp}-{rp}", "winner": winner, "end_reason": end_reason,
            "end_detail": end_detail, "serve_kmh": 180.0 if serve_number == 1 else 150.0,
            "rally_length": r["n_shots"] - (1 if r["ending"] == "error" else 0)})
    frames = pd.concat(frame_parts, ignore_index=True)
    return RallyData.from_tables(frames, pd.DataFrame(rally_rows), pd.DataFrame(shot_rows),
                                 fps=fps, meta={"source": "toy", "seed": seed})
