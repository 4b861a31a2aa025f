"""The simulation issue's acceptance figures: simulated service points against the generator.

For two players on a surface: `n_points` simulated service points for each server
(`Simulator.simulate_both_serving`, first serves then second serves after faults) against the
synthetic ground truth of the same matchup (`generate_matches`). Prints the share of
non-realistic rallies (and which checks failed), then per server first serve in %, aces %,
double faults %, serve points won % (over the realistic points), median first-serve speed and
mean rally length, simulated beside ground truth (serve speeds from the ball tracks for both:
all first serves, faults included, `eval.check_noise.first_serve_speeds`), and which of them
miss the acceptance tolerances (5 points, 8 km/h, 0.5 shot; earlier parts of
docs/evaluation.md counted the rally at 1 shot, and the count at 1 shot is printed beside),
each gap with its standard error from resampling both sides' points and how many of the twelve
a right simulator would bring within tolerance (`eval.check_noise`: both sides are samples, and
the generator itself, run as a simulator, scores about 11.8 of 12; `scripts/pool_checks.py`
pools the gaps of several seeds' json files); non-realistic rallies against the issue's 5 %
(15 % without physical limits); the shape of the rallies shot by shot; and how often the event
classifier's point winner agrees with the rules' winner on simulated rallies and on
ground-truth rallies. `scripts/check_simulation.py` is its command line.
"""

from __future__ import annotations

import collections
import json
import time
from pathlib import Path

import numpy as np

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.eval.bounce_fall import format_bounce_fall, post_bounce_fall
from sportsngen.eval.check_noise import (
    CHECK_COLUMNS,
    CHECK_SCALE,
    CHECK_TOLERANCE,
    expected_within,
    first_serve_speeds,
    gap_noise,
)
from sportsngen.eval.long_rallies import points_after_window
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.eval.shot_profile import (
    SLOW_FLIGHT_S,
    format_profiles,
    format_strike_endings,
    format_unanswered,
    shot_profile,
    strike_endings,
    unanswered_by_flight,
)
from sportsngen.eval.stats import rally_hazards, serve_stats
from sportsngen.eval.strike_states import (
    HIGH_CONTACT_Z_M,
    format_state_bands,
    high_contact_share,
    state_bands,
    strike_states,
)
from sportsngen.sim import Simulator
from sportsngen.sim.assemble import realistic_points
from sportsngen.sim.events import classifier_winner, frame_labels, shot_labels
from sportsngen.synth.generate import generate_matches

PLAYERS = ("Roger Federer", "Rafael Nadal")
SURFACES = ("hard", "clay", "grass")
# Up to the thirty-first part of docs/evaluation.md the check counted the rally at 1 shot.
RALLY_TOLERANCE_BEFORE = 1.0
# Non-realistic rallies: the limit with the physical limits on, and without them.
NON_REALISTIC_MAX = {True: 0.05, False: 0.15}


def classifier_agreement_on_truth(sim: Simulator, data) -> float:
    """Share of decided ground-truth rallies where g's reading of the last shot names the
    recorded winner (contacts from the rally-end rules, as for simulated rallies)."""
    arr = rally_arrays(data, Vocab.from_data(data), unknown="generic")
    n, t_max = len(arr), int(arr.length.max())
    pos = np.zeros((n, t_max, 3, 3), dtype=np.float32)
    for i, (s, k) in enumerate(zip(arr.start, arr.length)):
        pos[i, :k] = arr.pos_m[s:s + k]
    labels = frame_labels(sim.event_model, pos, arr.length, data.fps,
                          sim.model.cfg.window_frames)
    rules = analyse_rally_data(data).loc[arr.rally_id]
    r = data.rallies.set_index("rally_id").loc[arr.rally_id]
    role = np.where(r["winner"] == r["server"], 0, np.where(r["winner"] == r["receiver"], 1, -1))
    agree = []
    for i in range(n):
        if role[i] < 0:
            continue
        frames, hitters = rules["contact_frames"].iat[i], rules["hitters"].iat[i]
        lab = shot_labels(labels[i], frames, int(arr.length[i]))
        out = ("none", "in_play", "winner", "error")[lab[-1, 2]] if len(lab) else "none"
        agree.append(classifier_winner(out, hitters[-1] if hitters else -1) == role[i])
    return float(np.mean(agree))


