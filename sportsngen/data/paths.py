"""Where the shared real data lives, so tests and scripts can find it or skip with a reason."""

from __future__ import annotations

import os
from pathlib import Path

_REPO_ROOT = Path(__file__).resolve().parents[2]


def shared_data_dir() -> Path | None:
    """The folder holding `slam_pointbypoint/`, or None when it is absent.

    Looked up in `$SPORTSNGEN_SHARED_DATA`, then `../shared/data` beside the repository (the
    layout of a checkout next to the project's shared folder).
    """
    env = os.environ.get("SPORTSNGEN_SHARED_DATA")
    candidates = [Path(env)] if env else []
    candidates.append(_REPO_ROOT.parent / "shared" / "data")
    for cand in candidates:
        if (cand / "slam_pointbypoint").is_dir():
            return cand
    return None


def slam_dir() -> Path | None:
    """`<shared data>/slam_pointbypoint`, or None when absent."""
    root = shared_data_dir()
    return None if root is None else root / "slam_pointbypoint"


SHARED_DATA_MISSING = (
    "real Grand Slam data not found: expected ../shared/data/slam_pointbypoint beside the "
    "repository or $SPORTSNGEN_SHARED_DATA (see README, 'Data')"
)
