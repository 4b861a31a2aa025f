"""Why serves go unreturned: the receiver's movement and reach on first serves, simulated
against the ground truth.

    .venv/bin/python scripts/diagnose_returns.py [--model PATH] [--points 150] [--seed 2]
        [--top-p-player P] [--top-p-ball P]

Roger Federer serving to Rafael Nadal on hard: `--points` simulated first serves and the
generator's first serves of the same matchup. For every serve that lands in the box: how far
the receiver has moved from his start when the serve bounces, his closest horizontal distance
to the ball in the 30 frames after the bounce, and whether he returned it (a second racket
contact, from the rally-end rules). A model whose receivers stand still or are near the ball
but do not strike it shows here.
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from sportsngen.eval.rules import analyse_rally_data
from sportsngen.sim import Simulator
from sportsngen.synth.generate import generate_matches
from sportsngen.tennis.court import SERVICE_LINE_X_M

SERVER, RECEIVER = "Roger Federer", "Rafael Nadal"
AFTER_BOUNCE_FRAMES = 30


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


def describe(name: str, t: np.ndarray) -> None:
    near = t[:, 1] < 1.0
    print(f"{name:<6} serves in the box {len(t):>4}; receiver moved by the bounce: median "
          f"{np.median(t[:, 0]):.2f} m; closest gap: median {np.median(t[:, 1]):.2f} m "
          f"(IQR {np.percentile(t[:, 1], 25):.2f}-{np.percentile(t[:, 1], 75):.2f}); returned "
          f"{100 * t[:, 2].mean():.0f} %; returned when the ball came within 1 m "
          f"{100 * t[near, 2].mean():.0f} % (of {int(near.sum())})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--points", type=int, default=150)
    ap.add_argument("--seed", type=int, default=2)
    ap.add_argument("--top-p-player", type=float, default=None)
    ap.add_argument("--top-p-ball", type=float, default=None)
    ap.add_argument("--threads", type=int, default=None)
    args = ap.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    kw = {k: v for k, v in (("top_p_player", args.top_p_player),
                            ("top_p_ball", args.top_p_ball)) if v is not None}
    sim = Simulator.from_pretrained(args.model, **kw)
    print(f"top-p player {sim.top_p_player}, ball {sim.top_p_ball}")
    simd = sim.simulate_points(SERVER, RECEIVER, "hard", args.points, seed=args.seed,
                               serve_number=1)
    truth = generate_matches([(SERVER, RECEIVER)], "hard", 2 * args.points, seed=args.seed,
                             workers=1)
    r = truth.rallies
    truth = truth.subset(r.loc[(r["serve_number"] == 1) & (r["server"] == SERVER), "rally_id"])
    describe("sim", receiver_table(simd))
    describe("truth", receiver_table(truth))


if __name__ == "__main__":
    main()