def settings_line(sim: Simulator) -> str:
    """The simulator's sampling settings and the physical rules it plays under, one line."""
    return (f"top-p player {sim.top_p_player}, ball {sim.top_p_ball}, "
          f"contact odds {sim.contact_odds}, contact {sim.top_p_contact}, "
          f"serve {sim.top_p_serve}, "
          f"cache refresh {sim.refresh_frames}, strike in reach {sim.strike_in_reach}"
          + (f" from shot {sim.strike_in_reach_from}" if sim.strike_in_reach else "")
          + (", forced where it gives up" if sim.strike_in_reach_force else "")
          + (f", reach {sim.strike_in_reach_m} m" if sim.strike_in_reach else "")
          + (f" (the return's {sim.strike_in_reach_return_m} m)"
             if sim.strike_in_reach and sim.strike_in_reach_return_m is not None else "")
          + (", keep chasing" if sim.keep_chasing else "")
          + (" (high balls to a comfortable height)"
             if sim.keep_chasing and sim.chase_high_balls else "")
          + (f", contact reach {sim.contact_reach_m} m" if sim.physical_limits else "")
          + (f", the return's {sim.return_reach_m} m"
             if sim.physical_limits and sim.return_reach_m is not None else "")
          + (", the return's reach drawn per receiver"
             if sim.return_reach_draw and sim.return_reach is not None else "")
          + (", each rally ball's reach drawn per player"
             if sim.rally_reach_draw and sim.rally_reach is not None else "")
          + (", each player within his top speed"
             if sim.player_top_speed and sim.top_speeds is not None else "")
          + (", players' draws placed in their bins as the record's"
             if sim.player_quantiles_used() is not None else "")
          + (", the net in the ball's step" if sim.model.cfg.ball_net else "")
          + (", the surface's bounce" if sim.physical_bounce else "")
          + (f", players within {sim.player_accel_mps2:g} m/s²" if sim.player_accel_mps2
             else "")
          + (f", flat out from {sim.player_accel_full_frac:g} of it"
             if sim.player_accel_mps2 and sim.player_accel_full_frac else "")
          + (f", running along his heading within {sim.player_keep_heading_deg:g}°"
             if sim.player_accel_mps2 and sim.player_keep_heading_deg else ""))


def _serve_checks(players: tuple[str, str], simd, truth, points: dict, unreal: float,
                  physical_limits: bool, seed: int) -> dict:
    """Print the serve statistics simulated beside the truth, the tolerances they miss and the
    gaps' noise; -> the figures for the json."""
    s_sim = serve_stats(points["sim"]).reindex(list(players))
    s_true = serve_stats(points["truth"]).reindex(list(players))
    # Serve speeds measured the same way on both (the ball track's first frame after contact:
    # the generator's table holds launch speeds, the simulator's track speeds).
    speeds = {}
    for source, st, d in (("sim", s_sim, simd), ("truth", s_true, truth)):
        got = first_serve_speeds(d, source, list(players))
        st["first_serve_kmh_median"] = [
            float(np.median(v)) if len(v) else np.nan
            for v in (got[(source, p, "first_serve_kmh_median")] for p in st.index)]
        speeds.update(got)
    rows = []
    print(f"\n{'server':<15} {'':>6} " + " ".join(f"{h:>10}" for _, h, _ in CHECK_COLUMNS))
    for p in players:
        for name, st in (("sim", s_sim), ("truth", s_true)):
            vals = [st.loc[p, c] * f for c, _, f in CHECK_COLUMNS]
            print(f"{p:<15} {name:>6} " + " ".join(f"{v:>10.1f}" for v in vals))
            n_pts = int(np.nan_to_num(st.loc[p, "n_points"]))
            rows.append({"server": p, "source": name, "n_points": n_pts,
                         **{c: float(st.loc[p, c]) for c, _, _ in CHECK_COLUMNS}})
    misses, rally_gaps = [], []
    for p in players:
        for c, h, f in CHECK_COLUMNS:
            gap = abs(s_sim.loc[p, c] - s_true.loc[p, c]) * f
            if c == "rally_mean":
                rally_gaps.append(gap)
            if not gap <= CHECK_TOLERANCE[c]:
                misses.append(f"{p} {h} off by {gap:.2f} (tolerance {CHECK_TOLERANCE[c]:g})")
    within = int(2 * len(CHECK_COLUMNS) - len(misses))
    # The rallies that miss 0.5 but not 1 shot, to compare with the earlier parts' counts.
    lenient = int(sum(CHECK_TOLERANCE["rally_mean"] < g <= RALLY_TOLERANCE_BEFORE
                      for g in rally_gaps))
    limit = NON_REALISTIC_MAX[physical_limits]
    print(f"\nwithin tolerance: {within} of {2 * len(CHECK_COLUMNS)} (rally 0.5 shot; "
          f"{within + lenient} with the rally at 1 shot); non-realistic "
          f"{'under' if unreal < limit else 'NOT under'} {100 * limit:.0f} %")
    for m in misses:
        print(f"  outside: {m}")
    # Both sides are samples: a right simulator misses some tolerances too (eval.check_noise).
    noise = gap_noise(points["sim"], points["truth"], list(players),
                      [c for c, _, _ in CHECK_COLUMNS], values=speeds, seed=seed)
    expected = expected_within(noise, CHECK_TOLERANCE, CHECK_SCALE)
    print(f"\nthe gaps' noise (both sides resampled): a right simulator brings {expected:.1f} "
          f"of {2 * len(CHECK_COLUMNS)} within tolerance on average; |z| over 3 is a bias")
    print(f"{'server':<15} " + " ".join(f"{h:>16}" for _, h, _ in CHECK_COLUMNS))
    for p in players:
        cells = noise[noise["server"] == p].set_index("statistic")
        print(f"{p:<15} " + " ".join(
            f"{cells.at[c, 'gap'] * f:>+7.2f}±{cells.at[c, 'se'] * f:<4.2f} "
            f"z{cells.at[c, 'z']:>+4.1f}" for c, _, f in CHECK_COLUMNS))
    return {"stats": rows, "outside_tolerance": misses, "within_tolerance": within,
            "noise": noise, "expected_within_right_simulator": expected,
            "within_rally_1_shot": within + lenient}


