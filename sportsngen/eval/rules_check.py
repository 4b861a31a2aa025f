"""How well the rally-end rules (`sportsngen.tennis.rally`) recover the generator's own labels;
`scripts/check_rally_rules.py` is the command line.

Generates rallies (named players round robin, hard/clay/grass), judges them from the tracks
alone and compares with the rallies and shots tables: winner, end class (fault / ace /
double_fault / winner / error), end detail, number of shots, contact frames, bounce positions,
and the share flagged unrealistic (with each check's share). `add_noise` is a crude stand-in
for the model's binned tracks (the paper's augmentation is 0.025 m).
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from sportsngen.eval.rules import analyse_rally_data
from sportsngen.synth import generate_matches
from sportsngen.tennis.court import FENCE_X_M, FENCE_Y_M
from sportsngen.tennis.rally import CHECKS, CONTACT_REACH_M, MAX_RALLY_S, end_class

PLAYERS = ["Roger Federer", "Rafael Nadal", "Novak Djokovic", "Andy Murray", "John Isner"]


def add_noise(data, amp_m: float, seed: int) -> None:
    """Uniform noise on every coordinate (in place): ball x +-amp, y/z +-amp/2; players x/y
    +-amp. The ball stays above the ground."""
    rng = np.random.default_rng(seed)
    f = data.frames
    ball = (f["object"] == "ball").to_numpy()
    for col, a_ball in (("x", amp_m), ("y", amp_m / 2), ("z", amp_m / 2)):
        amp = np.where(ball, a_ball, 0.0 if col == "z" else amp_m)
        f[col] = f[col].to_numpy() + rng.uniform(-1.0, 1.0, len(f)) * amp
    f.loc[ball, "z"] = f.loc[ball, "z"].clip(lower=0.0)


def bounce_errors(res: pd.DataFrame, shots: pd.DataFrame) -> np.ndarray:
    """(n, 2) rule bounce minus generator bounce, metres, for each shot whose ball bounced inside
    the fences, in rallies where the rules found the generator's number of shots."""
    out = []
    by_rally = dict(tuple(shots.groupby("rally_id")))
    for rid, row in res.iterrows():
        s = by_rally.get(rid)
        if s is None or row["n_shots"] != len(s):
            continue
        frames = list(row["contact_frames"]) + [np.inf]
        for k, (bx, by) in enumerate(s[["bounce_x", "bounce_y"]].to_numpy()):
            after = [b for f, b in zip(row["bounce_frames"], row["bounces_m"])
                     if frames[k] < f < frames[k + 1]]
            inside = abs(bx) < FENCE_X_M and abs(by) < FENCE_Y_M  # else it hit the fence first
            if np.isfinite(bx) and inside and after:
                out.append((after[0][0] - bx, after[0][1] - by))
    return np.asarray(out).reshape(-1, 2)

def check_rally_rules(n_points: int = 1500, seed: int = 11, noise_m: float = 0.0) -> None:
    """Print how the rules read `n_points` generated points (seed `seed`), with `add_noise` of
    `noise_m` first where it is positive, against the generator's labels (module doc)."""

    t0 = time.perf_counter()
    data = generate_matches(PLAYERS, ["hard", "clay", "grass"], n_points, seed=seed,
                            workers=1)
    t1 = time.perf_counter()
    if noise_m > 0:
        add_noise(data, noise_m, seed)
    res = analyse_rally_data(data)
    t2 = time.perf_counter()
    r = data.rallies.set_index("rally_id").loc[res.index]
    print(f"{len(res)} rallies ({n_points} points, seed {seed}, noise "
          f"{noise_m} m): generated in {t1 - t0:.1f} s, judged in {t2 - t1:.1f} s")

    winner = np.where(r["winner"] == "", -1, np.where(r["winner"] == r["server"], 0, 1))
    gen_class = pd.Series(end_class(r["end_reason"].to_numpy(str)), index=res.index)
    n_gen = data.shots.groupby("rally_id").size().reindex(res.index, fill_value=0)
    gen_frames = data.shots.groupby("rally_id")["frame"].apply(list).reindex(res.index)
    same_n = res["n_shots"] == n_gen
    diffs = np.concatenate([np.abs(np.subtract(a, b)) for a, b in
                            zip(res.loc[same_n, "contact_frames"], gen_frames[same_n])])
    rows = [("winner (0 server / 1 receiver / -1 none)", res["winner"] == winner),
            ("end class", res["end_reason"] == gen_class),
            ("end detail", res["end_detail"] == r["end_detail"]),
            ("number of shots", same_n),
            ("all of winner, class, detail, shots",
             (res["winner"] == winner) & (res["end_reason"] == gen_class)
             & (res["end_detail"] == r["end_detail"]) & same_n)]
    print("\nagreement with the generator's labels")
    for name, ok in rows:
        print(f"  {name:<40} {ok.mean():7.2%}  ({int((~ok).sum())} differ)")
    print(f"  {'contact frame exact / within 1 frame':<40} {np.mean(diffs == 0):7.2%} / "
          f"{np.mean(diffs <= 1):.2%}  ({len(diffs)} contacts of rallies with equal shots)")
    err = bounce_errors(res, data.shots)
    print(f"  bounce position error (rules - generator, {len(err)} bounces): x mean "
          f"{err[:, 0].mean() * 100:+.2f} cm, sd {err[:, 0].std() * 100:.2f} cm, max |x| "
          f"{np.abs(err[:, 0]).max() * 100:.1f} cm; y sd {err[:, 1].std() * 100:.2f} cm")
    print(f"  rallies not ended by the end of the track: {int((~res['ended']).sum())}")

    print("\nend class: generator (rows) x rules (columns)")
    print(pd.crosstab(gen_class.rename("generator"), res["end_reason"].rename("rules")))
    print("\nend detail: generator (rows) x rules (columns)")
    print(pd.crosstab(r["end_detail"].rename("generator"), res["end_detail"].rename("rules")))

    print(f"\nflagged unrealistic: {(~res['realistic']).mean():.2%} of rallies; by check:")
    for check in CHECKS:
        share = res["failed_checks"].apply(lambda c, k=check: k in c).mean()
        print(f"  {check:<22} {share:7.2%}")
    gaps = res["contact_gaps_m"]
    serve_far = gaps.apply(lambda g: len(g) > 0 and g[0] > CONTACT_REACH_M)
    rally_far = gaps.apply(lambda g: any(x > CONTACT_REACH_M for x in g[1:]))
    print(f"  contact out of reach, serve only: {serve_far.mean():.2%} of rallies; any later "
          f"shot: {rally_far.mean():.2%}")
    frames = data.frames[data.frames["object"] == "ball"].groupby("rally_id").size()
    print(f"  tracks longer than the {MAX_RALLY_S:g} s cap: "
          f"{(frames > MAX_RALLY_S * data.fps).mean():.2%} of rallies; longer than 30 s: "
          f"{(frames > 30 * data.fps).mean():.2%}")
