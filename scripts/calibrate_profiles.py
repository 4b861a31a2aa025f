"""Calibrate the named player profiles to their real 2011 Grand Slam serving statistics.

Run: ``/work/main/.venv/bin/python scripts/calibrate_profiles.py [--rounds 6] [--points 1500]``

Targets: ``sportsngen/synth/data/slam2011_targets.csv`` (written by
``scripts/derive_player_stats.py`` from the 2011 US Open and Wimbledon point-by-point data of
Jeff Sackmann / Tennis Abstract, CC BY-NC-SA 4.0). Output: ``sportsngen/synth/data/profiles.json``.

Each round generates `--points` service points per named player against 96 population players
of the same gender (hard and grass alternating, as the two 2011 events), compares with the targets
and moves one parameter per statistic by a damped step, in the direction the physics says:

    first serve in %        <- first_serve_noise_deg   (more noise, more faults)
    double faults %         <- second_serve_noise_deg
    aces %                  <- serve_disguise_s        (the returner starts later)
    unreturned serves       <- serve_heaviness         (returns miss more)
    1st serve points won %  <- serve_initiative        (the serve sets up the next ball)
    2nd serve points won %  <- second_serve_initiative
    mean rally length       <- rally_noise_deg and rally_pressure together (rally tempo: own
                               errors and the pressure that makes the opponent err)
    median serve speeds     <- first/second_serve_kmh

The population is re-sampled every round around the current named profiles. Rounds use fixed
seeds (common random numbers), so the steps see the parameter change, not sampling noise.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pandas as pd

from sportsngen.synth import profiles as prof
from sportsngen.synth.profiles import PlayerProfile, sample_population
from sportsngen.synth.rally import play_rally

ROOT = Path(__file__).resolve().parents[1]
TARGETS_CSV = ROOT / "sportsngen" / "synth" / "data" / "slam2011_targets.csv"
SURFACES = ("hard", "grass")
STAT_KEYS = ("first_serve_in", "ace", "double_fault", "first_serve_won", "second_serve_won",
             "first_serve_kmh_median", "second_serve_kmh_median", "rally_mean")
RALLY_BINS = ("0", "1", "2", "3-4", "5-8", "9+")

# Starting points: handedness, style, contact height and the style's rally character.
INITIAL: dict[str, dict] = {
    "Roger Federer": dict(gender="men", handedness="right", style="all_court",
                          contact_height_m=2.75, aggression=0.55, net_approach=0.12,
                          slice_share=0.3, reaction_s=0.18),
    "Rafael Nadal": dict(gender="men", handedness="left", style="baseliner",
                         contact_height_m=2.65, aggression=0.35, topspin_mps=8.5,
                         recovery_depth_m=2.0, max_speed_mps=7.0, net_approach=0.06),
    "Novak Djokovic": dict(gender="men", handedness="right", style="baseliner",
                           contact_height_m=2.75, aggression=0.35, max_speed_mps=7.0,
                           max_accel_mps2=6.0, recovery_depth_m=1.2, net_approach=0.05),
    "Andy Murray": dict(gender="men", handedness="right", style="counter_puncher",
                        contact_height_m=2.8, aggression=0.3, slice_share=0.3,
                        recovery_depth_m=1.5, net_approach=0.06),
    "John Isner": dict(gender="men", handedness="right", style="big_server",
                       contact_height_m=3.05, aggression=0.65, max_speed_mps=6.0,
                       max_accel_mps2=5.0, reach_m=1.95, net_approach=0.2),
    "Serena Williams": dict(gender="women", handedness="right", style="big_server",
                            contact_height_m=2.6, aggression=0.6, rally_speed_mps=28.0,
                            max_speed_mps=6.3, reach_m=1.7, net_approach=0.05),
    "Maria Sharapova": dict(gender="women", handedness="right", style="baseliner",
                            contact_height_m=2.65, aggression=0.5, rally_speed_mps=27.0,
                            max_speed_mps=6.0, reach_m=1.75, net_approach=0.04),
}


def load_targets(path: Path = TARGETS_CSV) -> pd.DataFrame:
    """Targets, one row per player (index = name), fractions and km/h."""
    if not path.exists():
        sys.exit(f"targets file {path} missing: run scripts/derive_player_stats.py first")
    df = pd.read_csv(path, comment="#")
    key = next(c for c in ("player", "server", "name", "Unnamed: 0") if c in df.columns)
    df = df.rename(columns=dict(zip(("rally_0", "rally_1", "rally_2", "rally_3_4", "rally_5_8",
                                     "rally_9plus"), RALLY_BINS)))
    return df.set_index(key)


def initial_profile(name: str, target: pd.Series) -> PlayerProfile:
    kw = dict(INITIAL[name])
    kw["first_serve_kmh"] = float(target["first_serve_kmh_median"])
    kw["second_serve_kmh"] = float(target["second_serve_kmh_median"])
    # Normal spread with the real interquartile range (IQR = 1.349 sd), within reason.
    for key in ("first", "second"):
        iqr = float(target.get(f"{key}_serve_kmh_iqr", 11.0))
        kw[f"{key}_serve_kmh_sd"] = float(np.clip(iqr / 1.349, 5.0, 16.0))
    return PlayerProfile(name=name, **kw)


def service_outcomes(server: PlayerProfile, opponents: list[PlayerProfile], n_points: int,
                     seed: int) -> pd.DataFrame:
    """`n_points` service points of `server` (outcome only) against `opponents` in turn,
    alternating courts and ends; the serve behaviour does not depend on the score."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n_points):
        opp = opponents[i % len(opponents)]
        end = 1 if (i // 2) % 2 else -1
        side = "deuce" if i % 2 == 0 else "ad"
        surface = SURFACES[(i // 50) % 2]
        first = play_rally(server, opp, end, side, 1, surface, rng, render=False)
        res = first if first.end_reason != "fault" else \
            play_rally(server, opp, end, side, 2, surface, rng, render=False)
        rows.append((first.end_reason != "fault", res.end_reason == "ace",
                     res.end_reason == "double_fault", res.winner_role == 0,
                     res.serve_kmh, res.rally_length))
    return pd.DataFrame(rows, columns=["first_in", "ace", "df", "won", "kmh", "rally"])


def summarise(o: pd.DataFrame) -> dict[str, float]:
    first = o["first_in"]
    r = o["rally"]
    out = {"first_serve_in": first.mean(), "ace": o["ace"].mean(),
           "double_fault": o["df"].mean(), "first_serve_won": o.loc[first, "won"].mean(),
           "second_serve_won": o.loc[~first, "won"].mean(),
           "first_serve_kmh_median": o.loc[first, "kmh"].median(),
           "second_serve_kmh_median": o.loc[~first & ~o["df"], "kmh"].median(),
           "rally_mean": r.mean()}
    shares = [(r == 0).mean(), (r == 1).mean(), (r == 2).mean(), r.between(3, 4).mean(),
              r.between(5, 8).mean(), (r >= 9).mean()]
    out.update(dict(zip(RALLY_BINS, shares)))
    return out


def _measure(args: tuple) -> dict[str, float]:
    profile, opponents, n_points, seed = args
    return summarise(service_outcomes(profile, opponents, n_points, seed))


def step(p: PlayerProfile, sim: dict[str, float], tgt: pd.Series, damping: float) -> PlayerProfile:
    """One damped proportional update of the calibrated parameters."""
    d = damping
    clip = lambda v, lo, hi: float(min(max(v, lo), hi))  # noqa: E731
    fsi_t, df_t = float(tgt["first_serve_in"]), float(tgt["double_fault"])
    p2_t = df_t / max(1.0 - fsi_t, 1e-6)
    p2_s = sim["double_fault"] / max(1.0 - sim["first_serve_in"], 1e-6)
    unret_t = float(tgt["1"]) - float(tgt["ace"])  # serves in play but not returned
    unret_s = sim["1"] - sim["ace"]
    tempo = d * (sim["rally_mean"] - float(tgt["rally_mean"])) / 6.0
    return replace(
        p,
        first_serve_noise_deg=clip(p.first_serve_noise_deg * math.exp(
            2.5 * d * (sim["first_serve_in"] - fsi_t)), 0.05, 5.0),
        second_serve_noise_deg=clip(p.second_serve_noise_deg * math.exp(
            -2.5 * d * (p2_s - p2_t)), 0.05, 5.0),
        serve_disguise_s=clip(p.serve_disguise_s + 0.8 * d * (float(tgt["ace"]) - sim["ace"]),
                              -0.2, 0.4),
        serve_heaviness=clip(p.serve_heaviness * math.exp(
            4.0 * d * (unret_t - unret_s)), 0.2, 10.0),
        serve_initiative=clip(p.serve_initiative * math.exp(
            4.0 * d * (float(tgt["first_serve_won"]) - sim["first_serve_won"])), 0.2, 8.0),
        second_serve_initiative=clip(p.second_serve_initiative * math.exp(
            4.0 * d * (float(tgt["second_serve_won"]) - sim["second_serve_won"])), 0.2, 8.0),
        # Rally tempo: own noise and the pressure put on the opponent together.
        rally_noise_deg=clip(p.rally_noise_deg * math.exp(0.5 * tempo), 0.2, 4.0),
        rally_pressure=clip(p.rally_pressure * math.exp(0.5 * tempo), 0.2, 5.0),
        first_serve_kmh=p.first_serve_kmh + d * (float(tgt["first_serve_kmh_median"]) -
                                                 sim["first_serve_kmh_median"]),
        second_serve_kmh=p.second_serve_kmh + d * (float(tgt["second_serve_kmh_median"]) -
                                                   sim["second_serve_kmh_median"]),
    )


def write_profiles(named: dict[str, PlayerProfile], path: Path, note: str = "") -> None:
    payload = {
        "note": "Calibrated by scripts/calibrate_profiles.py against sportsngen/synth/data/"
                "slam2011_targets.csv (2011 US Open + Wimbledon, Jeff Sackmann / Tennis "
                "Abstract, CC BY-NC-SA 4.0). " + note,
        "players": [_rounded(p.to_dict()) for p in named.values()],
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(payload, indent=1) + "\n")
    if path.resolve() == prof.PROFILES_JSON.resolve():
        prof._named_cache.cache_clear()


def _rounded(d: dict) -> dict:
    return {k: (round(v, 4) if isinstance(v, float) else v) for k, v in d.items()}


def table(named: dict[str, PlayerProfile], sims: dict[str, dict], targets: pd.DataFrame) -> str:
    lines = [f"{'player':16s} " + " ".join(f"{k[:12]:>13s}" for k in STAT_KEYS + RALLY_BINS)]
    for name in named:
        sim, tgt = sims[name], targets.loc[name]
        cells = []
        for k in STAT_KEYS + RALLY_BINS:
            scale = 1.0 if ("kmh" in k or k == "rally_mean") else 100.0
            cells.append(f"{sim[k] * scale:6.1f}/{float(tgt[k]) * scale:6.1f}")
        lines.append(f"{name:16s} " + " ".join(cells))
    return "\n".join(lines)


def measure_all(named: dict[str, PlayerProfile], n_points: int, seed: int, workers: int,
                n_opponents: int = 96) -> dict[str, dict]:
    """Statistics of every named player against population players of the same gender."""
    jobs = []
    for i, p in enumerate(named.values()):
        centre = prof.average_profile(p.gender, profiles=list(named.values()))
        pop = sample_population(n_opponents, seed=seed + 1000 + i, gender=p.gender,
                                base=centre)
        jobs.append((p, pop, n_points, seed + i))
    if workers > 1:
        with get_context("spawn").Pool(workers) as pool:
            results = pool.map(_measure, jobs)
    else:
        results = [_measure(j) for j in jobs]
    return dict(zip(named, results))


TOLERANCE_PP = {"first_serve_in": 3, "ace": 3, "double_fault": 3, "first_serve_won": 3,
                "second_serve_won": 3}


def acceptance(named: dict[str, PlayerProfile], targets: pd.DataFrame, n_points: int, seed: int,
               workers: int, n_opponents: int = 48) -> str:
    """The acceptance table: each named player plays whole matches (through `MatchState`)
    against `n_opponents` population players of the same gender until `n_points` points are
    played (about half served by the named player); serving figures and rally lengths from the
    points table with `serve_stats` / `rally_distribution`. A markdown table; '!' marks a
    figure outside its tolerance (3 points, 5 km/h, 0.5 shots, 5 points per rally bin)."""
    from sportsngen.eval.stats import rally_distribution, serve_stats
    from sportsngen.synth.generate import service_points

    head = ("| player | service pts | 1st in % | aces % | DF % | 1st won % | 2nd won % | "
            "1st km/h | 2nd km/h | rally mean | " + " | ".join(f"rally {b} %" for b in RALLY_BINS)
            + " |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for i, (name, p) in enumerate(named.items()):
        centre = prof.average_profile(p.gender, profiles=list(named.values()))
        pop = sample_population(n_opponents, seed=seed + 500 + i, gender=p.gender, base=centre)
        pts = service_points([(p, q) for q in pop], list(SURFACES), n_points, seed + i,
                             workers=workers)
        st = serve_stats(pts).loc[name]
        rd = rally_distribution(pts).loc[name]
        t = targets.loc[name]
        cells = [name, f"{int(st['n_points'])}"]
        for k in STAT_KEYS:
            sim, real = float(st[k]), float(t[k])
            if k in TOLERANCE_PP:
                bad = abs(sim - real) * 100 > TOLERANCE_PP[k]
                cells.append(f"{sim * 100:.1f} / {real * 100:.1f}{' !' if bad else ''}")
            elif "kmh" in k:
                cells.append(f"{sim:.0f} / {real:.0f}{' !' if abs(sim - real) > 5 else ''}")
            else:
                cells.append(f"{sim:.2f} / {real:.2f}{' !' if abs(sim - real) > 0.5 else ''}")
        for b in RALLY_BINS:
            sim, real = float(rd[b]), float(t[b])
            cells.append(f"{sim * 100:.1f} / {real * 100:.1f}"
                         f"{' !' if abs(sim - real) * 100 > 5 else ''}")
        lines.append("| " + " | ".join(cells) + " |")
        print(lines[-1], flush=True)
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--points", type=int, default=1500, help="service points per player/round")
    ap.add_argument("--damping", type=float, default=0.8)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=2011)
    ap.add_argument("--opponents", type=int, default=0,
                    help="population players per named player (default 96; 48 for --report)")
    ap.add_argument("--init", action="store_true", help="start from the initial guesses")
    ap.add_argument("--only", nargs="*", help="calibrate only these players")
    ap.add_argument("--targets", type=Path, default=TARGETS_CSV)
    ap.add_argument("--out", type=Path, default=prof.PROFILES_JSON,
                    help="profiles file to start from (unless --init) and to write")
    ap.add_argument("--report", type=int, metavar="N_POINTS", default=0,
                    help="only print the acceptance table (whole matches, N_POINTS per player)")
    args = ap.parse_args()
    targets = load_targets(args.targets)
    t_start = time.time()
    if args.init or not args.out.exists():
        named = {n: initial_profile(n, targets.loc[n]) for n in INITIAL}
    else:
        raw = json.loads(args.out.read_text())["players"]
        named = {p["name"]: PlayerProfile.from_dict(p) for p in raw}
    if args.report:
        print("simulated / real (2011); '!' = outside tolerance", flush=True)
        acceptance(named, targets, args.report, args.seed + 7, args.workers,
                   args.opponents or 48)
        print(f"done in {time.time() - t_start:.0f} s", flush=True)
        return
    for r in range(args.rounds):
        sims = measure_all(named, args.points, args.seed, args.workers, args.opponents or 96)
        print(f"round {r} ({time.time() - t_start:.0f} s): simulated/target\n"
              + table(named, sims, targets), flush=True)
        for name in named:
            if args.only and name not in args.only:
                continue
            named[name] = step(named[name], sims[name], targets.loc[name], args.damping)
        write_profiles(named, args.out,
                       note=f"{r + 1} rounds of {args.points} service points a player")
    print(f"done in {time.time() - t_start:.0f} s", flush=True)


if __name__ == "__main__":
    main()

