"""A "what if she had gone down the line?" figure with the bundled model (the paper's Fig. 16).

    .venv/bin/python scripts/counterfactual_demo.py [--model PATH] [--n 100] [--seed 0]
        [--out docs/figures/counterfactual]

Branches a held-out generated rally before its third shot, forces it cross court and down the
line, rolls `--n` continuations of each, writes counterfactual.png and counterfactual.md
(`sportsngen.report.counterfactual`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.eval.command_line import add_simulator_options, simulator_from_args
from sportsngen.report.counterfactual import counterfactual_page


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_simulator_options(ap)
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--shot", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("docs/figures/counterfactual"))
    args = ap.parse_args()
    page = counterfactual_page(simulator_from_args(ap, args), args.out, args.n, args.seed,
                               args.shot)
    print(page, end="")


if __name__ == "__main__":
    main()
