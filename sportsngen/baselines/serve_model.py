"""Serve-level point model of a tennis match: one `ServeModel` per player, and a match engine.

Refines the i.i.d. point of `sportsngen.baselines.markov` into first / second serve, ace,
double fault, serve speed and rally length. `ServeModel.from_points` estimates a player's
rates from a points table (`sportsngen.data.points`); `ServeModel.adjusted_against` and
`matchup_point_probability` apply the server-versus-receiver adjustment of Barnett & Clarke
(2005, "Combining player statistics to predict outcomes of tennis matches").
`simulate_match_points` plays a whole match serve by serve through `MatchState` and writes the
same points table as the real data, so `sportsngen.eval.stats` compares it with real matches
directly. `ServeModel.serve_points_won` (after the adjustment) is the `pa` / `pb` the exact
formulas of `sportsngen.baselines.markov` take.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, fields, replace
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd

from sportsngen.baselines.markov import _check_p
from sportsngen.data.points import as_points_table
from sportsngen.data.tracking import SURFACES
from sportsngen.tennis.scoring import MatchFormat, MatchState, point_label

BUNDLED_PATH = Path(__file__).resolve().parent / "data" / "serve_models_2011.json"
_IQR_TO_SD = 1.349  # a normal distribution's inter-quartile range is 1.349 sigma
_SPEED_RANGE_KMH = (40.0, 265.0)  # keep sampled speeds physical (fastest recorded ~263)


@dataclass(frozen=True)
class ServeModel:
    """How one player serves, as rates conditional on the serve being reached.

    - `first_serve_in`: P(first serve in); `ace_first`: P(ace | first serve in);
      `first_serve_won`: P(server wins | first serve in), aces included.
    - `double_fault`: P(double fault | a second serve is needed); `ace_second`: P(ace | second
      serve in); `second_serve_won`: P(server wins | a second serve is needed), double faults
      counting as lost (the usual "second serve points won").
    - speeds in km/h (report units, as in the data): median and inter-quartile range of first
      and second serves that landed in; NaN where unknown.
    - `rally_won_pmf` / `rally_lost_pmf`: distribution of rally length (slam definition, index
      = length) on points without an ace or double fault that the server won / lost; None when
      the data has no rally lengths.
    - `return_won`: share of return points this player won; `tour_return_won`: the same over
      every player of the table the model came from (the reference for the Barnett-Clarke
      adjustment). NaN when unknown, which disables the adjustment.
    """

    first_serve_in: float
    ace_first: float
    first_serve_won: float
    double_fault: float
    ace_second: float
    second_serve_won: float
    first_serve_kmh_median: float = math.nan
    first_serve_kmh_iqr: float = math.nan
    second_serve_kmh_median: float = math.nan
    second_serve_kmh_iqr: float = math.nan
    rally_won_pmf: tuple[float, ...] | None = None
    rally_lost_pmf: tuple[float, ...] | None = None
    return_won: float = math.nan
    tour_return_won: float = math.nan

    def __post_init__(self) -> None:
        for name in ("first_serve_in", "ace_first", "first_serve_won", "double_fault",
                     "ace_second", "second_serve_won"):
            _check_p(getattr(self, name), name)
        if self.ace_first > self.first_serve_won:
            raise ValueError(f"ace_first {self.ace_first} exceeds first_serve_won "
                             f"{self.first_serve_won}: aces are won points")
        lo2, hi2 = (1.0 - self.double_fault) * self.ace_second, 1.0 - self.double_fault
        if not lo2 - 1e-12 <= self.second_serve_won <= hi2 + 1e-12:
            raise ValueError(f"second_serve_won {self.second_serve_won} must lie in [{lo2:.4f}, "
                             f"{hi2:.4f}]: second-serve aces are won, double faults lost")

    @property
    def serve_points_won(self) -> float:
        """P(server wins a service point), from the serve rates."""
        return (self.first_serve_in * self.first_serve_won
                + (1.0 - self.first_serve_in) * self.second_serve_won)

    @classmethod
    def from_points(cls, points: pd.DataFrame, player: str) -> ServeModel:
        """Estimate the model of `player` from a points table (`sportsngen.data.points`).

        Uses the points he served that carry the serve flags (first_serve_in, ace,
        double_fault not NA). Raises ValueError when there are none, or no first serve in,
        or no second serve.
        """
        pts = as_points_table(points)
        mine = pts[(pts["server"] == player) & pts["first_serve_in"].notna()
                   & pts["ace"].notna() & pts["double_fault"].notna()]
        fsi = mine["first_serve_in"].to_numpy(bool)
        ace = mine["ace"].to_numpy(bool)
        df = mine["double_fault"].to_numpy(bool)
        won = (mine["winner"] == player).to_numpy(bool)
        if fsi.sum() == 0 or (~fsi).sum() == 0:
            raise ValueError(f"player {player!r}: need served points with serve flags, both "
                             f"first serves in and second serves; got {fsi.sum()} first serves "
                             f"in and {(~fsi).sum()} second serves")
        second_in = ~fsi & ~df
        kmh = mine["serve_kmh"].to_numpy(float)
        med1, iqr1 = _median_iqr(kmh[fsi])
        med2, iqr2 = _median_iqr(kmh[second_in])
        rally = mine["rally"].astype("Float64").to_numpy(float, na_value=np.nan)
        rallied = ~ace & ~df & ~np.isnan(rally)
        won_pmf = _pmf(rally[rallied & won]) if rallied.any() else None
        lost_pmf = _pmf(rally[rallied & ~won]) if rallied.any() else None
        returns = pts[pts["receiver"] == player]
        return cls(
            first_serve_in=float(fsi.mean()), ace_first=float(ace[fsi].mean()),
            first_serve_won=float(won[fsi].mean()), double_fault=float(df[~fsi].mean()),
            ace_second=float(ace[second_in].mean()) if second_in.any() else 0.0,
            second_serve_won=float(won[~fsi].mean()),
            first_serve_kmh_median=med1, first_serve_kmh_iqr=iqr1,
            second_serve_kmh_median=med2, second_serve_kmh_iqr=iqr2,
            rally_won_pmf=won_pmf, rally_lost_pmf=lost_pmf,
            return_won=float((returns["winner"] == player).mean()) if len(returns) else math.nan,
            tour_return_won=float((pts["winner"] != pts["server"]).mean()),
        )

    def adjusted_against(self, receiver: ServeModel) -> ServeModel:
        """This server's model against `receiver` (Barnett & Clarke 2005).

        The serve-points-won rate moves by -(g_j - g_av): down by as much as the receiver
        wins more return points than average. Both first- and second-serve won rates move by
        that amount (clipped so aces and double faults keep their rates), so the overall rate
        moves by exactly that amount unless clipped. A receiver with unknown return rates
        leaves the model unchanged.
        """
        delta = receiver.tour_return_won - receiver.return_won
        if math.isnan(delta):
            return self
        lo2 = (1.0 - self.double_fault) * self.ace_second
        return replace(
            self,
            first_serve_won=float(np.clip(self.first_serve_won + delta, self.ace_first, 1.0)),
            second_serve_won=float(np.clip(self.second_serve_won + delta, lo2,
                                           1.0 - self.double_fault)),
        )


def pooled_serve_model(points: pd.DataFrame) -> ServeModel:
    """One model for every server of a points table together (the "average server"), for a
    player with no figures of his own. Its return rate is unknown (NaN), so it adjusts no
    server it plays against; a known receiver still adjusts it."""
    pts = as_points_table(points)
    won = (pts["winner"] == pts["server"]).to_numpy(bool)
    pooled = pts.assign(server="pooled", receiver="opponent",
                        winner=np.where(won, "pooled", "opponent"))
    return ServeModel.from_points(pooled, "pooled")


def _from_dict(params: dict) -> ServeModel:
    names = {f.name for f in fields(ServeModel)}
    kw = {k: (tuple(v) if isinstance(v, list) else v) for k, v in params.items() if k in names}
    return ServeModel(**{k: (math.nan if v is None else v) for k, v in kw.items()})


@lru_cache(maxsize=1)
def _bundled() -> tuple[dict[str, ServeModel], dict[str, ServeModel]]:
    doc = json.loads(BUNDLED_PATH.read_text())
    return ({p: _from_dict(v) for p, v in doc["players"].items()},
            {g: _from_dict(v) for g, v in doc.get("pooled", {}).items()})


def bundled_serve_models() -> dict[str, ServeModel]:
    """Serve models of every player with enough 2011 slam service points (name -> model),
    derived by `scripts/derive_serve_models.py` and shipped with the package."""
    return dict(_bundled()[0])


def serve_model(player: str) -> ServeModel:
    """The bundled serve model of `player`; ValueError listing the known players otherwise."""
    models = _bundled()[0]
    if player not in models:
        raise ValueError(f"no serve model for player {player!r}; known players: "
                         f"{', '.join(sorted(models))}")
    return models[player]


def serve_model_or_pooled(player: str, gender: str = "men") -> tuple[ServeModel, bool]:
    """(`player`'s bundled model, True), or (the pooled 2011 model of `gender`, False)."""
    models, pooled = _bundled()
    if player in models:
        return models[player], True
    if gender not in pooled:
        raise ValueError(f"gender must be one of {sorted(pooled)}, got {gender!r}")
    return pooled[gender], False


def _median_iqr(x: np.ndarray) -> tuple[float, float]:
    x = x[~np.isnan(x)]
    if len(x) == 0:
        return math.nan, math.nan
    q25, q50, q75 = np.percentile(x, [25, 50, 75])
    return float(q50), float(q75 - q25)


def _pmf(lengths: np.ndarray) -> tuple[float, ...] | None:
    if len(lengths) == 0:
        return None
    counts = np.bincount(lengths.astype(int))
    return tuple(float(c) for c in counts / counts.sum())


def matchup_point_probability(points: pd.DataFrame, server: str, receiver: str) -> float:
    """P(`server` wins a point on his serve against `receiver`), Barnett & Clarke (2005).

    f_sr = f_t + (f_s - f_av) - (g_r - g_av), with f_s the server's share of serve points
    won, g_r the receiver's share of return points won, f_av the table's share of serve
    points won by servers and g_av = 1 - f_av; the tournament average f_t is taken as f_av,
    so f_sr = f_s - g_r + 1 - f_av. Clipped to [0, 1].
    """
    pts = as_points_table(points)
    served = pts[pts["server"] == server]
    returned = pts[pts["receiver"] == receiver]
    if len(served) == 0:
        raise ValueError(f"server {server!r} serves no point in the table")
    if len(returned) == 0:
        raise ValueError(f"receiver {receiver!r} receives no point in the table")
    f_s = float((served["winner"] == server).mean())
    g_r = float((returned["winner"] == receiver).mean())
    f_av = float((pts["winner"] == pts["server"]).mean())
    return float(np.clip(f_s - g_r + 1.0 - f_av, 0.0, 1.0))


def _sample_speed(rng: np.random.Generator, median: float, iqr: float) -> float:
    if math.isnan(median):
        return math.nan
    sd = 0.0 if math.isnan(iqr) else iqr / _IQR_TO_SD
    return float(np.clip(rng.normal(median, sd), *_SPEED_RANGE_KMH))


def _sample_rally(rng: np.random.Generator, pmf: tuple[float, ...] | None) -> float:
    if pmf is None:
        return math.nan
    return float(rng.choice(len(pmf), p=np.asarray(pmf)))


def _play_point(m: ServeModel, rng: np.random.Generator) -> dict:
    """One service point of server model `m` (already adjusted to the receiver)."""
    if rng.random() < m.first_serve_in:
        serve_number, first_in, dfault = 1, True, False
        ace = rng.random() < m.ace_first
        p_rally = (m.first_serve_won - m.ace_first) / (1.0 - m.ace_first) if not ace else 1.0
        kmh = _sample_speed(rng, m.first_serve_kmh_median, m.first_serve_kmh_iqr)
    else:
        serve_number, first_in = 2, False
        dfault = rng.random() < m.double_fault
        ace = not dfault and rng.random() < m.ace_second
        p_in = m.second_serve_won / (1.0 - m.double_fault) if m.double_fault < 1.0 else 0.0
        p_rally = (p_in - m.ace_second) / (1.0 - m.ace_second) if m.ace_second < 1.0 else 1.0
        kmh = math.nan if dfault else _sample_speed(rng, m.second_serve_kmh_median,
                                                    m.second_serve_kmh_iqr)
    if dfault:
        won, rally = False, 0.0
    elif ace:
        won, rally = True, 1.0
    else:
        won = rng.random() < p_rally
        rally = _sample_rally(rng, m.rally_won_pmf if won else m.rally_lost_pmf)
    return {"serve_number": serve_number, "first_serve_in": first_in, "ace": bool(ace),
            "double_fault": bool(dfault), "serve_kmh": kmh, "rally": rally, "won": bool(won)}


def _score_strings(state: MatchState) -> tuple[str, str]:
    """Point score before the point, from the server's side ("AD", "40", ... or tie-break)."""
    a, b = state.points[state.server], state.points[state.receiver]
    return point_label(a, b, state.in_tiebreak), point_label(b, a, state.in_tiebreak)


def simulate_match_points(model_a: ServeModel, model_b: ServeModel,
                          names: tuple[str, str] = ("player_a", "player_b"),
                          fmt: MatchFormat | None = None, surface: str = "hard",
                          seed: int = 0, match_id: str = "sim-0", *, event: str = "",
                          first_server: int = 0,
                          opponent_adjust: bool = True) -> tuple[pd.DataFrame, MatchState]:
    """Play a whole match serve by serve; return (points table, final `MatchState`).

    Player 0 is `model_a` / `names[0]`. Each point: first serve in or not, ace, double fault,
    winner of the rally, serve speed (normal with the player's median and IQR, the speed of the
    serve that started the rally, NaN on a double fault as in the real data) and rally length
    (from the player's won/lost distribution; NA when the model has none). With
    `opponent_adjust`, each server's model is first adjusted to the receiver (Barnett &
    Clarke). Deterministic for a seed.
    """
    if surface not in SURFACES:
        raise ValueError(f"surface must be one of {SURFACES}, got {surface!r}")
    if len(names) != 2 or names[0] == names[1]:
        raise ValueError(f"names must be two different player names, got {names!r}")
    rng = np.random.default_rng(seed)
    models = (model_a, model_b)
    if opponent_adjust:
        models = (model_a.adjusted_against(model_b), model_b.adjusted_against(model_a))
    state = MatchState.new(MatchFormat() if fmt is None else fmt, first_server=first_server)
    rows = []
    while not state.is_over:
        srv, rcv = state.server, state.receiver
        shot = _play_point(models[srv], rng)
        won = shot.pop("won")
        server_score, receiver_score = _score_strings(state)
        rows.append({
            "match_id": match_id, "point": len(rows) + 1, "server": names[srv],
            "receiver": names[rcv], "winner": names[srv] if won else names[rcv],
            "surface": surface, "event": event, **shot, "set_no": state.set_no,
            "server_games": state.games[srv], "receiver_games": state.games[rcv],
            "server_score": server_score, "receiver_score": receiver_score,
        })
        state = state.point_won(srv if won else rcv)
    table = pd.DataFrame(rows)
    table["rally"] = table["rally"].astype("Float64").round().astype("Int64")
    return as_points_table(table), state
