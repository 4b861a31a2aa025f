"""Add and fit a model file's per-server aim of the serve inside the box (`model.serve_aim`;
`sportsngen.train.serve_bias.fit_serve_aim`) on the serves the model plays from its own tosses.

    .venv/bin/python scripts/fit_serve_aim.py --model FILE --out FILE [--data synthetic_named]
        [--players "A,B"] [--max-rallies 12000] [--prior-serves 100] [--seed 0] [--threads 2]

Each rally of the data config (conf/data/NAME.yaml; default the named players' round robins)
served by one of the players (default the file's named players) is played once from the
model's own serve start (`sportsngen.train.own_states.own_serve_states`), and the decoder's
state at its serve is paired with the record's serve of the same point; the aim is fitted on
those pairs, the wide shift refitted to hold each server's wide faults. The file must have the
serve table (`scripts/fit_serve_bias.py`); everything else in it is copied unchanged.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from sportsngen.data.tokens import N_SPECIAL_IDS, rally_arrays
from sportsngen.model.export import load_model, read_extra, save_model
from sportsngen.sim.simulator import Simulator, model_path
from sportsngen.train.datamodule import load_rally_data
from sportsngen.train.evaluate import data_config
from sportsngen.train.own_states import own_serve_states
from sportsngen.train.serve_bias import fit_serve_aim, with_serve_aim


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None, help="model file (default: the bundled one)")
    ap.add_argument("--out", required=True, help="where to write the model file")
    ap.add_argument("--data", default="synthetic_named", help="data config (conf/data/NAME)")
    ap.add_argument("--players", default=None,
                    help="comma-separated servers (default: the file's named players)")
    ap.add_argument("--max-rallies", type=int, default=12000,
                    help="at most this many of their rallies, drawn at random (--seed)")
    ap.add_argument("--prior-serves", type=float, default=100.0,
                    help="pseudo-serves at the head's own aim added to each server's record")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    if args.max_rallies < 1:
        ap.error(f"--max-rallies must be at least 1, got {args.max_rallies}")
    torch.set_num_threads(args.threads)
    path = model_path(args.model)
    model, ec, vocab, _ = load_model(path)
    if model.serve_bias is None:
        raise SystemExit(f"{path}: no serve table (model.serve_bias): run "
                         "scripts/fit_serve_bias.py first")
    extra = read_extra(path)
    if args.players:
        players = [p.strip() for p in args.players.split(",") if p.strip()]
    else:
        players = list(extra.get("split", {}).get("data", {}).get("players", {})
                       .get("named", []))
    if not players:
        raise SystemExit("no players: pass --players (the file's data names none)")
    for p in players:
        vocab.player_index(p, unknown="error")
    t0 = time.time()
    data = load_rally_data(data_config(args.data))
    ids = data.rallies.loc[data.rallies["server"].isin(players), "rally_id"].to_numpy()
    if not len(ids):
        raise SystemExit(f"no rally of {args.data} is served by {players}")
    rng = np.random.default_rng(args.seed)
    ids = np.sort(rng.choice(ids, min(args.max_rallies, len(ids)), replace=False))
    data = data.subset(ids)
    print(f"{len(ids)} rallies of {args.data} ({time.time() - t0:.0f} s)")
    sim = Simulator.from_pretrained(path)
    _, own = own_serve_states(sim, data, rally_arrays(data, vocab), seed=args.seed,
                              progress=True)
    print(f"{len(own)} serves played from the model's own tosses ({time.time() - t0:.0f} s)")
    model = with_serve_aim(model)
    table = fit_serve_aim(model, own, prior_serves=args.prior_serves)
    names = {N_SPECIAL_IDS + i: p for i, p in enumerate(vocab.players)}
    table.insert(0, "server", table["server_id"].map(names))
    table = table[table["server"].isin(players)]
    print(table.drop(columns="server_id").round(3).to_string(index=False))
    save_model(args.out, model, vocab, ec, extra=extra)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
