"""The bundled serve models of the Markov engine, derived from the real 2011 Grand Slam data
(`scripts/derive_serve_models.py`; read back by `serve_model.bundled_serve_models`).

One `ServeModel` (serve rates, serve speeds, rally-length distributions, return rate) per
player with at least `MIN_SERVE_POINTS` service points over the 2011 US Open and Wimbledon, and
one pooled model per gender (every server of that gender together: the stand-in for a player
without figures). Derived figures only; the raw files stay in ../shared/data. Source: Jeff
Sackmann / Tennis Abstract, tennis_slam_pointbypoint, CC BY-NC-SA 4.0.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from sportsngen.baselines.serve_model import BUNDLED_PATH, ServeModel, pooled_serve_model
from sportsngen.data.paths import SHARED_DATA_MISSING, slam_dir
from sportsngen.data.slam import parse_match_id, read_slam_events

MIN_SERVE_POINTS = 300


def _rounded(model: ServeModel) -> dict:
    """Scalars rounded for a readable file; distributions kept exact so they sum to one."""
    m = dataclasses.asdict(model)
    return {k: (round(v, 5) if isinstance(v, float) else v) for k, v in m.items()}


def derive_serve_models(out: Path = BUNDLED_PATH) -> dict:
    """The serve models derived from the shared slam files (exits where they are missing),
    written to `out` -> the file's contents."""
    folder = slam_dir()
    if folder is None:
        raise SystemExit(SHARED_DATA_MISSING)
    points = read_slam_events(folder, events=["2011-usopen", "2011-wimbledon"])
    counts = points.loc[points["first_serve_in"].notna(), "server"].value_counts()
    players = sorted(counts[counts >= MIN_SERVE_POINTS].index)
    models = {name: _rounded(ServeModel.from_points(points, name)) for name in players}
    gender = points["match_id"].map(lambda m: parse_match_id(m)[3])
    pooled = {g: _rounded(pooled_serve_model(points[gender == g])) for g in ("men", "women")}
    doc = {
        "source": "Jeff Sackmann / Tennis Abstract, tennis_slam_pointbypoint (CC BY-NC-SA 4.0);"
                  " 2011 US Open and Wimbledon; derived by scripts/derive_serve_models.py",
        "min_serve_points": MIN_SERVE_POINTS,
        "players": models,
        "pooled": pooled,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=1, allow_nan=True))
    print(f"wrote {len(models)} serve models to {out}")
    return doc
