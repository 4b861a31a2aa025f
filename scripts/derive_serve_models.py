"""Derive the bundled serve models of the Markov engine from the real 2011 Grand Slam data.

Writes `sportsngen/baselines/data/serve_models_2011.json`: one `ServeModel` (serve rates, serve
speeds, rally-length distributions, return rate) per player with at least MIN_SERVE_POINTS
service points over the 2011 US Open and Wimbledon. Derived figures only; the raw files stay in
../shared/data. Source: Jeff Sackmann / Tennis Abstract, tennis_slam_pointbypoint,
CC BY-NC-SA 4.0.

    python scripts/derive_serve_models.py
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from sportsngen.baselines.serve_model import ServeModel
from sportsngen.data.paths import SHARED_DATA_MISSING, slam_dir
from sportsngen.data.slam import read_slam_events

MIN_SERVE_POINTS = 300
OUT = Path(__file__).resolve().parents[1] / "sportsngen/baselines/data/serve_models_2011.json"


def main() -> None:
    folder = slam_dir()
    if folder is None:
        raise SystemExit(SHARED_DATA_MISSING)
    points = read_slam_events(folder, events=["2011-usopen", "2011-wimbledon"])
    counts = points.loc[points["first_serve_in"].notna(), "server"].value_counts()
    players = sorted(counts[counts >= MIN_SERVE_POINTS].index)
    models = {}
    for name in players:
        m = dataclasses.asdict(ServeModel.from_points(points, name))
        # Scalars rounded for a readable file; distributions kept exact so they sum to one.
        m = {k: (round(v, 5) if isinstance(v, float) else v) for k, v in m.items()}
        models[name] = m
    doc = {
        "source": "Jeff Sackmann / Tennis Abstract, tennis_slam_pointbypoint (CC BY-NC-SA 4.0);"
                  " 2011 US Open and Wimbledon; derived by scripts/derive_serve_models.py",
        "min_serve_points": MIN_SERVE_POINTS,
        "players": models,
    }
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(doc, indent=1, allow_nan=True))
    print(f"wrote {len(models)} serve models to {OUT}")


if __name__ == "__main__":
    main()
