"""Move a model file's late strikes' error table by what its own rollouts drew against a truth
(`model.strike_late`; `sportsngen.train.table_fits.fit_late_on_rollouts_file`).

    python scripts/fit_late_on_rollouts.py --model FILE --out FILE
        --pair SIM_DIR TRUTH_DIR [--pair SIM_DIR TRUTH_DIR ...] [--prior-strikes 200]
        [--rally | --second]

Each `--pair`: the file's rollouts of a matchup (`scripts/check_simulation.py --save-sim`)
and a large truth of the same players and surface (`RallyData.save`).
"""

from __future__ import annotations

from sportsngen.train.table_cli import model_parser
from sportsngen.train.table_fits import fit_late_on_rollouts_file


def main() -> None:
    ap = model_parser(__doc__)
    ap.add_argument("--pair", nargs=2, action="append", required=True,
                    metavar=("SIM_DIR", "TRUTH_DIR"), help="a matchup's rollouts and truth")
    ap.add_argument("--prior-strikes", type=float, default=200.0,
                    help="pseudo-strikes at no change added to each hitter's rollouts")
    kind = ap.add_mutually_exclusive_group()
    kind.add_argument("--rally", action="store_true",
                      help="every strike after the return, into the player's table")
    kind.add_argument("--second", action="store_true",
                      help="second-serve points' strikes after the return, into the second "
                           "serves' table")
    fit_late_on_rollouts_file(**vars(ap.parse_args()))


if __name__ == "__main__":
    main()
