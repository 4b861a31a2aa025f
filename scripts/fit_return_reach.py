"""Fit each receiver's reach for the return (with --rally each player's reach for the rally
balls) on a model file's recorded rallies into a copy of the file, with the sampling default
that draws from it (`sportsngen.train.rule_tables.fit_return_reach_file`).

    python scripts/fit_return_reach.py --model MODEL --more-data synthetic_named \\
        --out OUT.pt [--rally] [--serves-too] [--min-balls N]
"""

from __future__ import annotations

from sportsngen.sim.reach_table import MIN_BALLS
from sportsngen.train.rule_tables import fit_return_reach_file
from sportsngen.train.table_cli import rule_table_parser


def main() -> None:
    ap = rule_table_parser(__doc__, (
        ("--min-balls", int, MIN_BALLS,
         "a player's good balls for his own row (fewer: the pooled one)"),))
    ap.add_argument("--rally", action="store_true",
                    help="fit the rally balls' table (by the player due) instead of the return's")
    ap.add_argument("--serves-too", action="store_true", help="with --rally: fit both")
    args = ap.parse_args()
    if args.serves_too and not args.rally:
        ap.error("--serves-too goes with --rally")
    fit_return_reach_file(**vars(args))


if __name__ == "__main__":
    main()
