"""Where the rally balls are met: the ball's height at the strike, the hitter's depth behind his
baseline, how deep the ball he answers landed; the share of each band and its error share.

`shot_profile.strike_endings` says which strikes end points; this says from which states. A
model's head can strike right from the record's states and still err more in its rollouts when
its own players arrive where the record's never are. The generator's players meet a rally ball
at their comfortable height (a median 0.79-0.95 m, 1.3-4.5 % of strikes above 1.05 m), while the
bundled file's rollouts met 16-41 % above it (docs/evaluation.md, forty-ninth and fiftieth
parts): states its strike head saw a few dozen times in training. Heights are read from the
frames table for both sides, so a truth's exact contact and a rollout's frame carry the same
discretisation, at the last frame before the contact (a recorded shot's frame may follow it).
The hitter's depth is `shot_profile`'s `hitter_behind_m`, read for every strike at once by
name.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.tennis.court import BASELINE_X_M

HIGH_CONTACT_Z_M = 1.05      # a rally ball met above this: above the generator's players' range
# Band edges of each state (m); the last band is open.
BANDS_M = {
    "contact_z_m": (0.8, 0.95, HIGH_CONTACT_Z_M, 1.2, 1.4),
    "hitter_behind_m": (0.5, 1.5, 2.3),
    "incoming_depth_m": (2.5, 4.5),
}
MIN_Z_STRIKES = 20           # a band's gap gets a z where both sides have this many strikes


def strike_states(data, realistic_only: bool = True, first_shot: int = 2) -> pd.DataFrame:
    """Rally strikes (`shot_index` >= `first_shot`; 2: the server's first rally ball) of
    `data` (a `RallyData` or anything with its `rallies`, `shots` and `frames` tables) ->
    one row each: rally_id, shot_index, hitter, contact_z_m (the ball's height at the shot's
    frame, or at the frame before where the ball is already going away from him in it),
    hitter_behind_m (his |x| at that frame less the baseline's; negative inside the
    court), incoming_depth_m (the baseline's |x| less that of the bounce of the ball he
    answers; NaN where it has none) and error (the strike ended the point as its hitter's
    error). Non-realistic rallies are left out unless `realistic_only` is False."""
    shots = data.shots.sort_values(["rally_id", "shot_index"])
    if realistic_only and "realistic" in data.rallies:
        keep = data.rallies.loc[data.rallies["realistic"].astype(bool), "rally_id"]
        shots = shots[shots["rally_id"].isin(keep)]
    incoming = BASELINE_X_M - shots.groupby("rally_id")["bounce_x"].shift(1).abs()
    shots = shots.assign(incoming_depth_m=incoming)
    shots = shots[shots["shot_index"] >= first_shot]
    frames = data.frames[["rally_id", "frame", "object", "x", "z"]]
    ball = frames[frames["object"] == "ball"][["rally_id", "frame", "x", "z"]]
    before = ball.assign(frame=ball["frame"] + 1).rename(columns={"x": "x_before",
                                                                  "z": "z_before"})
    players = frames[frames["object"] != "ball"].rename(columns={"object": "hitter",
                                                                 "x": "hitter_x"})
    out = shots[["rally_id", "shot_index", "hitter", "frame", "outcome",
                 "incoming_depth_m"]].merge(ball, on=["rally_id", "frame"], how="left")
    out = out.merge(before, on=["rally_id", "frame"], how="left")
    out = out.merge(players[["rally_id", "frame", "hitter", "hitter_x"]],
                    on=["rally_id", "frame", "hitter"], how="left")
    # A recorded shot's frame is the one nearest its contact and may come after it, the ball
    # already on its way back (14 % of the generator's rally strikes, and 68 % of those it
    # reads above 1.05 m); a rollout's is the frame before its contact. Read where the step
    # into the shot's frame goes away from the hitter, the frame before it is the ball he met.
    away = (out["x"] - out["x_before"]) * np.sign(out["hitter_x"]) < 0
    z = np.where(away.to_numpy() & out["z_before"].notna().to_numpy(), out["z_before"], out["z"])
    return pd.DataFrame({
        "rally_id": out["rally_id"].to_numpy(), "shot_index": out["shot_index"].to_numpy(),
        "hitter": out["hitter"].astype(str).to_numpy(),
        "contact_z_m": z.astype(float),
        "hitter_behind_m": out["hitter_x"].abs().to_numpy(float) - BASELINE_X_M,
        "incoming_depth_m": out["incoming_depth_m"].to_numpy(float),
        "error": (out["outcome"].astype(str) == "error").to_numpy()})


def state_bands(states: pd.DataFrame) -> pd.DataFrame:
    """`strike_states` rows -> per state and band (`BANDS_M`): n, share (of the rows with
    that state known), error share and its binomial standard error."""
    rows = []
    for col, edges in BANDS_M.items():
        known = states[states[col].notna()]
        cut = np.digitize(known[col].to_numpy(), edges)
        labels = [f"< {edges[0]:g}"] + [f"{a:g}-{b:g}" for a, b in zip(edges[:-1], edges[1:])] + \
            [f">= {edges[-1]:g}"]
        for k, label in enumerate(labels):
            e = known["error"].to_numpy()[cut == k]
            n = len(e)
            err = float(e.mean()) if n else np.nan
            rows.append({"state": col, "band": label, "n": n,
                         "share": n / len(known) if len(known) else np.nan, "error": err,
                         "error_se": float(np.sqrt(err * (1 - err) / n)) if n else np.nan})
    return pd.DataFrame(rows).set_index(["state", "band"])


def high_contact_share(states: pd.DataFrame) -> float:
    """The share of strikes met above `HIGH_CONTACT_Z_M` (of those with a height)."""
    z = states["contact_z_m"].dropna().to_numpy()
    return float((z > HIGH_CONTACT_Z_M).mean()) if len(z) else float("nan")


def format_state_bands(sim: pd.DataFrame, truth: pd.DataFrame) -> str:
    """Two `state_bands` tables side by side ("sim / truth"), with the error shares' gap in
    standard errors of both sides (z) where both have at least `MIN_Z_STRIKES` strikes."""
    lines = [f"{'state':<17} {'band':<9} {'share':>13} {'error':>13} {'z':>5}"]
    for key in sim.index:
        a, b = sim.loc[key], truth.loc[key]
        se = np.hypot(a["error_se"], b["error_se"])
        enough = min(a["n"], b["n"]) >= MIN_Z_STRIKES and np.isfinite(se) and se > 0
        z = (a["error"] - b["error"]) / se if enough else np.nan
        lines.append(f"{key[0]:<17} {key[1]:<9} {a['share']:.3f} / {b['share']:.3f} "
                     f"{a['error']:.3f} / {b['error']:.3f} {z:+5.1f}")
    return "\n".join(lines)
