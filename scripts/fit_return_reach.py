"""Fit each receiver's reach for the return (and with --rally each player's reach for the rally
balls) on a model file's recorded rallies, and write it into a copy of the file
(`extra.return_reach` / `extra.rally_reach`, `sportsngen.sim.reach_table`) with the sampling
default that draws from it (`return_reach_draw=true` / `rally_reach_draw=true`).

    .venv/bin/python scripts/fit_return_reach.py --model MODEL --more-data synthetic_named \\
        --out OUT.pt [--rally] [--serves-too]

The balls read are the file's training split and, with --more-data, every rally of that data
config; a player with fewer than --min-balls good balls plays the pooled row. With --rally the
rally balls' table is fitted (the return's is left as it is; add --serves-too for both).
"""

from __future__ import annotations

from sportsngen.sim.reach_table import MIN_BALLS, reach_table_from_data
from sportsngen.sim.simulator import model_path
from sportsngen.train.evaluate import training_rally_data
from sportsngen.train.table_cli import rule_table_parser, write_rule_tables

# What each table is called in the file and its sampling default.
TABLES = {"serve": ("return_reach", "return_reach_draw", "serves", "returned"),
          "rally": ("rally_reach", "rally_reach_draw", "rally balls", "answered")}


def main() -> None:
    ap = rule_table_parser(__doc__)
    ap.add_argument("--min-balls", type=int, default=MIN_BALLS,
                    help="a player's good balls for his own row (fewer: the pooled one)")
    ap.add_argument("--rally", action="store_true",
                    help="fit the rally balls' table (by the player due) instead of the return's")
    ap.add_argument("--serves-too", action="store_true", help="with --rally: fit both")
    args = ap.parse_args()
    if args.serves_too and not args.rally:
        ap.error("--serves-too goes with --rally")
    src = model_path(args.model)
    try:
        parts = training_rally_data(src, args.more_data)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    kinds = ("serve", "rally") if args.serves_too else ("rally",) if args.rally else ("serve",)
    fitted = {}
    for kind in kinds:
        _, _, what, verb = TABLES[kind]
        table, balls = reach_table_from_data(parts, kind, args.min_balls)
        print(f"{len(balls)} good {what}, {balls['answered'].mean():.3f} {verb}")
        print(f"pooled: half {verb} at {table.pooled[0]:.3f} m, scale {table.pooled[1]:.3f} m")
        for name, (c, s) in sorted(table.players.items()):
            n = int((balls["player"] == name).sum())
            print(f"{name:<20} {n:6d} balls: half {verb} at {c:.3f} m, scale {s:.3f} m")
        fitted[kind] = table
    out = write_rule_tables(src, args.out,
                            {TABLES[k][0]: table.to_dict() for k, table in fitted.items()},
                            **{TABLES[k][1]: True for k in fitted})
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
