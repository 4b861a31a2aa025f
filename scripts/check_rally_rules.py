"""How well the rally-end rules (`sportsngen.tennis.rally`) recover the generator's own labels.

Generated rallies judged from the tracks alone against their labels
(`sportsngen.eval.rules_check`). `--noise-m A` adds uniform noise of +-A m in x and +-A/2 m in
y and z to the ball, and +-A m to the players, first (the paper's augmentation is A = 0.025).

    python scripts/check_rally_rules.py                  # ~1500 points, ~2000 rallies
    python scripts/check_rally_rules.py --noise-m 0.025
"""

from __future__ import annotations

import argparse

from sportsngen.eval.rules_check import check_rally_rules


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-points", type=int, default=1500)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--noise-m", type=float, default=0.0)
    args = ap.parse_args()
    check_rally_rules(args.n_points, args.seed, args.noise_m)


if __name__ == "__main__":
    main()
