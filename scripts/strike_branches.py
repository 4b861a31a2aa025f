"""Where a model's serves go wrong: recorded serves branched before, at and after the strike.

    python scripts/strike_branches.py [--model PATH] [--points 300] [--seed 0]
        [--top-p-ball P] [--[no-]contact-odds] [--top-p-contact P] [--after -1 0 1 3]

Prints, per branch point and serve number, the share of serves landing in the box and the
shares of those wide and returned (`sportsngen.eval.diagnostics.strike_branches`), beside the
recorded serves of the generator's Federer v Nadal on hard.
"""

from __future__ import annotations

import argparse

import torch

from sportsngen.eval.diagnostics import DiagnosticsSetup, strike_branches, truth_points
from sportsngen.sim import Simulator


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--points", type=int, default=300)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--top-p-ball", type=float, default=None)
    ap.add_argument("--contact-odds", action=argparse.BooleanOptionalAction, default=None)
    ap.add_argument("--top-p-contact", type=float, default=None)
    ap.add_argument("--after", type=int, nargs="+", default=[-1, 0, 1, 3])
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    kw = {} if args.top_p_ball is None else {"top_p_ball": args.top_p_ball}
    if args.contact_odds is not None:   # else the model file's default
        kw["contact_odds"] = args.contact_odds
    if args.top_p_contact is not None:
        kw["top_p_contact"] = args.top_p_contact
    sim = Simulator.from_pretrained(args.model, **kw)
    truth = truth_points(DiagnosticsSetup(n_points=args.points, seed=args.seed))
    table = strike_branches(sim, truth, tuple(args.after), seed=args.seed)
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))


if __name__ == "__main__":
    main()
