"""The named players' 2011 calibration targets: derived from the 2011 slam point-by-point files
(`derive_targets`, `scripts/derive_player_stats.py`) and read back (`load_targets`).

The 2011 US Open and Wimbledon are the two events with first/second serve flags and rally
lengths; pooled, they give one row per player (serving, rally-length shares as server,
returning; fractions in [0, 1], speeds in km/h) in `data/slam2011_targets.csv`. The serving
figures are checked against the table in the shared data README. Like `synth.calibrate`, this
reads `eval`'s statistics: the targets are measured with the code that measures generated play.

Source: Jeff Sackmann / Tennis Abstract, tennis_slam_pointbypoint
(https://github.com/JeffSackmann/tennis_slam_pointbypoint), CC BY-NC-SA 4.0.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

from sportsngen.data.paths import SHARED_DATA_MISSING, slam_dir
from sportsngen.data.slam import parse_match_id, read_slam_events
from sportsngen.eval.stats import rally_distribution, return_stats, serve_stats, serve_stats_table

TARGETS_CSV = Path(__file__).with_name("data") / "slam2011_targets.csv"
RALLY_BINS = ("0", "1", "2", "3-4", "5-8", "9+")
EVENTS = ("2011-usopen", "2011-wimbledon")
PLAYERS = ("Roger Federer", "Rafael Nadal", "Novak Djokovic", "Andy Murray", "John Isner",
           "Serena Williams", "Maria Sharapova")
SOURCE = ("Source: Jeff Sackmann / Tennis Abstract, tennis_slam_pointbypoint "
          "(https://github.com/JeffSackmann/tennis_slam_pointbypoint), CC BY-NC-SA 4.0. "
          "Derived by scripts/derive_player_stats.py")
# The shared data README's table (%, km/h): 1st in, aces, DF, 1st won, 2nd won, median speeds.
README_TABLE = {
    "Roger Federer": (66.4, 11.1, 1.6, 78.6, 59.8, 189, 156),
    "Rafael Nadal": (70.2, 5.9, 1.9, 73.5, 53.8, 181, 140),
    "Novak Djokovic": (66.2, 7.4, 2.2, 75.1, 56.3, 189, 146),
    "Serena Williams": (59.0, 14.9, 3.0, 78.0, 50.8, 168, 135),
}
README_COLS = ("first_serve_in", "ace", "double_fault", "first_serve_won", "second_serve_won",
               "first_serve_kmh_median", "second_serve_kmh_median")


def load_targets(path: Path = TARGETS_CSV) -> pd.DataFrame:
    """2011 targets, one row per player (index = name), fractions and km/h."""
    if not Path(path).exists():
        raise FileNotFoundError(f"targets file {path} missing: run "
                                "scripts/derive_player_stats.py first")
    df = pd.read_csv(path, comment="#")
    key = next(c for c in ("player", "server", "name", "Unnamed: 0") if c in df.columns)
    df = df.rename(columns=dict(zip(("rally_0", "rally_1", "rally_2", "rally_3_4", "rally_5_8",
                                     "rally_9plus"), RALLY_BINS)))
    return df.set_index(key)


def player_targets(points: pd.DataFrame, players: tuple[str, ...] = PLAYERS) -> pd.DataFrame:
    """One row per player: serving, rally-length shares (as server) and returning figures."""
    known = set(points["server"])
    unknown = [p for p in players if p not in known]
    if unknown:
        raise ValueError(f"players not found in the points table: {unknown}")
    serve = serve_stats(points).loc[list(players)]
    serve = serve.rename(columns={"n_points": "n_service_points"})
    rally = rally_distribution(points).loc[list(players)]
    rally.columns = ["rally_" + c.replace("-", "_").replace("+", "plus") for c in rally.columns]
    ret = return_stats(points).loc[list(players)]
    genders = points.drop_duplicates("server").set_index("server")["match_id"]
    out = pd.concat([serve, rally, ret], axis=1)
    out.insert(0, "gender", [parse_match_id(genders[p])[3] for p in players])
    out.insert(1, "events", "+".join(sorted(points["event"].unique())))
    out.index.name = "player"
    return out


def check_readme(targets: pd.DataFrame) -> float:
    """Largest deviation from the README table, printing the comparison (pp and km/h)."""
    worst = 0.0
    print("\nREADME check (ours / README):")
    for name, want in README_TABLE.items():
        got = [targets.loc[name, c] * (100.0 if "kmh" not in c else 1.0) for c in README_COLS]
        cells = [f"{g:.1f}/{w}" for g, w in zip(got, want)]
        print(f"  {name:<16} " + "  ".join(cells))
        # tolerance 0.1 pp on the shares, 1 km/h on the speeds, scaled to one common number
        worst = max(worst, *(abs(g - w) / (0.1 if "kmh" not in c else 1.0)
                             for g, w, c in zip(got, want, README_COLS)))
    return worst


def derive_targets(out: Path = TARGETS_CSV) -> bool:
    """The targets derived from the shared slam files (exits where they are missing), printed
    and written to `out` (read it with `load_targets`) -> whether the README's serving table
    is reproduced (within 0.1 pp / 1 km/h)."""
    if slam_dir() is None:
        raise SystemExit(SHARED_DATA_MISSING)
    points = read_slam_events(events=list(EVENTS))
    targets = player_targets(points)
    print(serve_stats_table(serve_stats(points).loc[list(PLAYERS)]))
    print(targets[["n_return_points", "return_points_won", "return_first_won",
                   "return_second_won"]].round(3).to_string())
    worst = check_readme(targets)
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "w", encoding="utf-8") as f:
        f.write(f"# {SOURCE}. Events pooled: {', '.join(EVENTS)}. Fractions in [0, 1]; "
                "speeds km/h (median, IQR); rally_* are shares of service points by rally "
                "length (0 = double fault, 1 = ace or unreturned serve).\n")
        targets.round(4).to_csv(f)
    print(f"\nwrote {out}")
    if worst > 1.0:
        print(f"README table NOT reproduced (worst deviation {worst:.2f} x tolerance)",
              file=sys.stderr)
        return False
    print("README table reproduced (within 0.1 pp / 1 km/h)")
    return True
