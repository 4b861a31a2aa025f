"""Derive per-player serve / return / rally calibration targets from the 2011 slam files
(`sportsngen.synth.targets.derive_targets`).

Run: ``python scripts/derive_player_stats.py`` (needs ../shared/data/slam_pointbypoint, see
sportsngen.data.paths). Writes ``sportsngen/synth/data/slam2011_targets.csv`` (or --out) and
exits non-zero when the serving figures do not match the shared data README's table.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sportsngen.synth.targets import TARGETS_CSV, derive_targets


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=TARGETS_CSV, help="CSV to write")
    return 0 if derive_targets(ap.parse_args(argv).out) else 2


if __name__ == "__main__":
    sys.exit(main())
