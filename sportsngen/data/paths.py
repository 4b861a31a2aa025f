"""Where the shared real data lives, so tests and scripts can find it or skip with a reason."""

from __future__ import annotations

import os
from pathlib import Path

_REPO_ROOT = Path(__file__).resolve().parents[2]


def conf_dir() -> Path:
    """The project's Hydra configs as the package carries them: `sportsngen/conf`, a link to the
    checkout's `conf/` that a wheel holds as a copy, so an installed package finds them too."""
    return Path(__file__).resolve().parents[1] / "conf"


def _shared_dir_with(subfolder: str) -> Path | None:
    """The first shared data folder holding `subfolder`: `$SPORTSNGEN_SHARED_DATA`, then
    `../shared/data` beside the repository (the layout of a checkout next to the project's
    shared folder)."""
    env = os.environ.get("SPORTSNGEN_SHARED_DATA")
    candidates = [Path(env)] if env else []
    candidates.append(_REPO_ROOT.parent / "shared" / "data")
    for cand in candidates:
        if (cand / subfolder).is_dir():
            return cand
    return None


def shared_data_dir() -> Path | None:
    """The folder holding `slam_pointbypoint/`, or None when it is absent."""
    return _shared_dir_with("slam_pointbypoint")


def slam_dir() -> Path | None:
    """`<shared data>/slam_pointbypoint`, or None when absent."""
    root = shared_data_dir()
    return None if root is None else root / "slam_pointbypoint"


def hawkeye_targets_path() -> Path | None:
    """`<shared data>/hawkeye/ball_targets_2019_2020.csv` (real Hawk-Eye summary figures), or
    None when absent."""
    root = _shared_dir_with("hawkeye")
    path = None if root is None else root / "hawkeye" / "ball_targets_2019_2020.csv"
    return path if path is not None and path.is_file() else None


SHARED_DATA_MISSING = (
    "real Grand Slam data not found: expected ../shared/data/slam_pointbypoint beside the "
    "repository or $SPORTSNGEN_SHARED_DATA (see README, 'Data')"
)
HAWKEYE_TARGETS_MISSING = (
    "real Hawk-Eye figures not found: expected ../shared/data/hawkeye/ball_targets_2019_2020.csv "
    "beside the repository or under $SPORTSNGEN_SHARED_DATA"
)
