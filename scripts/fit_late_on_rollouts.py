"""Move a model file's late strikes' error table by what its own rollouts drew
(`model.strike_late`; `sportsngen.train.rollout_tables`).

    .venv/bin/python scripts/fit_late_on_rollouts.py --model FILE --out FILE
        --pair SIM_DIR TRUTH_DIR [--pair SIM_DIR TRUTH_DIR ...] [--prior-strikes 200]
        [--rally | --second]

Each `--pair` is one matchup: the file's rollouts saved by `scripts/check_simulation.py
--save-sim DIR` (made with `--model FILE`) and a truth of the same players and surface
(`RallyData.save`; a large one, e.g. 12,000 points from `synth.generate.generate_matches`). Per
hitter and role the log-odds gap between the truth's share of his strikes from the rally's
fifth on that ended the point as his error and the rollouts' share is pooled over the pairs,
shrunk by n / (n + prior) and added to his late row (the table is added at zero where the file
has none). With `--rally` the gap is taken over every strike after the return and added to
the player's own table (`model.strike_bias`), each receiver's step taken off his returns' row
(`train.rollout_tables.add_rollout_rally_shift`). With `--second` the gap is taken over the
strikes after the return of second-serve points alone and added to the second serves' table
(`model.strike_second`, added at zero where the file has none;
`train.rollout_tables.add_rollout_second_shift`). Everything else in the file is copied
unchanged. Run it again on new rollouts of the file it wrote to take a further step.
"""

from __future__ import annotations

import argparse

from sportsngen.data.tracking import RallyData
from sportsngen.eval.shot_profile import strike_endings
from sportsngen.model.export import load_model, read_extra, save_model
from sportsngen.sim.simulator import model_path
from sportsngen.train.rollout_tables import (
    RALLY_STAGES,
    add_rollout_late_shift,
    add_rollout_rally_shift,
    add_rollout_second_shift,
    at_serve,
    rollout_error_gaps,
)
from sportsngen.train.strike_bias import with_strike_late, with_strike_second


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None, help="model file (default: the bundled one)")
    ap.add_argument("--out", required=True, help="where to write the model file")
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
    args = ap.parse_args()
    path = model_path(args.model)
    model, event_model, vocab, _ = load_model(path)
    if args.second:
        if model.strike_bias is None:
            raise SystemExit(f"{path}: no model.strike_bias, which the second serves' table "
                             f"adds to")
        model = with_strike_second(model)
    elif not args.rally:
        if model.strike_pressure is None:
            raise SystemExit(f"{path}: no model.strike_pressure, which the late table needs")
        model = with_strike_late(model)
    pairs = []
    for sim_dir, truth_dir in args.pair:
        sim = strike_endings(RallyData.load(sim_dir, validate=False), by_serve=args.second)
        truth = strike_endings(RallyData.load(truth_dir), by_serve=args.second)
        pairs.append((at_serve(sim, 2), at_serve(truth, 2)) if args.second else (sim, truth))
    try:
        if args.second:
            table = add_rollout_second_shift(model, vocab,
                                             rollout_error_gaps(pairs, RALLY_STAGES),
                                             prior_strikes=args.prior_strikes)
        elif args.rally:
            table = add_rollout_rally_shift(model, vocab, rollout_error_gaps(pairs, RALLY_STAGES),
                                            prior_strikes=args.prior_strikes)
        else:
            table = add_rollout_late_shift(model, vocab, rollout_error_gaps(pairs),
                                           prior_strikes=args.prior_strikes)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    print(table.round(3).to_string())
    save_model(args.out, model, vocab, event_model, extra=read_extra(path))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
