"""Refit a model file's per-server serve shifts (`model.serve_bias`) on its own rollouts: each
named server's long and wide shifts moved until his rolled-out serves fault as often as his
record (`sportsngen.train.serve_bias_rollouts`).

    .venv/bin/python scripts/refine_serve_bias.py --model FILE --out FILE
        [--more-data synthetic_named] [--players "A,B"] [--serves 400] [--rounds 3]
        [--seed 0] [--threads 2] [--csv rounds.csv]

The record is the file's own training split (`extra.split`) and with `--more-data NAME` every
rally of conf/data/NAME.yaml; the players default to the named players of the file's training
data. Rollouts use the file's sampling defaults. Everything else in the file is copied
unchanged. Run after `scripts/fit_serve_bias.py` (which adds and fits the table on the
record's states).
"""

from __future__ import annotations

import time

from sportsngen.sim import Simulator
from sportsngen.train.serve_bias_rollouts import refine_serve_bias
from sportsngen.train.table_cli import open_table_run, table_parser


def main() -> None:
    ap = table_parser(__doc__)
    ap.add_argument("--players", default=None,
                    help="comma-separated servers (default: the training data's named players)")
    ap.add_argument("--serves", type=int, default=400, help="rollouts a server, serve, round")
    ap.add_argument("--rounds", type=int, default=3, help="updates before the last measurement")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--csv", default=None, help="write the rounds table here")
    args = ap.parse_args()
    run = open_table_run(args, lambda m: None if m.serve_bias is not None
                         else "no per-server table (model.serve_bias): run "
                              "scripts/fit_serve_bias.py first")
    if args.players:
        players = [p.strip() for p in args.players.split(",") if p.strip()]
    else:
        players = list(run.extra.get("split", {}).get("data", {}).get("players", {})
                       .get("named", []))
    if not players:
        raise SystemExit("no players: pass --players (the file's data names none)")
    sim = Simulator.from_pretrained(run.path)
    t0 = time.time()
    table = refine_serve_bias(sim, run.arrays, players, n_serves=args.serves,
                              rounds=args.rounds, seed=args.seed)
    print(f"({time.time() - t0:.0f} s)")
    last = table[table["round"] == args.rounds]
    print(last[["server", "serve", "record_n", "record_share", "rollout_n",
                "rollout_share"]].round(3).to_string(index=False))
    if args.csv:
        table.to_csv(args.csv, index=False)
    run.save(sim.model, args.out)


if __name__ == "__main__":
    main()
