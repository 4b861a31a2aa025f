"""Read each player's top running speed from a model file's recorded rallies into a copy of
the file, with the sampling default that bounds every rollout frame by it
(`sportsngen.train.rule_tables.fit_top_speed_file`).

    python scripts/fit_top_speed.py --model MODEL --more-data synthetic_named --out OUT.pt \\
        [--quantile Q] [--min-frames N]
"""

from __future__ import annotations

from sportsngen.sim.top_speed import MIN_FRAMES, QUANTILE
from sportsngen.train.rule_tables import fit_top_speed_file
from sportsngen.train.table_cli import rule_table_parser


def main() -> None:
    fit_top_speed_file(**vars(rule_table_parser(__doc__, (
        ("--quantile", float, QUANTILE, "a player's top speed: this quantile of his frame speeds"),
        ("--min-frames", int, MIN_FRAMES,
         "a player's frames for his own row (fewer: the pooled one)"))).parse_args()))


if __name__ == "__main__":
    main()