def _rally_shape(sim: Simulator, simd, truth, real, points: dict) -> dict:
    """Print how the points end and how each shot is struck, sim beside truth; -> the
    figures for the json."""
    # Shot by shot, where the points end: odd lengths are the server's wins, even ones the
    # receiver's (docs/evaluation.md, tenth part: where serve points are lost).
    hz = {name: rally_hazards(pts["rally"], 6)["hazard"] for name, pts in points.items()}
    print("\npoints ending at rally length L of those reaching it (L = 1 .. 6), sim / truth: " +
          "  ".join(f"{L}: {hz['sim'][L]:.2f} / {hz['truth'][L]:.2f}" for L in range(1, 7)))
    # Points decided after the serve left the model's window, where the rollout's own view
    # past the window cost the servers (docs/evaluation.md, twenty-ninth part).
    w = sim.model.cfg.window_frames
    late = {"sim": points_after_window(real, w), "truth": points_after_window(truth, w)}
    print(f"\npoints decided {w} frames or more after the serve (out of the model's window), "
          f"sim / truth: {100 * late['sim'].at['after', 'share']:.1f} / "
          f"{100 * late['truth'].at['after', 'share']:.1f} % of points, the server won "
          f"{100 * late['sim'].at['after', 'server_won']:.1f} / "
          f"{100 * late['truth'].at['after', 'server_won']:.1f} % of them "
          f"(of the others {100 * late['sim'].at['before', 'server_won']:.1f} / "
          f"{100 * late['truth'].at['before', 'server_won']:.1f} %)")
    # How each shot is struck and ends over whole points (the strikes table reads one strike
    # at a time from the record; here the rally's drift counts too).
    profiles = {"sim": shot_profile(simd), "truth": shot_profile(truth)}
    print("\nshot by shot after the serve (1 = the return), sim / truth:\n"
          + format_profiles(profiles["sim"], profiles["truth"]))
    # Balls in play left unanswered, slow flights apart (docs/evaluation.md, thirty-ninth part).
    unanswered = {"sim": unanswered_by_flight(simd), "truth": unanswered_by_flight(truth)}
    print("\nballs in play after the serve left unanswered, by flight (slow: first bounce "
          f"{SLOW_FLIGHT_S} s or more after the contact), sim / truth:\n"
          + format_unanswered(unanswered["sim"], unanswered["truth"]))
    # Whose strikes end the points, by role and stage (docs/evaluation.md, forty-seventh part).
    print("\nstrikes that ended the point as the hitter's error or winner, by hitter, role and "
          "stage, sim / truth (z: the gap in standard errors of both):\n"
          + format_strike_endings(strike_endings(simd), strike_endings(truth)))
    # The same by the point's serve (docs/evaluation.md, seventy-fourth part).
    print("\nthe same by the point's serve (1 first, 2 second), sim / truth:\n"
          + format_strike_endings(strike_endings(simd, by_serve=True),
                                  strike_endings(truth, by_serve=True)))
    # From which states: where the rally balls are met (docs/evaluation.md, forty-ninth part).
    states = {"sim": strike_states(simd), "truth": strike_states(truth)}
    print(f"\nrally strikes from the server's first rally ball by where they are met, sim / "
          f"truth (met above {HIGH_CONTACT_Z_M} m: {high_contact_share(states['sim']):.3f} / "
          f"{high_contact_share(states['truth']):.3f}); share of strikes, error share, z:\n"
          + format_state_bands(state_bands(states["sim"]), state_bands(states["truth"])))
    # The spin a bounce gives, which the free-flight residual cannot see (fiftieth part).
    print("\nthe ball's fall after its bounces (median vertical acceleration; gravity and drag "
          "alone about -10.3 m/s²), sim / truth:\n"
          + format_bounce_fall(post_bounce_fall(simd), post_bounce_fall(truth)))
    return {"rally_hazards": {k: [float(v) for v in h] for k, h in hz.items()},
            "points_after_window": {k: v.to_dict(orient="index") for k, v in late.items()},
            "shot_profile": {k: p.reset_index().to_dict(orient="records")
                             for k, p in profiles.items()},
            "unanswered_by_flight": {k: u.to_dict(orient="index")
                                     for k, u in unanswered.items()}}


