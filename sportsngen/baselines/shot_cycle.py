"""Shot-cycle behaviour model (Vid2Player style): non-parametric decisions fitted on `RallyData`.

Each racket contact is described by a point state (`shot_cycle_table`): the hitter's and the
opponent's regions at the contact, the incoming ball's start and bounce regions and the speed
the hitter needed to reach the ball (five bins). Given the state the model draws

- the shot type ("stroke/spin") from the categorical distribution of the state's examples;
- the speed (m/s) from a 1-D KDE and the placement (first bounce, hitter's frame) from a 2-D KDE
  of the examples with that state and shot type; a ball into the net with the examples' net
  rate; the KDEs' bandwidths by leave-one-out cross-validation, samples below a tenth of the
  peak density redrawn (`shot_cycle_kde`);
- the recovery: a Bernoulli net approach, then the mode of a 2-D KDE of the recovery positions
  of the examples that made the same choice (given serve or rally shot, own region and the
  placement's lateral third).

Serves use the state (serve number, side). When a state has fewer than `min_examples` examples,
features are marginalised (dropped) in the order speed needed, incoming bounce, incoming start,
opponent position, then own position (`RALLY_LEVELS`); the first level with enough examples is
used. Models are opponent-specific for a (player, opponent) pair with at least
`min_opponent_shots` shots, general (all the player's shots) otherwise.

Everything random draws from the numpy Generator passed in, and fitting is deterministic, so a
seed fixes every decision.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from sportsngen.baselines.shot_cycle_kde import KDE, fit_kde
from sportsngen.baselines.shot_cycle_table import infer_handedness, shot_table
from sportsngen.data.tracking import RallyData
from sportsngen.tennis.court import THIRD_WIDTH_M, is_in_service_box, is_in_singles

MIN_EXAMPLES = 10
MIN_OPPONENT_SHOTS = 400
RALLY_STATE = ("own_region", "opp_region", "in_start_region", "in_bounce_region", "speed_bin")
MARGINALISATION_ORDER = ("speed_bin", "in_bounce_region", "in_start_region", "opp_region",
                         "own_region")
SERVE_STATE = ("serve_number", "side")
RECOVERY_STATE = ("is_serve", "own_region", "place_lateral")
PLACE_MIN_STD_M = 0.1
SPEED_MIN_STD_MPS = 0.5
RECOVERY_MIN_STD_M = 0.1
REACTION_S = 0.2   # not identifiable from tracks where players are always moving: a constant
RESULTS = ("in", "out", "net")
_NUMERIC = ("speed_mps", "place_x", "place_y", "recovery_x", "recovery_y", "net_approach")
_LABELS = ("shot_type", "stroke", "result", "error_kind")


def levels(features: tuple[str, ...], order: tuple[str, ...]) -> list[tuple[str, ...]]:
    """Feature sets from all of `features` down to none, dropping them in `order`."""
    keep = list(features)
    out = [tuple(keep)]
    for f in order:
        keep.remove(f)
        out.append(tuple(keep))
    return out


RALLY_LEVELS = levels(RALLY_STATE, MARGINALISATION_ORDER)
SERVE_LEVELS = levels(SERVE_STATE, ("side", "serve_number"))
RECOVERY_LEVELS = levels(RECOVERY_STATE, ("place_lateral", "own_region", "is_serve"))


@dataclass(frozen=True)
class ShotDecision:
    """A drawn shot. `place_xy` is the first bounce in the hitter's frame (for a ball into the
    net: where it was going). `result`: "in" or "out" by the placement, or "net". `type_level` /
    `place_level`: the marginalisation levels used (0 = full state)."""

    shot_type: str
    speed_mps: float
    place_xy: tuple[float, float]
    result: str
    error_kind: str
    type_level: int
    place_level: int

    @property
    def stroke(self) -> str:
        return self.shot_type.split("/")[0]

    @property
    def spin(self) -> str:
        return self.shot_type.split("/")[1]


@dataclass(frozen=True)
class Physique:
    """Movement limits read from a player's tracks: robust maxima (99.9th percentiles) of the
    frame-difference speed and acceleration, the reach (99th percentile of the
    centre-of-mass-to-ball distance at rally contacts), and the usual offset and height of a
    groundstroke contact (medians). Observed motion bounds the capacity from below."""

    max_speed_mps: float = 7.0
    max_accel_mps2: float = 6.0
    reach_m: float = 1.8
    contact_offset_m: float = 0.75
    contact_z_m: float = 1.0
    reaction_s: float = REACTION_S


def place_lateral(y_m) -> np.ndarray:
    """Lateral third 0/1/2 (hitter's frame: -y, centre, +y) of a placement; NaN -> 1."""
    y = np.asarray(y_m, dtype=float)
    half = THIRD_WIDTH_M / 2.0
    return np.where(y < -half, 0, np.where(y > half, 2, 1)).astype(np.int64)


def _groups(table: pd.DataFrame, lvls: list[tuple[str, ...]],
            extra: tuple[str, ...] = ()) -> list[dict]:
    """Row indices per key at each level (keys always tuples)."""
    out = []
    for feats in lvls:
        cols = list(feats) + list(extra)
        if not cols:
            out.append({(): np.arange(len(table))})
            continue
        g = table.groupby(cols, sort=False).indices
        out.append({(k if isinstance(k, tuple) else (k,)): v for k, v in g.items()})
    return out


@dataclass
class PlayerModel:
    """The fitted decisions of one player (against one opponent, or in general: `opponent`
    None). `table` holds the player's shots (`shot_cycle_table.shot_table` rows)."""

    player: str
    opponent: str | None
    table: pd.DataFrame
    handedness: str = "right"
    physique: Physique = field(default_factory=Physique)
    min_examples: int = MIN_EXAMPLES
    _cache: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        t = self.table.reset_index(drop=True).copy()
        t["place_lateral"] = place_lateral(t["place_y"])
        self.table = t
        serve = t["is_serve"].to_numpy(bool)
        self._rows = {"rally": np.flatnonzero(~serve), "serve": np.flatnonzero(serve)}
        self._index = {}
        for kind, lvls in (("rally", RALLY_LEVELS), ("serve", SERVE_LEVELS)):
            sub = t.iloc[self._rows[kind]]
            self._index[kind] = _groups(sub, lvls)
            self._index[kind + "_typed"] = _groups(sub, lvls, ("shot_type",))
        self._a = {c: t[c].to_numpy(float) for c in _NUMERIC}
        self._a.update({c: t[c].astype(str).to_numpy(object) for c in _LABELS})
        rec = np.flatnonzero(np.isfinite(t["recovery_x"].to_numpy(float)))
        self._rows["recovery"] = rec
        self._index["recovery"] = _groups(t.iloc[rec], RECOVERY_LEVELS)

    @property
    def strokes(self) -> set[str]:
        """The strokes this player's data has."""
        return set(self._a["stroke"])

    # -- lookups --------------------------------------------------------------------------------
    def lookup(self, kind: str, state: dict, shot_type: str | None = None,
               min_examples: int | None = None) -> tuple[int, np.ndarray]:
        """(level, rows of `table`) of the first marginalisation level whose cell has at least
        `min_examples` examples; the last level (no features) whatever its size. `kind`:
        "rally", "serve" or "recovery"; with `shot_type`, cells are per shot type too."""
        need = self.min_examples if min_examples is None else min_examples
        lvls = {"rally": RALLY_LEVELS, "serve": SERVE_LEVELS, "recovery": RECOVERY_LEVELS}[kind]
        index = self._index[kind + ("_typed" if shot_type is not None else "")]
        base = self._rows[kind]
        rows = np.array([], dtype=np.int64)
        for lvl, feats in enumerate(lvls):
            key = tuple(state[f] for f in feats) + ((shot_type,) if shot_type is not None
                                                    else ())
            rows = index[lvl].get(key, np.array([], dtype=np.int64))
            if len(rows) >= need:
                return lvl, base[rows]
        return len(lvls) - 1, base[rows]

    def _kde(self, key: tuple, rows: np.ndarray, cols: tuple[str, ...],
             min_std: float) -> KDE | None:
        if key not in self._cache:
            pts = np.column_stack([self._a[c][rows] for c in cols])
            pts = pts[np.isfinite(pts).all(axis=1)]
            self._cache[key] = fit_kde(pts, min_std) if len(pts) else None
        return self._cache[key]

    # -- decisions ------------------------------------------------------------------------------
    def shot_types(self, kind: str, state: dict,
                   allowed: tuple[str, ...] | None = None) -> tuple[int, np.ndarray, np.ndarray]:
        """(level, shot types, probabilities) for the state: the categorical distribution of
        the first level with enough examples. With `allowed` (strokes), only those types, from
        the first level (at or after that) that has any."""
        lvl, rows = self.lookup(kind, state)
        if len(rows) == 0:
            raise ValueError(f"{self.player} has no {kind} shots in the data")
        types = self._a["shot_type"][rows]
        if allowed is not None:
            ok = np.isin(self._a["stroke"][rows], allowed)
            if not ok.any():
                lvl = len(RALLY_LEVELS if kind == "rally" else SERVE_LEVELS) - 1
                rows = self._rows[kind]
                types = self._a["shot_type"][rows]
                ok = np.isin(self._a["stroke"][rows], allowed)
            if not ok.any():
                raise ValueError(f"{self.player} has no {kind} shots of strokes {allowed}")
            types = types[ok]
        names, counts = np.unique(types.astype(str), return_counts=True)
        return lvl, names, counts / counts.sum()

    def choose_shot(self, state: dict, rng: np.random.Generator, kind: str = "rally",
                    allowed: tuple[str, ...] | None = None) -> ShotDecision:
        """Draw a shot for `state` (keys `RALLY_STATE`, or `SERVE_STATE` with kind "serve").
        `allowed` restricts the shot types by stroke (e.g. volleys for a ball taken before the
        bounce)."""
        type_level, names, probs = self.shot_types(kind, state, allowed)
        shot_type = str(names[rng.choice(len(names), p=probs)])
        lvl, rows = self.lookup(kind, state, shot_type)
        typed = shot_type
        if len(rows) == 0:  # this type never seen at any level of this kind: any type
            lvl, rows = self.lookup(kind, state)
            typed = "*"
        feats = (RALLY_LEVELS if kind == "rally" else SERVE_LEVELS)[lvl]
        key = (kind, lvl, tuple(state[f] for f in feats), typed)
        speed = float(self._kde(key + ("speed",), rows, ("speed_mps",),
                                SPEED_MIN_STD_MPS).sample(rng)[0, 0])
        place_kde = self._kde(key + ("place",), rows, ("place_x", "place_y"), PLACE_MIN_STD_M)
        # The result (in / out / net) is drawn at the cell's rates; the placement from the
        # cell's KDE, with kernels on the examples of that result and draws that land the same.
        res = self._a["result"][rows]
        counts = np.array([np.sum(res == r) for r in RESULTS], dtype=float)
        if place_kde is None:
            counts[:2] = 0.0
        result = RESULTS[rng.choice(3, p=counts / counts.sum())] if counts.sum() > 0 else "net"
        if place_kde is None:
            place = np.array([6.0, 0.0])
        elif result == "net":
            place = place_kde.sample(rng)[0]
        else:
            landed = res[np.isfinite(self._a["place_x"][rows])]
            inside, want = self._in_test(kind, state), result == "in"
            place = place_kde.sample(rng, centres=landed == result,
                                     accept=lambda d: inside(d) == want)[0]
        err = rows[res != "in"]
        if len(err) == 0:
            err = np.flatnonzero(self._a["result"] != "in")
        forced = float(np.mean(self._a["error_kind"][err] == "forced")) if len(err) else 0.0
        error_kind = "forced" if rng.random() < forced else "unforced"
        return ShotDecision(shot_type, max(speed, 2.0), (float(place[0]), float(place[1])),
                            result, error_kind, type_level, lvl)

    @staticmethod
    def _in_test(kind: str, state: dict):
        """Placements (n, 2) in the hitter's frame -> landed in (the far service box of the
        state's side for a serve, the far singles court otherwise)."""
        if kind == "serve":
            return lambda d: np.asarray(is_in_service_box(d[:, 0], d[:, 1], -1, state["side"]))
        return lambda d: np.asarray(is_in_singles(d[:, 0], d[:, 1], 1))

    def recover(self, is_serve: bool, own_region: int, place_y_m: float,
                rng: np.random.Generator) -> tuple[bool, tuple[float, float]]:
        """(net approach, recovery position in the hitter's frame) after a shot placed at
        lateral `place_y_m`: Bernoulli approach, then the mode of the recovery KDE of the
        examples that made the same choice (the other choice's mode if none did)."""
        state = {"is_serve": bool(is_serve), "own_region": int(own_region),
                 "place_lateral": int(place_lateral(place_y_m))}
        lvl, rows = self.lookup("recovery", state)
        if len(rows) == 0:
            return False, (-13.0, 0.0)
        net = self._a["net_approach"][rows]
        approach = bool(rng.random() < float(np.mean(net)))
        chosen = rows[net == float(approach)]
        chosen = chosen if len(chosen) else rows
        key = ("recovery", lvl, tuple(state[f] for f in RECOVERY_LEVELS[lvl]), approach)
        if key + ("mode",) not in self._cache:
            kde = self._kde(key, chosen, ("recovery_x", "recovery_y"), RECOVERY_MIN_STD_M)
            self._cache[key + ("mode",)] = tuple(float(v) for v in kde.mode())
        return approach, self._cache[key + ("mode",)]


@dataclass(frozen=True)
class Stance:
    """Where a player stands at the serve (server) or waits for it (receiver), his frame, and
    (server only) the serve contact point (x, y, z)."""

    xy: tuple[float, float]
    contact_xyz: tuple[float, float, float] | None = None


@dataclass
class ShotCycleModel:
    """Player models keyed (player, opponent) and (player, None); stances per player keyed
    (role, serve_number, side)."""

    models: dict[tuple[str, str | None], PlayerModel]
    stances: dict[str, dict[tuple[str, int, str], Stance]]

    def player_model(self, player: str, opponent: str | None = None) -> PlayerModel:
        """The opponent-specific model where one was fitted, else the player's general one."""
        if (player, opponent) in self.models:
            return self.models[(player, opponent)]
        if (player, None) not in self.models:
            known = sorted({p for p, _ in self.models})
            raise KeyError(f"no shot-cycle model for {player!r}; players: {known}")
        return self.models[(player, None)]

    @property
    def players(self) -> list[str]:
        return sorted({p for p, _ in self.models})


def physique(data: RallyData, table: pd.DataFrame) -> dict[str, Physique]:
    """Per player `Physique` from the frames and the shot table."""
    f = data.frames[data.frames["object"] != "ball"].sort_values(["rally_id", "object", "frame"])
    out: dict[str, Physique] = {}
    dt = 1.0 / data.fps
    same = (f["rally_id"].to_numpy()[1:] == f["rally_id"].to_numpy()[:-1]) & \
        (f["object"].to_numpy()[1:] == f["object"].to_numpy()[:-1])
    v = np.diff(f[["x", "y"]].to_numpy(float), axis=0) / dt
    v[~same] = np.nan
    a = np.full(len(v), np.nan)
    a[1:] = np.where(same[1:] & same[:-1], np.hypot(*(v[1:] - v[:-1]).T) / dt, np.nan)
    speed = np.hypot(v[:, 0], v[:, 1])
    who = f["object"].to_numpy(object)[1:]
    rally = table[~table["is_serve"]]
    gap = np.hypot(rally["contact_x"] - rally["own_x"], rally["contact_y"] - rally["own_y"])
    ground = rally["stroke"].isin(("forehand", "backhand"))
    for p in table["hitter"].unique():
        mine = who == p
        g = gap[rally["hitter"] == p].dropna()
        z = rally.loc[ground & (rally["hitter"] == p), "contact_z"].dropna()
        out[str(p)] = Physique(
            max_speed_mps=float(np.nanpercentile(speed[mine], 99.9)),
            max_accel_mps2=float(np.nanpercentile(a[mine], 99.9)),
            reach_m=float(np.percentile(g, 99)) if len(g) else Physique.reach_m,
            contact_offset_m=float(np.median(g)) if len(g) else Physique.contact_offset_m,
            contact_z_m=float(np.median(z)) if len(z) else Physique.contact_z_m)
    return out


def _stances(table: pd.DataFrame) -> dict[str, dict[tuple[str, int, str], Stance]]:
    serves = table[table["is_serve"]]
    out: dict[str, dict] = {}
    for (p, n, side), g in serves.groupby(["hitter", "serve_number", "side"]):
        xy = fit_kde(g[["own_x", "own_y"]].to_numpy(float), RECOVERY_MIN_STD_M).mode()
        c = g[["contact_x", "contact_y", "contact_z"]].median().to_numpy(float)
        out.setdefault(str(p), {})[("server", int(n), str(side))] = Stance(
            (float(xy[0]), float(xy[1])), (float(c[0]), float(c[1]), float(c[2])))
    for (p, n, side), g in serves.groupby(["opponent", "serve_number", "side"]):
        pts = g[["opp_x", "opp_y"]].to_numpy(float)
        pts = pts[np.isfinite(pts).all(axis=1)]
        if len(pts):
            xy = fit_kde(pts, RECOVERY_MIN_STD_M).mode()
            out.setdefault(str(p), {})[("receiver", int(n), str(side))] = Stance(
                (float(xy[0]), float(xy[1])))
    return out


def fit_from_table(table: pd.DataFrame, physiques: dict[str, Physique] | None = None,
                   min_examples: int = MIN_EXAMPLES,
                   min_opponent_shots: int = MIN_OPPONENT_SHOTS) -> ShotCycleModel:
    """Fit on a shot table (`shot_cycle_table.shot_table`, or hand-built with its columns)."""
    hand = infer_handedness(table)
    physiques = physiques or {}
    models: dict[tuple[str, str | None], PlayerModel] = {}
    for p, g in table.groupby("hitter", sort=True):
        kw = {"handedness": hand.get(str(p), "right"),
              "physique": physiques.get(str(p), Physique()), "min_examples": min_examples}
        models[(str(p), None)] = PlayerModel(str(p), None, g, **kw)
        for o, go in g.groupby("opponent", sort=True):
            if len(go) >= min_opponent_shots:
                models[(str(p), str(o))] = PlayerModel(str(p), str(o), go, **kw)
    return ShotCycleModel(models, _stances(table))


def fit_shot_cycle(data: RallyData, min_examples: int = MIN_EXAMPLES,
                   min_opponent_shots: int = MIN_OPPONENT_SHOTS) -> ShotCycleModel:
    """Fit the shot-cycle model on any `RallyData` (its shots and the players' frames)."""
    table = shot_table(data)
    return fit_from_table(table, physique(data, table), min_examples, min_opponent_shots)
