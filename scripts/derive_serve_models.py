"""Derive the bundled serve models of the Markov engine from the real 2011 Grand Slam data
(`sportsngen.baselines.serve_models_2011`): writes
`sportsngen/baselines/data/serve_models_2011.json` (needs ../shared/data/slam_pointbypoint).

    python scripts/derive_serve_models.py
"""

from __future__ import annotations

import argparse

from sportsngen.baselines.serve_models_2011 import derive_serve_models


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    derive_serve_models()


if __name__ == "__main__":
    main()