def check_simulation(sim: Simulator, players: tuple[str, str], surface: str, n_points: int,
                     truth_points: int, seed: int, save_sim: Path | None = None,
                     physical_limits: bool = True, json_path: str | None = None) -> None:
    """Print the check of `sim` (built with `physical_limits`) on `n_points` service points a
    server of `players` on `surface` against `truth_points` generated points (module doc);
    `save_sim` keeps the simulated rallies, `json_path` writes the figures."""
    print(settings_line(sim))
    t0 = time.perf_counter()
    simd = sim.simulate_both_serving(*players, surface, n_points, seed=seed)
    if save_sim is not None:
        simd.save(save_sim)
    sim_s = time.perf_counter() - t0
    r = simd.rallies
    failed = collections.Counter(c for f in r["failed_checks"] for c in f.split(";") if c)
    unreal = float((~r["realistic"]).mean())
    print(f"simulated {len(r)} rallies ({2 * n_points} points) in {sim_s:.0f} s; "
          f"non-realistic {100 * unreal:.1f} %: {dict(failed.most_common())}")
    if "forced_strikes" in r:
        print(f"strikes forced where the rule for balls in reach gave up: "
              f"{int(r['forced_strikes'].sum())}")
    t0 = time.perf_counter()
    truth = generate_matches([players], surface, truth_points, seed=seed,
                             workers=2)
    print(f"ground truth: {len(truth.rallies)} rallies in {time.perf_counter() - t0:.0f} s")
    real = realistic_points(simd)
    points = {"sim": real.points(), "truth": truth.points()}
    checks = _serve_checks(players, simd, truth, points, unreal, physical_limits, seed)
    shape = _rally_shape(sim, simd, truth, real, points)
    decided = r[(r["rules_winner"] >= 0)]
    agree_sim = float((decided["classifier_winner"] == decided["rules_winner"]).mean())
    sub = truth.subset(truth.rallies["rally_id"].iloc[:1000])
    agree_true = classifier_agreement_on_truth(sim, sub)
    print(f"\nevent classifier's point winner = rules' winner: simulated {100 * agree_sim:.1f} % "
          f"of {len(decided)} decided rallies; ground truth {100 * agree_true:.1f} % "
          "(1000 rallies, recorded winner)")
    if json_path:
        with open(json_path, "w") as fh:
            json.dump({"non_realistic": unreal, "failed_checks": dict(failed),
                       **checks, "noise": checks["noise"].to_dict(orient="records"),
                       "agreement_sim": agree_sim, "agreement_truth": agree_true, **shape,
                       "simulate_s": sim_s, "top_p_player": sim.top_p_player,
                       "top_p_ball": sim.top_p_ball, "top_p_contact": sim.top_p_contact,
                       "top_p_serve": sim.top_p_serve,
                       "strike_in_reach": sim.strike_in_reach,
                       "strike_in_reach_from": sim.strike_in_reach_from,
                       "strike_in_reach_force": sim.strike_in_reach_force,
                       "keep_chasing": sim.keep_chasing,
                       "chase_high_balls": sim.chase_high_balls},
                      fh, indent=2)
