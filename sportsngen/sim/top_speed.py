"""Each player's top running speed, read from his record, for the rollouts' kinematic limit.

The generator's players run no faster than their profile's top speed (`synth.players.Mover`:
6.0 m/s for Sharapova, 6.3 for Serena Williams, 6.8-7.0 for the named men), and in its tracks
no frame of theirs is faster. The rollouts' players were bounded by the acceleration limit
alone (`sim.kinematics`) and by the chase rule's 7 m/s (`sim.constraints.KeepChasing`, which
raises a late player's speed toward that): the women ran up to 7.0-7.2 m/s (the 99.9th
percentile of their frame speeds; the truth's 6.0 and 6.3) and answered the balls that asked
5-8 m/s of them 0.74-0.86 of the time against the truth's 0.16-0.77 (docs/evaluation.md,
fifty-fourth part). A player's top speed is physics the model need not learn.

`TopSpeeds` holds a speed per player: the `QUANTILE` of his frame-to-frame horizontal speeds
over the recorded rallies (a high quantile, not the maximum, so that a tracking glitch does not
set it), with a pooled row for players without enough frames. Pure numpy and pandas.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

QUANTILE = 0.999
MIN_FRAMES = 5000         # a player's frames for his own row (fewer: the pooled one)


@dataclass
class TopSpeeds:
    """Per player his top speed (m/s); `pooled` for players without a row."""

    pooled_mps: float
    players_mps: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for who, v in [("pooled", self.pooled_mps), *self.players_mps.items()]:
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"top speed of {who} must be positive, got {v}")

    def speeds_mps(self, players) -> np.ndarray:
        """The top speeds of the players named in `players` (any shape, the result's)."""
        names = np.asarray(players, dtype=object)
        flat = [self.players_mps.get(str(p), self.pooled_mps) for p in names.ravel()]
        return np.asarray(flat, dtype=float).reshape(names.shape)

    def to_dict(self) -> dict:
        return {"pooled_mps": float(self.pooled_mps),
                "players_mps": {k: float(v) for k, v in self.players_mps.items()}}

    @staticmethod
    def from_dict(d: dict) -> TopSpeeds:
        return TopSpeeds(float(d["pooled_mps"]),
                         {k: float(v) for k, v in d["players_mps"].items()})


def player_speeds(frames: pd.DataFrame, fps: float) -> pd.DataFrame:
    """Every player's frame-to-frame horizontal speed in `frames` (a `RallyData.frames`
    table) -> columns player, speed_mps (the ball and each rally's first frame left out)."""
    f = frames[frames["object"] != "ball"].sort_values(["rally_id", "object", "frame"])
    g = f.groupby(["rally_id", "object"], sort=False)
    step = np.hypot(g["x"].diff(), g["y"].diff()) / g["frame"].diff()
    out = pd.DataFrame({"player": f["object"].to_numpy(str), "speed_mps": (step * fps).to_numpy()})
    return out.dropna(ignore_index=True)


def fit_top_speeds(speeds: pd.DataFrame, quantile: float = QUANTILE,
                   min_frames: int = MIN_FRAMES) -> TopSpeeds:
    """`TopSpeeds` from `player_speeds`' rows: each player with at least `min_frames` frames
    his own `quantile` of them, the pooled row that of all."""
    if not 0.5 <= quantile <= 1.0:
        raise ValueError(f"quantile must lie in [0.5, 1], got {quantile}")
    if speeds.empty:
        raise ValueError("no player frames to read the speeds from")
    players = {str(name): float(g.quantile(quantile))
               for name, g in speeds.groupby("player")["speed_mps"] if len(g) >= min_frames}
    return TopSpeeds(float(speeds["speed_mps"].quantile(quantile)), players)


def top_speeds_from_data(parts: list, quantile: float = QUANTILE,
                         min_frames: int = MIN_FRAMES) -> tuple[TopSpeeds, pd.DataFrame]:
    """Fit `TopSpeeds` on recorded rallies (`RallyData` parts: a model file's training split
    and more of its players' play) -> (table, the frames' speeds read)."""
    if not parts:
        raise ValueError("no rallies to read the speeds from")
    speeds = pd.concat([player_speeds(d.frames, d.fps) for d in parts], ignore_index=True)
    return fit_top_speeds(speeds, quantile, min_frames), speeds
