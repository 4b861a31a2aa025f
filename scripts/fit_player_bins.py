"""Read where the players' offsets fall inside the player head's bins from a model file's
recorded rallies into a copy of the file, with the sampling default that places every player
draw by it (`sportsngen.train.rule_tables.fit_player_bins_file`).

    python scripts/fit_player_bins.py --model MODEL --more-data synthetic_named --out OUT.pt \\
        [--quantiles Q] [--min-offsets N]
"""

from __future__ import annotations

from sportsngen.model.bin_quantiles import MIN_OFFSETS, N_QUANTILES
from sportsngen.train.rule_tables import fit_player_bins_file
from sportsngen.train.table_cli import rule_table_parser


def main() -> None:
    fit_player_bins_file(**vars(rule_table_parser(__doc__, (
        ("--quantiles", int, N_QUANTILES, "quantiles stored per bin (0, 1/Q, ..., 1)"),
        ("--min-offsets", int, MIN_OFFSETS,
         "a bin's offsets for its own spread (fewer: uniform)"))).parse_args()))


if __name__ == "__main__":
    main()
