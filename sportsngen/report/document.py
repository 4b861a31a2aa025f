"""The match report as one self-contained HTML file: a JSON document and the viewer around it.

`match_document` gathers what a report shows (players, score line, statistics beside the 2011
figures, the win-probability timeline with importance and key moments, optional rallies and
what-if results) into one plain dict; `write_report` puts it, the stylesheet and the viewer's
script (`assets/`) inline into `assets/report.html`. Nothing is fetched when the file is
opened: it works offline and from any folder.
"""

from __future__ import annotations

import html
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from sportsngen.report.figures import SOURCE_2011, STAT_ROWS, match_figures, real_2011_figures
from sportsngen.report.live import ServeOdds, describe_point, key_moments
from sportsngen.tennis import court

ASSETS = Path(__file__).resolve().parent / "assets"
# The court the rally views draw (metres, the project frame): one source, `tennis.court`.
COURT = {"baseline_x": court.BASELINE_X_M, "service_x": court.SERVICE_LINE_X_M,
         "singles_y": court.SINGLES_HALF_WIDTH_M, "doubles_y": court.DOUBLES_HALF_WIDTH_M,
         "net_post_y": court.NET_POST_Y_M, "net_centre_z": court.NET_HEIGHT_CENTRE_M}
N_KEY_MOMENTS = 6
_PROB_DIGITS = 4


def _plain(obj):
    """JSON-ready copy: numpy scalars and arrays to Python, NaN / NA to None."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray, pd.Series)):
        return [_plain(v) for v in obj]
    if obj is None or obj is pd.NA:
        return None
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return None if math.isnan(obj) else float(obj)
    return obj


def _points_block(tl: pd.DataFrame, rallies_of_point: dict[int, list[int]] | None) -> dict:
    """The timeline as columns (compact), probabilities rounded."""
    block = {c: tl[c].tolist() for c in tl.columns}
    for c in ("p_before", "p_if_won", "p_if_lost", "importance", "p_after", "swing"):
        block[c] = np.round(tl[c].to_numpy(float), _PROB_DIGITS).tolist()
    if rallies_of_point is not None:
        block["rallies"] = [rallies_of_point.get(int(p), []) for p in tl["point"]]
    return block


def match_document(*, players: tuple[str, str], title: str, subtitle: str, score_line: str,
                   points: pd.DataFrame, tl: pd.DataFrame, odds: ServeOdds, kind: str,
                   surface: str = "hard",
                   notes: list[str] | None = None, attribution: str = "",
                   rallies: dict | None = None, rallies_of_point: dict | None = None,
                   fps: float = 25.0, whatif: list[dict] | None = None,
                   n_key_moments: int = N_KEY_MOMENTS) -> dict:
    """Everything the viewer shows, as a JSON-ready dict. `kind`: "simulated" or "recorded";
    `points` is the match's points table (for the statistics), `tl` its timeline
    (`sportsngen.report.live.timeline`)."""
    if len(points) != len(tl):
        raise ValueError(f"points table has {len(points)} rows but the timeline {len(tl)}")
    moments = key_moments(tl, n_key_moments)
    real = {p: real_2011_figures(p) for p in players}
    doc = {
        "version": 1, "kind": kind, "title": title, "subtitle": subtitle,
        "score_line": score_line, "players": list(players), "fps": float(fps),
        "surface": surface, "court": COURT,
        "model": ("Win probability before each point: the serve-level Markov model (exact), "
                  + odds.describe(players) + "."),
        "notes": list(notes or []),
        "attribution": attribution,
        "points": _points_block(tl, rallies_of_point),
        "key_moments": [{"i": i, "text": describe_point(tl.iloc[i], players)} for i in moments],
        "stats": {"rows": [list(r) for r in STAT_ROWS], "match": match_figures(points, players),
                  "real2011": real,
                  "real_source": SOURCE_2011 if any(v is not None for v in real.values())
                  else ""},
        "rallies": rallies,
        "whatif": whatif or [],
    }
    return _plain(doc)


def render_html(doc: dict) -> str:
    """The report page: template, stylesheet, viewer script and the document, all inline."""
    page = (ASSETS / "report.html").read_text(encoding="utf-8")
    data = json.dumps(doc, separators=(",", ":"), allow_nan=False)
    data = data.replace("</", "<\\/")  # a "</script>" inside a string must not end the block
    parts = {
        "{{TITLE}}": html.escape(str(doc.get("title", "match report"))),
        "{{CSS}}": (ASSETS / "report.css").read_text(encoding="utf-8"),
        "{{JS}}": (ASSETS / "report.js").read_text(encoding="utf-8"),
        "{{DATA}}": data,
    }
    for key, value in parts.items():
        page = page.replace(key, value, 1)
    return page


def write_report(doc: dict, path: str | Path) -> Path:
    """Write the report of `doc` to `path` (folders made as needed); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(render_html(doc), encoding="utf-8")
    return path
