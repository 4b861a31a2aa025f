"""Calibration of the named player profiles to real data, by damped proportional steps.

Two sources, two sets of knobs that do not overlap:

- **2011 serving statistics** (`data/slam2011_targets.csv`, derived from the 2011 US Open and
  Wimbledon point-by-point data of Jeff Sackmann / Tennis Abstract, CC BY-NC-SA 4.0): each
  round plays service points of every named player against population players of his gender
  (hard and grass, as the two events) and moves one parameter per statistic:

      first serve in %        <- first_serve_noise_deg   (more noise, more faults)
      double faults %         <- second_serve_noise_deg
      aces %                  <- serve_disguise_s        (the returner starts later; at
                                                          its floor: serve_margin_m)
      unreturned serves       <- serve_heaviness         (more rushed returns)
      1st serve points won %  <- serve_initiative        (the serve sets up the next ball)
      2nd serve points won %  <- second_serve_initiative
      mean rally length       <- rally_noise_deg and rally_pressure together
      median serve speeds     <- first/second_serve_kmh

- **Hawk-Eye ball keypoints** (`eval.hawkeye`: 2019-2020 medians per player and surface):
  the named matchups are played with frames and measured with the same statistics as real
  keypoints (`hawkeye_step` lists which parameter follows which statistic).

Rounds use fixed seeds (common random numbers), so the steps see the parameter change more
than sampling noise; the population is re-sampled every round around the current profiles.
This is the one `synth` module that reads `eval`'s statistics (pure numpy/pandas): generated
play is measured with exactly the code that measures real play.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from sportsngen.synth import profiles as prof
from sportsngen.synth.profiles import (
    PlayerProfile,
    initial_profile,
    profile_seeds,
    read_profiles,
    sample_population,
)
from sportsngen.synth.rally import play_rally
from sportsngen.synth.targets import RALLY_BINS, load_targets
from sportsngen.workers import pool_context

SURFACES_2011 = ("hard", "grass")
STAT_KEYS = ("first_serve_in", "ace", "double_fault", "first_serve_won", "second_serve_won",
             "first_serve_kmh_median", "second_serve_kmh_median", "rally_mean")
TOLERANCE_PP = {"first_serve_in": 3, "ace": 3, "double_fault": 3, "first_serve_won": 3,
                "second_serve_won": 3}
TOLERANCE_KMH = 5.0
TOLERANCE_RALLY_MEAN = 0.5
TOLERANCE_RALLY_BIN_PP = 5
DISGUISE_RANGE_S = (-0.2, 0.4)
SERVE_MARGIN_RANGE_M = (0.45, 1.2)  # the lower end: every named player's before version 6.2


def starting_profiles(out: Path, init: bool, targets: pd.DataFrame) -> dict[str, PlayerProfile]:
    """The profiles a calibration starts from: those in `out`, or with `init` (or no `out`
    yet) each named player's seed (`profile_seeds`, `initial_profile`)."""
    if init or not out.exists():
        return {n: initial_profile(n, targets.loc[n], s) for n, s in profile_seeds().items()}
    return read_profiles(out)


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
        surface = SURFACES_2011[(i // 50) % 2]
        first = play_rally(server, opp, end, side, 1, surface, rng, render=False)
        res = first if first.end_reason != "fault" else \
            play_rally(server, opp, end, side, 2, surface, rng, render=False)
        rows.append((first.end_reason != "fault", res.end_reason == "ace",
                     res.end_reason == "double_fault", res.winner_role == 0,
                     res.serve_kmh, res.rally_length))
    return pd.DataFrame(rows, columns=["first_in", "ace", "df", "won", "kmh", "rally"])


def summarise(o: pd.DataFrame) -> dict[str, float]:
    """The 2011 statistics of `service_outcomes` rows."""
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


def _clip(v: float, lo: float, hi: float) -> float:
    return float(min(max(v, lo), hi))


def step_2011(p: PlayerProfile, sim: dict[str, float], tgt: pd.Series,
              damping: float) -> PlayerProfile:
    """One damped proportional update of the parameters the 2011 statistics calibrate."""
    d = damping
    fsi_t, df_t = float(tgt["first_serve_in"]), float(tgt["double_fault"])
    p2_t = df_t / max(1.0 - fsi_t, 1e-6)
    p2_s = sim["double_fault"] / max(1.0 - sim["first_serve_in"], 1e-6)
    unret_t = float(tgt["1"]) - float(tgt["ace"])  # serves in play but not returned
    unret_s = sim["1"] - sim["ace"]
    tempo = d * (sim["rally_mean"] - float(tgt["rally_mean"])) / 6.0
    ace_gap = sim["ace"] - float(tgt["ace"])
    # The returner already reacts at his floor (`rally.MIN_RETURN_REACTION_S`): the server's
    # aces follow how far inside the lines he aims (Djokovic, 4,000 service points: margin
    # 0.45 -> 0.65 m, aces 10.4 -> 6.0 %, first serves in 66 -> 72 % before their noise moves).
    margin = p.serve_margin_m
    if p.serve_disguise_s <= DISGUISE_RANGE_S[0] + 1e-9:
        margin = _clip(margin + 4.0 * d * ace_gap, *SERVE_MARGIN_RANGE_M)
    return _carry_overrides(p, replace(
        p,
        first_serve_noise_deg=_clip(p.first_serve_noise_deg * math.exp(
            2.5 * d * (sim["first_serve_in"] - fsi_t)), 0.05, 5.0),
        second_serve_noise_deg=_clip(p.second_serve_noise_deg * math.exp(
            -2.5 * d * (p2_s - p2_t)), 0.05, 5.0),
        serve_disguise_s=_clip(p.serve_disguise_s - 0.8 * d * ace_gap, *DISGUISE_RANGE_S),
        serve_margin_m=margin,
        serve_heaviness=_clip(p.serve_heaviness * math.exp(
            4.0 * d * (unret_t - unret_s)), 0.2, 10.0),
        serve_initiative=_clip(p.serve_initiative * math.exp(
            4.0 * d * (float(tgt["first_serve_won"]) - sim["first_serve_won"])), 0.2, 8.0),
        second_serve_initiative=_clip(p.second_serve_initiative * math.exp(
            4.0 * d * (float(tgt["second_serve_won"]) - sim["second_serve_won"])), 0.2, 8.0),
        # Rally tempo: own noise and the pressure put on the opponent together.
        rally_noise_deg=_clip(p.rally_noise_deg * math.exp(0.5 * tempo), 0.2, 4.0),
        rally_pressure=_clip(p.rally_pressure * math.exp(0.5 * tempo), 0.2, 5.0),
        first_serve_kmh=p.first_serve_kmh + d * (float(tgt["first_serve_kmh_median"]) -
                                                 sim["first_serve_kmh_median"]),
        second_serve_kmh=p.second_serve_kmh + d * (float(tgt["second_serve_kmh_median"]) -
                                                   sim["second_serve_kmh_median"]),
    ))


# The 2011 steps that add to a field; the others multiply it.
ADDITIVE_2011_FIELDS = ("serve_disguise_s", "serve_margin_m", "first_serve_kmh",
                        "second_serve_kmh")


def _carry_overrides(old: PlayerProfile, new: PlayerProfile) -> PlayerProfile:
    """`new` with each surface override of a field the 2011 step moved moved alike (the same
    difference for `ADDITIVE_2011_FIELDS`, the same ratio for the rest): the 2011 figures pool
    hard and grass, so an override stays what it was set to be, an offset from the base (Federer
    on hard, version 6.4: less rally noise and serve initiative than on grass)."""
    if not old.surface_overrides:
        return new
    carried = []
    for surface, values in old.surface_overrides:
        moved = []
        for field, value in values:
            before, after = getattr(old, field), getattr(new, field)
            if after != before:
                value = value + (after - before) if field in ADDITIVE_2011_FIELDS else \
                    value * (after / before if before else 1.0)
            moved.append((field, float(value)))
        carried.append((surface, tuple(moved)))
    return replace(new, surface_overrides=tuple(carried))


def _rounded(d: dict) -> dict:
    return {k: _rounded(v) if isinstance(v, dict) else round(v, 4) if isinstance(v, float)
            else v for k, v in d.items()}


def write_profiles(named: dict[str, PlayerProfile], path: Path, note: str = "") -> None:
    """Write profiles as `profiles.json` holds them (floats to 4 decimals)."""
    payload = {
        "note": "Calibrated by sportsngen.synth.calibrate (scripts/calibrate_profiles.py) "
                "against sportsngen/synth/data/slam2011_targets.csv (2011 US Open + Wimbledon, "
                "Jeff Sackmann / Tennis Abstract, CC BY-NC-SA 4.0) and the Hawk-Eye keypoint "
                "figures of AO 2020 and RG 2019-2020 via CourtVision. " + note,
        "players": [_rounded(p.to_dict()) for p in named.values()],
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(payload, indent=1) + "\n")
    if path.resolve() == prof.PROFILES_JSON.resolve():
        prof._named_cache.cache_clear()


def table_2011(named: dict[str, PlayerProfile], sims: dict[str, dict],
               targets: pd.DataFrame) -> str:
    """A plain-text table of simulated/target figures (percentages, km/h, shots)."""
    lines = [f"{'player':16s} " + " ".join(f"{k[:12]:>13s}" for k in STAT_KEYS + RALLY_BINS)]
    for name in named:
        sim, tgt = sims[name], targets.loc[name]
        cells = []
        for k in STAT_KEYS + RALLY_BINS:
            scale = 1.0 if ("kmh" in k or k == "rally_mean") else 100.0
            cells.append(f"{sim[k] * scale:6.1f}/{float(tgt[k]) * scale:6.1f}")
        lines.append(f"{name:16s} " + " ".join(cells))
    return "\n".join(lines)


def population_opponents(p: PlayerProfile, named: dict[str, PlayerProfile], n: int,
                         seed: int) -> list[PlayerProfile]:
    """`n` population players of `p`'s gender around the named players' average: the
    opponents the 2011 figures are measured against."""
    centre = prof.average_profile(p.gender, profiles=list(named.values()))
    return sample_population(n, seed=seed, gender=p.gender, base=centre)


def measure_2011(named: dict[str, PlayerProfile], n_points: int, seed: int, workers: int,
                 n_opponents: int = 96) -> dict[str, dict]:
    """2011 statistics of every named player against population players of his gender."""
    jobs = [(p, population_opponents(p, named, n_opponents, seed + 1000 + i), n_points, seed + i)
            for i, p in enumerate(named.values())]
    if workers > 1:
        with pool_context(__name__).Pool(workers) as pool:
            results = pool.map(_measure, jobs)
    else:
        results = [_measure(j) for j in jobs]
    return dict(zip(named, results))


def acceptance_2011(named: dict[str, PlayerProfile], targets: pd.DataFrame, n_points: int,
                    seed: int, workers: int, n_opponents: int = 48) -> str:
    """The acceptance table: each named player plays whole matches (through `MatchState`)
    against `n_opponents` population players of his gender until `n_points` points are played
    (about half served by him); serving figures and rally lengths from the points table with
    `serve_stats` / `rally_distribution`. A markdown table; '!' marks a figure outside its
    tolerance (3 points, 5 km/h, 0.5 shots, 5 points per rally bin)."""
    from sportsngen.eval.stats import rally_distribution, serve_stats
    from sportsngen.synth.generate import service_points

    head = ("| player | service pts | 1st in % | aces % | DF % | 1st won % | 2nd won % | "
            "1st km/h | 2nd km/h | rally mean | " + " | ".join(f"rally {b} %" for b in RALLY_BINS)
            + " |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for i, (name, p) in enumerate(named.items()):
        pop = population_opponents(p, named, n_opponents, seed + 500 + i)
        pts = service_points([(p, q) for q in pop], list(SURFACES_2011), n_points, seed + i,
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
                bad = abs(sim - real) > TOLERANCE_KMH
                cells.append(f"{sim:.0f} / {real:.0f}{' !' if bad else ''}")
            else:
                bad = abs(sim - real) > TOLERANCE_RALLY_MEAN
                cells.append(f"{sim:.2f} / {real:.2f}{' !' if bad else ''}")
        for b in RALLY_BINS:
            sim, real = float(rd[b]), float(t[b])
            bad = abs(sim - real) * 100 > TOLERANCE_RALLY_BIN_PP
            cells.append(f"{sim * 100:.1f} / {real * 100:.1f}{' !' if bad else ''}")
        lines.append("| " + " | ".join(cells) + " |")
        print(lines[-1], flush=True)
    return "\n".join(lines)


# -- Hawk-Eye ball-level figures ------------------------------------------------------------

# statistic -> profile parameter: "add": param += damping * gain * (real - generated);
# "log": param *= exp(damping * gain * (real - generated)); clipped to [lo, hi]. Gains are the
# inverse sensitivities measured on the physics: a contact height or a court position moves
# its statistic one for one; a second serve crosses the net ~0.02 m higher per m/s of kick; a
# rally ball or a return ~2.1 m lower per unit of log pace (~0.065 m per m/s at 31-34 m/s); the
# 90 % quantile of a player's return net heights ~0.6 m lower per unit of log rushed-return
# noise (3 -> 2: 0.13-0.27 m, Federer, Nadal, Djokovic and Williams on hard and clay).
# Pace follows the net height; topspin stays at the seeds' (men 6, Nadal 8.5, women 4 m/s):
# fitted too, it chased the opponent's contact height and drove both pace and spin up.
HAWKEYE_KNOBS: tuple[tuple[str, str, str, float, float, float], ...] = (
    ("serve_contact_z_median", "contact_height_m", "add", 1.0, 2.3, 3.3),
    ("return1_contact_behind_m_median", "return_depth_m", "add", 1.0, -2.5, 6.0),
    ("return2_contact_behind_m_median", "second_return_depth_m", "add", 1.0, -2.5, 6.0),
    ("rally_contact_behind_m_median", "recovery_depth_m", "add", 1.0, -1.0, 5.0),
    ("serve2_net_z_median", "second_serve_spin_mps", "add", 30.0, 0.0, 12.0),
    ("rally_net_z_median", "rally_speed_mps", "log", -0.45, 24.0, 42.0),
    ("rally_depth_m_median", "rally_depth_margin_m", "add", 1.0, 1.5, 6.0),
    ("return_net_z_median", "return_pace", "log", -0.45, 0.5, 1.3),
    ("return_net_z_p90", "rushed_return_noise", "log", 1.7, 1.0, 5.0),
)
SERVE_ZONE_STATS = ("serve1_wide_share", "serve1_body_share", "serve1_t_share")
SERVE_ZONE_FIELDS = ("serve_wide", "serve_body", "serve_t")
MIN_HAWKEYE_N = 30   # a generated statistic over fewer strikes does not steer
# With `tour_for_thin`, a player with fewer real rally strikes on a surface than this (Murray
# on clay, Sharapova on hard: one match each) is calibrated to his tour's figures there: one
# match is one opponent's game, and Sharapova's flat balls left Serena Williams' contacts 0.19
# m below Williams' own figures, which are measured against the whole tour. Not the default:
# it brought the Hawk-Eye figures in but, in three runs, pulled the 2011 figures out
# (docs/synthetic-data.md).
MIN_OWN_RALLY_STRIKES = 200


def measure_hawkeye(named: dict[str, PlayerProfile], n_points: int, seed: int, workers: int,
                    matchups=None) -> pd.DataFrame:
    """Hawk-Eye statistics (`eval.hawkeye.hawkeye_stats`, per player and tour) of `n_points`
    generated points of each matchup (default: the README's five), matchup k from seed + k."""
    from sportsngen.eval.hawkeye import hawkeye_stats
    from sportsngen.eval.hawkeye_report import README_MATCHUPS, generated_strikes

    strikes = generated_strikes(n_points, seed, matchups or README_MATCHUPS, profiles=named,
                                workers=workers)
    tours = {p.name: ("ATP" if p.gender == "men" else "WTA") for p in named.values()}
    return hawkeye_stats(strikes, tours=tours)


def calibration_targets(targets: pd.DataFrame,
                        named: dict[str, PlayerProfile]) -> pd.DataFrame:
    """The Hawk-Eye figures each named player is calibrated to: his own on a surface where he
    has at least `MIN_OWN_RALLY_STRIKES` real rally strikes, else his tour's (ATP / WTA)."""
    t = targets.astype({"player": str, "surface": str, "statistic": str})
    rally_n = t[t["statistic"] == "rally_contact_z_median"].set_index(["player", "surface"])["n"]
    parts = [t[~t["player"].isin(list(named))]]
    for name, p in named.items():
        own = t[t["player"] == name]
        tour = t[t["player"] == ("ATP" if p.gender == "men" else "WTA")]
        for surface in own["surface"].unique():
            if rally_n.get((name, surface), 0) >= MIN_OWN_RALLY_STRIKES:
                parts.append(own[own["surface"] == surface])
            else:
                parts.append(tour[tour["surface"] == surface].assign(player=name))
    return pd.concat(parts, ignore_index=True)


def _player_figures(stats: pd.DataFrame, targets: pd.DataFrame, name: str,
                    surfaces: set[str] | None = None) -> tuple[pd.Series, pd.Series]:
    """(generated, real) per statistic of one player, each the mean over the surfaces both
    have (generated over at least `MIN_HAWKEYE_N` strikes), or over those of `surfaces`."""
    key = ["surface", "statistic"]
    g = stats[stats["player"].astype(str) == name].astype({"surface": str, "statistic": str})
    t = targets[targets["player"].astype(str) == name].astype({"surface": str,
                                                                 "statistic": str})
    m = g.merge(t, on=key, suffixes=("_g", "_t"))
    m = m[m["value_g"].notna() & m["value_t"].notna() & (m["n_g"] >= MIN_HAWKEYE_N)]
    if surfaces is not None:
        m = m[m["surface"].isin(surfaces)]
    return m.groupby("statistic")["value_g"].mean(), m.groupby("statistic")["value_t"].mean()


def _knob_step(value: float, err: float, mode: str, gain: float, lo: float, hi: float,
               damping: float) -> float:
    value = value + damping * gain * err if mode == "add" else \
        value * math.exp(damping * gain * err)
    return _clip(value, lo, hi)


def step_hawkeye(p: PlayerProfile, stats: pd.DataFrame, targets: pd.DataFrame,
                 damping: float) -> PlayerProfile:
    """One damped update of the parameters the Hawk-Eye figures calibrate (`HAWKEYE_KNOBS`,
    and the first-serve placement mix from the zone shares); a player without real figures
    keeps his. A field one of the player's surfaces overrides
    (`PlayerProfile.surface_overrides`) is stepped there on that surface's figures alone, its
    base value on the other surfaces'."""
    overrides = {surface: dict(values) for surface, values in p.surface_overrides}
    changes = {}
    for stat, param, mode, gain, lo, hi in HAWKEYE_KNOBS:
        def knob(values, sim, real, stat=stat, param=param, mode=mode, gain=gain, lo=lo, hi=hi):
            if stat not in sim.index:
                return None
            return {param: _knob_step(values[param], float(real[stat] - sim[stat]), mode,
                                      gain, lo, hi, damping)}
        changes.update(_step_by_surface(p, overrides, stats, targets, (param,), knob))
    changes.update(_step_by_surface(
        p, overrides, stats, targets, SERVE_ZONE_FIELDS,
        lambda values, sim, real: _mix_step(list(values.values()), sim, real, damping)))
    if overrides:
        changes["surface_overrides"] = tuple((surface, tuple(values.items()))
                                             for surface, values in overrides.items())
    return replace(p, **changes)


def _step_by_surface(p: PlayerProfile, overrides: dict[str, dict[str, float]],
                     stats: pd.DataFrame, targets: pd.DataFrame, names: tuple[str, ...],
                     step) -> dict[str, float]:
    """`step(values, sim, real)` (new values or None) of the fields `names`: on each surface
    that overrides any of them, on that surface's figures alone (written into `overrides`);
    the base values on the other surfaces' figures (returned)."""
    split = {surface for surface, values in overrides.items()
             if any(n in values for n in names)}
    for surface in split:
        values = {n: overrides[surface].get(n, getattr(p, n)) for n in names}
        moved = step(values, *_player_figures(stats, targets, p.name, {surface}))
        overrides[surface].update(moved or {})
    rest = set(stats["surface"].astype(str)) - split
    return step({n: getattr(p, n) for n in names},
                *_player_figures(stats, targets, p.name, rest)) or {}


def _mix_step(mix: list[float], sim: pd.Series, real: pd.Series,
              damping: float) -> dict[str, float] | None:
    """The first-serve placement mix moved toward the real zone shares (None: no figures)."""
    if not all(s in sim.index for s in SERVE_ZONE_STATS):
        return None
    ratio = np.array([max(real[s], 0.005) / max(sim[s], 0.005) for s in SERVE_ZONE_STATS])
    m = np.asarray(mix, dtype=float) * ratio ** damping
    return dict(zip(SERVE_ZONE_FIELDS, (float(v) for v in m / m.sum())))


def hawkeye_table(named: dict[str, PlayerProfile], stats: pd.DataFrame,
                  targets: pd.DataFrame) -> str:
    """generated/real of the calibrated statistics, one line a player."""
    cols = [k[0] for k in HAWKEYE_KNOBS] + list(SERVE_ZONE_STATS)
    lines = [f"{'player':16s} " + " ".join(f"{c.split('_m_')[0][:14]:>15s}" for c in cols)]
    for name in named:
        sim, real = _player_figures(stats, targets, name)
        cells = [f"{sim.get(c, np.nan):7.2f}/{real.get(c, np.nan):<7.2f}" for c in cols]
        lines.append(f"{name:16s} " + " ".join(cells))
    return "\n".join(lines)


def calibrate(named: dict[str, PlayerProfile], rounds: int, points_2011: int,
              points_hawkeye: int, seed: int, workers: int, damping: float,
              only: list[str] | None = None, out: Path | None = None,
              hawkeye_targets: pd.DataFrame | None = None, tour_for_thin: bool = False,
              log=print) -> dict[str, PlayerProfile]:
    """`rounds` joint rounds: measure the 2011 statistics (`points_2011` service points a
    player; 0 skips them) and the Hawk-Eye statistics (`points_hawkeye` points a matchup; 0
    skips them), step every player (or `only` these), write the profiles to `out`.
    `tour_for_thin`: players with thin Hawk-Eye figures follow their tour's
    (`calibration_targets`)."""
    targets = load_targets()
    if points_hawkeye and hawkeye_targets is None:
        from sportsngen.eval.hawkeye import load_targets as load_hawkeye_targets
        hawkeye_targets = load_hawkeye_targets()
    if hawkeye_targets is not None and tour_for_thin:
        hawkeye_targets = calibration_targets(hawkeye_targets, named)
    named = dict(named)
    for r in range(rounds):
        sims = measure_2011(named, points_2011, seed, workers) if points_2011 else None
        he = measure_hawkeye(named, points_hawkeye, seed, workers) if points_hawkeye else None
        if sims is not None:
            log(f"round {r}: 2011 simulated/target\n" + table_2011(named, sims, targets))
        if he is not None:
            log(f"round {r}: Hawk-Eye generated/real\n" +
                hawkeye_table(named, he, hawkeye_targets))
        for name, p in named.items():
            if only and name not in only:
                continue
            if sims is not None:
                p = step_2011(p, sims[name], targets.loc[name], damping)
            if he is not None:
                p = step_hawkeye(p, he, hawkeye_targets, damping)
            named[name] = p
        if out is not None:
            write_profiles(named, out, note=f"last run: {r + 1} rounds of {points_2011} service "
                                            f"points a player and {points_hawkeye} points a "
                                            "Hawk-Eye matchup")
    return named


def acceptance_hawkeye(named: dict[str, PlayerProfile], n_points: int, seed: int,
                       workers: int) -> str:
    """The Hawk-Eye acceptance table: the README's five matchups, `n_points` each, compared
    with the real figures for its groups (`eval.hawkeye_report.README_GROUPS`), markdown."""
    from sportsngen.eval.hawkeye import compare, comparison_markdown, load_targets
    from sportsngen.eval.hawkeye_report import README_GROUPS

    stats = measure_hawkeye(named, n_points, seed, workers)
    cmp = compare(stats, load_targets(), README_GROUPS)
    return comparison_markdown(cmp)


def calibrate_profiles(out: Path = prof.PROFILES_JSON, init: bool = False, rounds: int = 6,
                       points: int = 1500, hawkeye_points: int = 0, damping: float = 0.8,
                       workers: int = 2, seed: int = 2011, only: list[str] | None = None,
                       tour_for_thin: bool = False, report: int = 0,
                       hawkeye_report: int = 0) -> None:
    """`scripts/calibrate_profiles.py`: from `starting_profiles`, print the 2011 acceptance
    table (`report` points a player) and/or the Hawk-Eye one (`hawkeye_report` points a
    matchup), or else `calibrate` and write the profiles to `out`, logging each round."""
    t0 = time.time()
    targets = load_targets()
    named = starting_profiles(out, init, targets)
    if report:
        print("simulated / real (2011); '!' = outside tolerance", flush=True)
        acceptance_2011(named, targets, report, seed + 7, workers)
    if hawkeye_report:
        print(acceptance_hawkeye(named, hawkeye_report, seed + 7, workers))
    if not (report or hawkeye_report):
        calibrate(named, rounds, points, hawkeye_points, seed, workers, damping, only=only,
                  out=out, tour_for_thin=tour_for_thin,
                  log=lambda s: print(f"[{time.time() - t0:.0f} s] {s}", flush=True))
    print(f"done in {time.time() - t0:.0f} s", flush=True)
