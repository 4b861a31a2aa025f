"""Why serves go unreturned, and how returned serves end: simulated first serves against the
generator's (`scripts/diagnose_returns.py` and `scripts/diagnose_rally_ends.py` are the command
lines).

`diagnose_returns`: Roger Federer serving to Rafael Nadal on hard. For every serve that lands in
the box: how far the receiver has moved from his start when the serve bounces, his closest
horizontal distance to the ball in the 30 frames after the bounce, and whether he returned it (a
second racket contact, from the rally-end rules). A model whose receivers stand still or are
near the ball but do not strike it shows here. Then, teacher-forced on the ground-truth rallies:
at the ball tokens around each return's contact, the model's probability of a reversal (an x
offset of more than 0.5 m from the constant-velocity extrapolation) against how often the
recorded next frame has one; and at the receiver's tokens around the frame where he starts to
run after the serve (`sportsngen.train.module.movement_onsets`), the model's probability that
he accelerates (an x offset of at least 1 mm from the constant-velocity extrapolation) against
the recorded share. And for serves that came within 1 m of the receiver, simulated or recorded:
the model's largest probability of a contact on the track itself, returned or not (a near serve
the model would not strike shows a state it never saw a contact from).

`diagnose_rally_ends`: the returned first serves by rally length (shots, the serve included)
and end reason (an error, or a winner nobody reached), from the rally-end rules
(`sportsngen.eval.rules.analyse_rally_data`) for both sides so the two are read alike, and how
often the server wins once the serve is returned. A model whose players react to the ball but
cannot reach the next one shows many short rallies ending in winners.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch
from torch.utils.data import default_collate

from sportsngen.data.tokens import rally_arrays
from sportsngen.eval.contact_odds import REVERSAL_M, far_probability
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.model.inputs import BALL
from sportsngen.sim import Simulator
from sportsngen.sim.assemble import realistic_points
from sportsngen.synth.generate import generate_matches
from sportsngen.tennis.court import SERVICE_LINE_X_M
from sportsngen.train.metrics import window_states
from sportsngen.train.module import movement_onsets
from sportsngen.train.windows import WindowDataset

SERVER, RECEIVER = "Roger Federer", "Rafael Nadal"
AFTER_BOUNCE_FRAMES = 30
N_TOSS_FRAMES = 10       # nobody moves through the toss
STILL_M = 0.05           # a receiver who moved less by the bounce has not started


def receiver_table(data) -> np.ndarray:
    """(n, 3): receiver moved by the bounce (m), closest gap after it (m), returned (0/1)."""
    rules = analyse_rally_data(data)
    rallies = data.rallies.set_index("rally_id")
    frames = data.frames.set_index(["rally_id", "object", "frame"]).sort_index()[["x", "y"]]
    rows = []
    for rid, bounces, n_shots in zip(rules.index, rules["bounce_frames"], rules["n_shots"]):
        if not len(bounces):
            continue
        ball = frames.loc[(rid, "ball")]
        rec = frames.loc[(rid, rallies.at[rid, "receiver"])]
        fb = bounces[0]
        if abs(ball.at[fb, "x"]) > SERVICE_LINE_X_M:      # long: not in the box
            continue
        after = ball.loc[fb:fb + AFTER_BOUNCE_FRAMES]
        gap = np.hypot(after["x"] - rec.loc[after.index, "x"],
                       after["y"] - rec.loc[after.index, "y"])
        moved = np.hypot(rec.at[fb, "x"] - rec["x"].iat[0], rec.at[fb, "y"] - rec["y"].iat[0])
        rows.append((moved, gap.min(), float(n_shots >= 2)))
    return np.asarray(rows)


def first_serves(sim: Simulator, server: str, receiver: str, n_points: int, seed: int):
    """-> (`n_points` simulated first serves of `server` on hard, the generator's first serves
    of `server` in `2 * n_points` points of the same matchup)."""
    simulated = sim.simulate_points(server, receiver, "hard", n_points, seed=seed,
                                    serve_number=1)
    truth = generate_matches([(server, receiver)], "hard", 2 * n_points, seed=seed, workers=1)
    r = truth.rallies
    truth = truth.subset(r.loc[(r["serve_number"] == 1) & (r["server"] == server), "rally_id"])
    return simulated, truth


def describe(name: str, t: np.ndarray) -> None:
    near = t[:, 1] < 1.0
    moving = t[:, 0] >= STILL_M
    print(f"{name:<6} serves in the box {len(t):>4}; receiver moved by the bounce: median "
          f"{np.median(t[:, 0]):.2f} m, still (< {STILL_M} m) {100 * (~moving).mean():.0f} %; "
          f"closest gap: median {np.median(t[:, 1]):.2f} m "
          f"(IQR {np.percentile(t[:, 1], 25):.2f}-{np.percentile(t[:, 1], 75):.2f}); returned "
          f"{100 * t[:, 2].mean():.0f} %, {100 * t[moving, 2].mean():.0f} % of those moving; "
          f"returned when the ball came within 1 m {100 * t[near, 2].mean():.0f} % "
          f"(of {int(near.sum())})")


def first_windows(sim: Simulator, data) -> tuple[object, list[dict]]:
    """-> (the rallies' arrays, each rally's first window, in the arrays' order)."""
    arr = rally_arrays(data, sim.vocab, unknown="generic")
    windows = WindowDataset(arr, sim.model.cfg.window_frames)
    first = {ri: i for i, (ri, s) in enumerate(windows.items) if s == 0}
    return arr, [windows[first[ri]] for ri in range(len(arr))]


@torch.no_grad()
def near_serves(sim: Simulator, data) -> np.ndarray:
    """Serves in the box that came within 1 m of the receiver (first window only) -> (n, 4):
    returned (0/1), closest gap (m), the receiver's speed there (m/s), and the model's
    largest P(reversal) from the bounce to 30 frames after it, teacher-forced on the track
    itself: low on an unreturned near serve means the model judged the state unplayable."""
    model, cfg = sim.model, sim.model.cfg
    rules = analyse_rally_data(data)
    arr, firsts = first_windows(sim, data)
    rows = []
    for ri, (rid, w) in enumerate(zip(arr.rally_id, firsts)):
        bounces = rules.at[rid, "bounce_frames"]
        if not len(bounces):
            continue
        pos = np.asarray(w["pos_m"])
        fb = bounces[0]
        hi = min(fb + AFTER_BOUNCE_FRAMES, cfg.window_frames - 1, int(arr.length[ri]) - 1)
        if hi <= fb or abs(pos[fb, BALL, 0]) > SERVICE_LINE_X_M:
            continue
        gap = np.hypot(*(pos[fb:hi, BALL, :2] - pos[fb:hi, 1, :2]).T)
        if gap.min() > 1.0:
            continue
        k = fb + int(np.argmin(gap))
        p_rev = far_probability(model, window_states(model, default_collate([w]))[0, :, BALL])
        rows.append((float(rules.at[rid, "n_shots"] >= 2), gap.min(),
                     np.hypot(*(pos[k, 1, :2] - pos[k - 1, 1, :2])) * cfg.fps,
                     float(p_rev[fb:hi].max())))
    return np.asarray(rows).reshape(-1, 4)


def describe_near(name: str, t: np.ndarray) -> None:
    for returned, label in ((1, "returned"), (0, "not returned")):
        s = t[t[:, 0] == returned]
        if len(s):
            print(f"  {name:<6} {label:<13} {len(s):>4}: closest gap {np.median(s[:, 1]):.2f} m, "
                  f"receiver speed there {np.median(s[:, 2]):.2f} m/s, largest P(reversal) "
                  f"{np.median(s[:, 3]):.2f} (medians)")


@torch.no_grad()
def contact_mass(sim: Simulator, data, offsets=range(-3, 2)) -> dict[int, tuple[float, float]]:
    """Teacher-forced: {offset: (mean P(reversal), recorded share)} at the ball tokens
    `offset` frames from each return's contact (returns within the first window only)."""
    model, cfg = sim.model, sim.model.cfg
    rules = analyse_rally_data(data).reset_index(drop=True)
    _, firsts = first_windows(sim, data)
    out = {k: [] for k in offsets}
    for ri, w in enumerate(firsts):
        contacts = rules["contact_frames"].iat[ri]
        if len(contacts) < 2 or contacts[1] + max(offsets) >= cfg.window_frames - 1:
            continue
        p_rev = far_probability(model, window_states(model, default_collate([w]))[0, :, BALL])
        off = w["next_pos_m"][:, BALL, 0] - model.centres(
            torch.as_tensor(w["pos_m"]), torch.as_tensor(w["vel_mps"]),
            torch.as_tensor(w["prev_vel_mps"]))[:, BALL, 0].numpy()
        for k in offsets:
            f = contacts[1] + k
            out[k].append((float(p_rev[f]), float(abs(off[f]) > REVERSAL_M)))
    return {k: tuple(np.mean(v, axis=0)) for k, v in out.items() if v}


@torch.no_grad()
def onset_mass(sim: Simulator, data, offsets=range(-2, 2)) -> dict[int, tuple[float, float]]:
    """Teacher-forced: {offset: (mean P(receiver accelerates), recorded share)} at the
    receiver's tokens `offset` frames from his first start after the serve (first window)."""
    model, cfg = sim.model, sim.model.cfg
    edges = model.player_bins.edges[0]
    still = ((edges[:-1] + edges[1:]) / 2).abs() < 1e-3
    out = {k: [] for k in offsets}
    for first in first_windows(sim, data)[1]:
        w = default_collate([first])
        starts = movement_onsets(w["vel_mps"], w["pos_m"], w["next_pos_m"], cfg.fps)[0, :, 1]
        starts &= w["has_next"][0]
        starts[:N_TOSS_FRAMES] = False
        if not starts.any():
            continue
        f0 = int(torch.nonzero(starts)[0])
        h = window_states(model, w)[0, :, 1]
        p = model.player_head.dim_logits(h, torch.zeros(len(h), 2, dtype=torch.long), 0)
        moving = 1.0 - p.softmax(-1)[:, still].sum(-1)
        off = w["next_pos_m"][0, :, 1, 0] - model.centres(w["pos_m"][0],
                                                          w["vel_mps"][0])[:, 1, 0]
        for k in offsets:
            if 0 <= f0 + k < len(h) and bool(w["has_next"][0, f0 + k]):
                out[k].append((float(moving[f0 + k]), float(abs(off[f0 + k]) >= 1e-3)))
    return {k: tuple(np.mean(v, axis=0)) for k, v in out.items() if v}


MAX_SHOTS_ROW = 5   # longer rallies are pooled into this row


def returned_rally_table(data) -> tuple[pd.DataFrame, float, int]:
    """-> (counts by shots x end reason, server's share of the returned rallies, how many)."""
    rules = analyse_rally_data(data)
    rules = rules[rules["n_shots"] >= 2]
    rallies = data.rallies.set_index("rally_id").loc[rules.index]
    won = float((rallies["winner"] == rallies["server"]).mean())
    table = pd.crosstab(rules["n_shots"].clip(upper=MAX_SHOTS_ROW).rename("shots"),
                        rules["end_reason"])
    return table, won, len(rules)


def diagnose_returns(sim: Simulator, n_points: int, seed: int) -> None:
    """Print the receivers' movement and reach on `n_points` simulated first serves of Federer
    to Nadal on hard beside the generator's, and the teacher-forced readings (module doc)."""
    print(f"top-p player {sim.top_p_player}, ball {sim.top_p_ball}")
    simd, truth = first_serves(sim, SERVER, RECEIVER, n_points, seed)
    describe("sim", receiver_table(simd))
    describe("truth", receiver_table(truth))
    print("serves that came within 1 m of the receiver, teacher-forced on their own tracks:")
    describe_near("sim", near_serves(sim, simd))
    describe_near("truth", near_serves(sim, truth))
    print("teacher-forced on the ground truth's returns: P(reversal) / recorded share")
    for k, (p, share) in contact_mass(sim, truth).items():
        print(f"  ball token {k:+d} from the contact: {p:.3f} / {share:.2f}")
    print("teacher-forced at the receiver's start after the serve: P(accelerates) / recorded")
    for k, (p, share) in onset_mass(sim, truth).items():
        print(f"  receiver token {k:+d} from the start: {p:.3f} / {share:.2f}")


def diagnose_rally_ends(sim: Simulator, server: str, receiver: str, n_points: int,
                        seed: int) -> None:
    """Print how `n_points` simulated first serves of `server` end once returned, beside the
    generator's of the same matchup on hard (module doc)."""
    simulated, truth = first_serves(sim, server, receiver, n_points, seed)
    simulated = realistic_points(simulated)
    for name, data in (("simulated", simulated), ("ground truth", truth)):
        table, won, n = returned_rally_table(data)
        print(f"{name}: {n} returned first serves of {server}; the server won "
              f"{100 * won:.1f} %\n{table.to_string()}\n")
