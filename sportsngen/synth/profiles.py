"""Player profiles: every per-player parameter of the synthetic generator in one dataclass.

A `PlayerProfile` drives three things: how the player moves (`players.py`: reaction delay,
speed and acceleration limits, reach, recovery position), how the player decides
(`behaviour.py`: serve speeds, placement, aim noise, rally aggression and consistency) and how
hard the player is to play against (serve disguise and heaviness).

Named profiles (Federer, Nadal, ...) live in ``data/profiles.json``, written by
``scripts/calibrate_profiles.py`` so that the generator reproduces each player's real 2011 Grand
Slam serving statistics, starting from each player's seed in ``data/profile_seeds.json``
(`profile_seeds`, `initial_profile`). `sample_population` draws anonymous players of varied
styles around the average of the named players, for training a generic model.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, fields, replace
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd

from sportsngen.data.tracking import SURFACES

PROFILES_JSON = Path(__file__).with_name("data") / "profiles.json"
SEEDS_JSON = Path(__file__).with_name("data") / "profile_seeds.json"

HANDEDNESS = ("right", "left")
GENDERS = ("men", "women")
STYLES = ("all_court", "baseliner", "serve_volleyer", "counter_puncher", "big_server")

# Fields that are probabilities or shares (must lie in [0, 1]).
_UNIT_FIELDS = ("serve_wide", "serve_body", "serve_t", "aggression", "net_approach",
                "slice_share", "cross_court", "down_the_line", "forehand_preference")
# Fields that may be negative (signed spins, timing offsets that anticipate); every other
# numeric field must be >= 0.
_SIGNED_FIELDS = ("first_serve_spin_mps", "second_serve_spin_mps", "serve_disguise_s",
                  "topspin_mps", "slice_spin_mps", "recovery_depth_m", "return_depth_m",
                  "second_return_depth_m")
# Fields that say who the player is, not how he plays: no surface overrides them.
_IDENTITY_FIELDS = ("name", "gender", "handedness", "style", "surface_overrides")


@dataclass(frozen=True)
class PlayerProfile:
    """Every parameter of one player. Units in the names; probabilities in [0, 1].

    Movement (elite values: reaction 0.15-0.25 s, at most ~7 m/s and ~6 m/s^2):
    ``reaction_s`` delay between the opponent's contact and the first step; ``max_speed_mps``,
    ``max_accel_mps2`` limits of the centre of mass; ``reach_m`` the furthest horizontal distance
    between centre of mass and ball at a contact; ``recovery_depth_m`` how far behind the
    baseline the player recovers to and likes to meet rally balls (negative: inside the court),
    ``recovery_backhand_offset_m`` how far toward the backhand side; ``return_depth_m`` and
    ``second_return_depth_m`` where the player waits for a first / second serve and likes to
    meet it (behind the baseline; on clay deeper, on grass nearer: `behaviour.SURFACE_DEPTH_M`).

    Serve: ``contact_height_m`` of the toss; first/second serve speed at contact (mean and
    standard deviation, km/h); spins (m/s, > 0 topspin/kick); ``serve_wide/body/t`` the
    placement mix of first serves (normalised); ``first_serve_noise_deg`` and
    ``second_serve_noise_deg`` the execution noise (s.d. of the launch elevation, degrees; the
    azimuth gets `AZIMUTH_NOISE_RATIO` times more) that makes faults happen at the player's rate;
    ``serve_margin_m`` how far inside the lines first serves are aimed; ``serve_disguise_s``
    delays the returner's reaction (negative: the serve is read early); ``serve_heaviness``
    multiplies the returner's aim noise on first serves (its square root on second serves: pace,
    kick and placement beyond the aim point); ``serve_initiative`` and
    ``second_serve_initiative`` multiply the difficulty of the server's first rally ball (the
    "serve plus one" a good serve sets up).

    Rally: ``rally_speed_mps`` a neutral groundstroke's speed; ``rally_depth_margin_m`` how far
    inside the baseline it is aimed; ``topspin_mps`` its spin; ``rally_noise_deg`` its execution
    noise; ``rally_pressure`` multiplies the opponent's aim noise on this player's rally balls
    (weight of shot: pace, spin and depth beyond what the aim point says); ``aggression``
    (0 safe, 1 all-out) moves targets toward the lines and raises speed
    and noise; ``net_approach`` chance to come in after a short ball; ``slice_share`` of
    backhands hit with slice; ``cross_court``/``down_the_line`` direction mix (the rest goes to
    the middle); ``forehand_preference`` how readily the player runs around the backhand;
    ``return_anticipation_s`` shortens the reaction to serves; ``return_noise_deg`` the aim noise
    of returns; ``rushed_return_noise`` multiplies it on a return the serve's weight rushed
    (`behaviour.RUSHED_RETURN_EXPONENT`): how well the returner keeps his composure, which sets the
    high tail of his returns (Hawk-Eye: 90 % of Djokovic's cross the net below 2.47 m, of the
    ATP's below 2.94 m); ``return_pace`` the speed of a return as a share of the rally ball's.

    Surfaces: ``surface_overrides`` ((surface, ((field, value), ...)), ...), in JSON
    ``{"clay": {"field": value}}``, replaces fields on one surface (`on_surface`): where a
    player's real figures run the other way between surfaces from the tour's (Nadal returns
    higher and from deeper against second serves on hard than on clay; everyone else the
    reverse), one value per player can place at most one surface. The generator plays a point
    with the profile of its surface (his own 2011 matches too, on hard); the population and
    the average profile read the base.
    """

    name: str
    gender: str = "men"
    handedness: str = "right"
    style: str = "all_court"
    # movement
    reaction_s: float = 0.20
    max_speed_mps: float = 6.8
    max_accel_mps2: float = 6.0
    reach_m: float = 1.8
    recovery_depth_m: float = 1.0
    recovery_backhand_offset_m: float = 0.3
    return_depth_m: float = 1.2
    second_return_depth_m: float = 0.5
    # serve
    contact_height_m: float = 2.8
    first_serve_kmh: float = 185.0
    first_serve_kmh_sd: float = 8.0
    second_serve_kmh: float = 150.0
    second_serve_kmh_sd: float = 8.0
    first_serve_spin_mps: float = 2.0
    second_serve_spin_mps: float = 7.0
    serve_wide: float = 0.4
    serve_body: float = 0.2
    serve_t: float = 0.4
    first_serve_noise_deg: float = 0.8
    second_serve_noise_deg: float = 0.6
    serve_margin_m: float = 0.45
    serve_disguise_s: float = 0.0
    serve_heaviness: float = 1.0
    serve_initiative: float = 1.0
    second_serve_initiative: float = 1.0
    # rally
    rally_speed_mps: float = 31.0
    rally_depth_margin_m: float = 3.4
    rally_noise_deg: float = 1.5
    rally_pressure: float = 1.0
    aggression: float = 0.4
    net_approach: float = 0.1
    topspin_mps: float = 6.0
    slice_spin_mps: float = -4.0
    slice_share: float = 0.15
    cross_court: float = 0.5
    down_the_line: float = 0.25
    forehand_preference: float = 0.5
    return_anticipation_s: float = 0.1
    return_noise_deg: float = 1.4
    rushed_return_noise: float = 3.0
    return_pace: float = 0.85
    surface_overrides: tuple[tuple[str, tuple[tuple[str, float], ...]], ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"profile name must be a non-empty string, got {self.name!r}")
        if self.gender not in GENDERS:
            raise ValueError(f"profile {self.name!r}: gender must be one of {GENDERS}, "
                             f"got {self.gender!r}")
        if self.handedness not in HANDEDNESS:
            raise ValueError(f"profile {self.name!r}: handedness must be one of {HANDEDNESS}, "
                             f"got {self.handedness!r}")
        if self.style not in STYLES:
            raise ValueError(f"profile {self.name!r}: style must be one of {STYLES}, "
                             f"got {self.style!r}")
        for f in fields(self):
            if f.name in _IDENTITY_FIELDS:
                continue
            value = getattr(self, f.name)
            if not isinstance(value, (int, float)) or not np.isfinite(value):
                raise ValueError(f"profile {self.name!r}: {f.name} must be a finite number, "
                                 f"got {value!r}")
            if f.name in _UNIT_FIELDS and not 0.0 <= value <= 1.0:
                raise ValueError(f"profile {self.name!r}: {f.name} is a probability and must "
                                 f"lie in [0, 1], got {value}")
            if f.name not in _SIGNED_FIELDS and value < 0:
                raise ValueError(f"profile {self.name!r}: {f.name} must be >= 0, got {value}")
        if self.serve_wide + self.serve_body + self.serve_t <= 0:
            raise ValueError(f"profile {self.name!r}: serve_wide + serve_body + serve_t "
                             "must be positive")
        if self.cross_court + self.down_the_line > 1.0 + 1e-9:
            raise ValueError(f"profile {self.name!r}: cross_court + down_the_line must be "
                             f"<= 1, got {self.cross_court + self.down_the_line}")
        if self.max_speed_mps <= 0 or self.max_accel_mps2 <= 0 or self.reach_m <= 0:
            raise ValueError(f"profile {self.name!r}: max_speed_mps, max_accel_mps2 and "
                             "reach_m must be positive")
        if not 1.5 <= self.contact_height_m <= 3.5:
            raise ValueError(f"profile {self.name!r}: contact_height_m must lie in "
                             f"[1.5, 3.5] m, got {self.contact_height_m}")

        self._check_surface_overrides()

    def _check_surface_overrides(self) -> None:
        numeric = {f.name for f in fields(self)} - set(_IDENTITY_FIELDS)
        seen = set()
        for entry in self.surface_overrides:
            if not (isinstance(entry, tuple) and len(entry) == 2):
                raise ValueError(f"profile {self.name!r}: surface_overrides holds (surface, "
                                 f"((field, value), ...)) pairs, got {entry!r}")
            surface, values = entry
            if surface not in SURFACES:
                raise ValueError(f"profile {self.name!r}: surface_overrides names unknown "
                                 f"surface {surface!r}; known: {list(SURFACES)}")
            if surface in seen:
                raise ValueError(f"profile {self.name!r}: surface_overrides names "
                                 f"{surface!r} twice")
            seen.add(surface)
            unknown = sorted({k for k, _ in values} - numeric)
            if unknown:
                raise ValueError(f"profile {self.name!r}: surface_overrides[{surface!r}] "
                                 f"names fields {unknown} that no surface can change; "
                                 f"known: {sorted(numeric)}")
            # The overridden profile must itself be valid (limits, probabilities).
            replace(self, surface_overrides=(), name=f"{self.name} on {surface}",
                    **dict(values))

    def on_surface(self, surface: str) -> PlayerProfile:
        """This player as he plays on `surface`: the base fields with that surface's
        overrides (the same profile where there are none)."""
        if surface not in SURFACES:
            raise ValueError(f"unknown surface {surface!r}; known: {list(SURFACES)}")
        if not self.surface_overrides:
            return self
        return _resolved(self, surface)

    @property
    def serve_mix(self) -> np.ndarray:
        """First-serve placement probabilities (wide, body, T), normalised."""
        mix = np.array([self.serve_wide, self.serve_body, self.serve_t], dtype=float)
        return mix / mix.sum()

    def to_dict(self) -> dict:
        d = asdict(self)
        d["surface_overrides"] = {s: dict(v) for s, v in self.surface_overrides}
        if not d["surface_overrides"]:
            del d["surface_overrides"]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> PlayerProfile:
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"unknown profile fields {unknown}; known: {sorted(known)}")
        d = dict(d)
        overrides = d.pop("surface_overrides", {})
        if not isinstance(overrides, dict) or not all(isinstance(v, dict)
                                                      for v in overrides.values()):
            raise ValueError(f"profile {d.get('name')!r}: surface_overrides must map a "
                             f"surface to {{field: value}}, got {overrides!r}")
        d["surface_overrides"] = tuple((s, tuple((k, float(x)) for k, x in v.items()))
                                       for s, v in overrides.items())
        return cls(**d)


@lru_cache(maxsize=256)
def _resolved(p: PlayerProfile, surface: str) -> PlayerProfile:
    # The generator resolves every point's players; building (and validating) the overridden
    # profile once a player and surface, not once a point.
    values = dict(dict(p.surface_overrides).get(surface, ()))
    return replace(p, **values) if values else p


def read_profiles(path: Path) -> dict[str, PlayerProfile]:
    """The profiles of a file written as `profiles.json` is, by name."""
    raw = json.loads(Path(path).read_text())["players"]
    return {p["name"]: PlayerProfile.from_dict(p) for p in raw}


@lru_cache(maxsize=1)
def _named_cache() -> dict[str, PlayerProfile]:
    if not PROFILES_JSON.exists():
        raise FileNotFoundError(f"named profiles file missing: {PROFILES_JSON} "
                                "(run scripts/calibrate_profiles.py)")
    return read_profiles(PROFILES_JSON)


def named_profiles() -> dict[str, PlayerProfile]:
    """The calibrated named profiles, by name (a fresh dict; profiles are immutable)."""
    return dict(_named_cache())


def get_profile(player: str | PlayerProfile) -> PlayerProfile:
    """A profile from a name of a named player, or the profile itself."""
    if isinstance(player, PlayerProfile):
        return player
    named = _named_cache()
    if not isinstance(player, str) or player not in named:
        raise ValueError(f"unknown player {player!r}; known players: {sorted(named)} "
                         "(or pass a PlayerProfile, e.g. from sample_population)")
    return named[player]


def profile_seeds(path: Path = SEEDS_JSON) -> dict[str, dict]:
    """The named players' starting points (handedness, style, character) by name."""
    return json.loads(Path(path).read_text())["players"]


def initial_profile(name: str, target: pd.Series, seed: dict) -> PlayerProfile:
    """A named player's starting profile: his seed, serve speeds at the 2011 medians with the
    real spread (IQR = 1.349 sd, within reason)."""
    kw = {**seed, "name": name}
    kw["first_serve_kmh"] = float(target["first_serve_kmh_median"])
    kw["second_serve_kmh"] = float(target["second_serve_kmh_median"])
    for key in ("first", "second"):
        iqr = float(target.get(f"{key}_serve_kmh_iqr", 11.0))
        kw[f"{key}_serve_kmh_sd"] = float(np.clip(iqr / 1.349, 5.0, 16.0))
    return PlayerProfile.from_dict(kw)


# Fields the population does not take from the named players: they are the tour's best
# returners (Hawk-Eye: 90 % of Djokovic's returns cross the net below 2.47 m, of the ATP's below
# 2.94 m), so the population keeps the default composure, the tour's.
_TOUR_DEFAULT_FIELDS = ("rushed_return_noise",)


def average_profile(gender: str = "men", name: str = "Average",
                    profiles: list[PlayerProfile] | None = None) -> PlayerProfile:
    """Field-wise mean of the named profiles (or of `profiles`) of one gender: the centre of
    the population (`_TOUR_DEFAULT_FIELDS` keep their defaults)."""
    if gender not in GENDERS:
        raise ValueError(f"gender must be one of {GENDERS}, got {gender!r}")
    pool = list(_named_cache().values()) if profiles is None else list(profiles)
    group = [p for p in pool if p.gender == gender]
    base = PlayerProfile(name=name, gender=gender)
    if not group:
        return base
    numeric = {f.name: float(np.mean([getattr(p, f.name) for p in group]))
               for f in fields(PlayerProfile)
               if f.name not in (*_IDENTITY_FIELDS, *_TOUR_DEFAULT_FIELDS)}
    return replace(base, **numeric)


# Style offsets applied to the average profile; values are additive unless named *_scale.
_STYLE_OFFSETS: dict[str, dict[str, float]] = {
    "all_court": {},
    "baseliner": {"aggression": -0.08, "rally_noise_deg": -0.04, "net_approach": -0.06,
                  "recovery_depth_m": 0.6},
    "serve_volleyer": {"net_approach": 0.35, "aggression": 0.08, "first_serve_kmh": 5.0,
                       "recovery_depth_m": -0.4, "slice_share": 0.15},
    "counter_puncher": {"aggression": -0.15, "rally_noise_deg": -0.06, "max_speed_mps": 0.3,
                        "recovery_depth_m": 1.0, "first_serve_kmh": -8.0},
    "big_server": {"first_serve_kmh": 12.0, "second_serve_kmh": 8.0, "contact_height_m": 0.15,
                   "serve_disguise_s": 0.03, "rally_noise_deg": 0.05, "max_speed_mps": -0.4,
                   "aggression": 0.1},
}
_STYLE_WEIGHTS = np.array([0.3, 0.3, 0.1, 0.15, 0.15])

# Clip ranges that keep sampled players physically plausible.
_CLIPS: dict[str, tuple[float, float]] = {
    "reaction_s": (0.15, 0.28), "max_speed_mps": (5.0, 7.0), "max_accel_mps2": (4.0, 6.0),
    "aggression": (0.0, 1.0), "net_approach": (0.0, 0.8), "slice_share": (0.0, 0.6),
    "contact_height_m": (2.5, 3.1), "recovery_depth_m": (0.0, 3.0),
    "serve_disguise_s": (-0.2, 0.4),
}


def sample_population(n: int, seed: int = 0, gender: str = "men",
                      prefix: str | None = None,
                      base: PlayerProfile | None = None) -> list[PlayerProfile]:
    """`n` anonymous players of varied styles around the average named player of `gender`
    (or around `base`).

    Styles: all-court, baseliner, serve-volleyer, counter-puncher, big server; about 15% are
    left-handed. Names are ``"<prefix> 000"`` ... (default prefix "Pop M"/"Pop W").
    Deterministic for a seed.
    """
    if int(n) != n or n <= 0:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    rng = np.random.default_rng(seed)
    base = average_profile(gender) if base is None else base
    prefix = prefix or ("Pop M" if gender == "men" else "Pop W")
    out = []
    for i in range(int(n)):
        style = STYLES[rng.choice(len(STYLES), p=_STYLE_WEIGHTS)]
        values = {f.name: getattr(base, f.name) for f in fields(PlayerProfile)
                  if f.name not in _IDENTITY_FIELDS}
        for key, off in _STYLE_OFFSETS[style].items():
            values[key] += off
        # Individual variation: a few percent on every speed/noise, a little on shares.
        for key in ("first_serve_kmh", "second_serve_kmh"):
            values[key] *= 1.0 + 0.03 * rng.standard_normal()
        for key in ("rally_speed_mps", "rally_noise_deg", "first_serve_noise_deg",
                    "second_serve_noise_deg", "return_noise_deg", "max_speed_mps",
                    "max_accel_mps2", "reaction_s"):
            values[key] *= 1.0 + 0.06 * rng.standard_normal()
        for key in ("aggression", "cross_court", "down_the_line", "forehand_preference"):
            values[key] += 0.06 * rng.standard_normal()
        values["serve_disguise_s"] += 0.02 * rng.standard_normal()
        values["second_serve_kmh"] = min(values["second_serve_kmh"],
                                         values["first_serve_kmh"] - 15.0)
        for key, (lo, hi) in _CLIPS.items():
            values[key] = float(np.clip(values[key], lo, hi))
        for key in ("cross_court", "down_the_line", "forehand_preference"):
            values[key] = float(np.clip(values[key], 0.05, 0.9))
        if values["cross_court"] + values["down_the_line"] > 0.95:
            values["down_the_line"] = 0.95 - values["cross_court"]
        hand = "left" if rng.random() < 0.15 else "right"
        out.append(PlayerProfile(name=f"{prefix} {i:03d}", gender=gender, handedness=hand,
                                 style=style, **values))
    return out
