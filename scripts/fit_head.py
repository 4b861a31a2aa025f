"""Fit a model file's serve (or strike) head alone on its frozen decoder's states, read once.

    .venv/bin/python scripts/fit_head.py --model FILE --out FILE [--head serve|strike]
        [--steps 4000] [--lr 1e-3] [--batch-size 256] [--seed 0] [--threads 2]
        [--more-points N --more-seed S] [--more-data NAME] [--no-flip] [--states FILE]
        [--strike-roles] [--own-serves]

The rallies are the file's own training data and split (`extra.split`: the data config, the
validation fraction and seed), so the validation NLL is on the rallies its last stage held
out, and with `--more-points N` also N points generated from the same config with another
seed (training only), or with `--more-data NAME` the points of conf/data/NAME.yaml (e.g.
synthetic_named, the named players' round robins); the head ends at its best validation NLL
(`sportsngen.train.head_fit`). Everything else in the file (other weights, sampling defaults,
calibrator) is copied unchanged. `--states FILE` keeps the states read (minutes for the strike
head) in FILE and reads them from there on the next run with the same model and options.
"""

from __future__ import annotations

import argparse
import json
import time

import torch

from sportsngen.data.tokens import rally_arrays
from sportsngen.model.export import load_model, read_extra, save_model
from sportsngen.sim.simulator import Simulator, model_path
from sportsngen.train.datamodule import load_rally_data, split_rallies
from sportsngen.train.evaluate import data_config
from sportsngen.train.finetune import with_strike_roles
from sportsngen.train.head_fit import (
    HEADS,
    HeadStates,
    cached_states,
    collect_head_states,
    fit_head,
)
from sportsngen.train.own_states import own_serve_states


def _read_states(model, vocab, split: dict, args) -> tuple[HeadStates, HeadStates]:
    data = load_rally_data(split["data"])
    arrays = rally_arrays(data, vocab)
    train, val = split_rallies(arrays, float(split["val_fraction"]), int(split["seed"]))
    tr = collect_head_states(model, train, args.head, flip=not args.no_flip)
    va = collect_head_states(model, val, args.head, progress=False)
    if args.own_serves:
        sim = Simulator.from_pretrained(args.model)
        own = [own_serve_states(sim, data, part, seed=args.seed + i, progress=True,
                                record=states)[1]
               for i, (part, states) in enumerate(((train, tr), (val, va)))]
        print(f"{len(own[0])} training and {len(own[1])} validation serves played from the "
              "model's own tosses")
        tr, va = HeadStates.concat([tr, own[0]]), HeadStates.concat([va, own[1]])
    if args.more_data or args.more_points > 0:
        more = data_config(args.more_data) if args.more_data else dict(split["data"])
        if args.more_points > 0:
            more["n_points"] = args.more_points
        if not args.more_data or args.more_seed is not None:
            more["seed"] = 1000 if args.more_seed is None else args.more_seed
        if more == split["data"] or (not args.more_data and int(more["seed"]) == int(
                split["data"].get("seed", 0))):
            raise SystemExit("the more points would repeat the file's own data: give another "
                             "--more-seed")
        extra_arrays = rally_arrays(load_rally_data(more), vocab)
        tr = HeadStates.concat([tr, collect_head_states(model, extra_arrays, args.head,
                                                        flip=not args.no_flip)])
    return tr, va


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None, help="model file (default: the bundled one)")
    ap.add_argument("--out", required=True, help="where to write the model file with the head")
    ap.add_argument("--head", choices=HEADS, default="serve")
    ap.add_argument("--steps", type=int, default=4000)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--batch-size", type=int, default=256)
    ap.add_argument("--eval-every", type=int, default=250)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--more-points", type=int, default=0,
                    help="also train on this many more points generated as the file's data "
                         "with another seed (--more-seed): more serves of every player")
    ap.add_argument("--more-seed", type=int, default=None,
                    help="the more points' seed (default 1000, or --more-data's own)")
    ap.add_argument("--more-data", default=None,
                    help="draw the more points from this data config (conf/data/NAME.yaml), "
                         "e.g. synthetic_named: the named players' round robins, several "
                         "times each named player's serves in the file's own data")
    ap.add_argument("--no-flip", action="store_true",
                    help="train on the windows as recorded only (default: also turned about "
                         "the net's centre, as training's augmentation does)")
    ap.add_argument("--strike-roles", action="store_true",
                    help="add the strike head's shift by the hitter's role and the serve "
                         "(model.strike_roles) and fit it with the head")
    ap.add_argument("--own-serves", action="store_true",
                    help="also fit the serve head on its states at the serves the model plays "
                         "from its own tosses, each paired with the record's serve of the same "
                         "point (sportsngen.train.own_states; training and validation)")
    ap.add_argument("--states", default=None,
                    help="cache of the states read: written on the first run, read after")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    path = model_path(args.model)
    model, ec, vocab, _ = load_model(path)
    if args.own_serves and args.head != "serve":
        raise SystemExit("--own-serves pairs the model's own serves with the record's: use "
                         "--head serve")
    if args.strike_roles:
        if args.head != "strike":
            raise SystemExit("--strike-roles shifts the strike head's input: use --head strike")
        model = with_strike_roles(model)
    extra = read_extra(path)
    split = extra.get("split")
    if not split or "data" not in split:
        raise SystemExit(f"{path} records no training data split (extra.split): it cannot "
                         "say which rallies it learnt from")
    t0 = time.time()
    key = {"model": str(path), "head": args.head, "flip": not args.no_flip,
           "more_points": args.more_points,
           "more_seed": 1000 if args.more_seed is None else args.more_seed}
    if args.more_data:        # (caches written before the option keep their key)
        key["more_data"] = args.more_data
    if args.own_serves:       # (caches written before the option keep their key)
        key.update(own_serves=True, seed=args.seed)
    try:
        states, cached = cached_states(args.states, key, lambda: dict(zip(
            ("train", "val"), _read_states(model, vocab, split, args))))
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    tr, va = states["train"], states["val"]
    print(f"{len(tr)} training and {len(va)} validation {args.head} targets "
          + (f"read from {args.states}" if cached else f"({time.time() - t0:.0f} s)"))
    t0 = time.time()
    history = fit_head(model, args.head, tr, va, steps=args.steps, lr=args.lr,
                       batch_size=args.batch_size, eval_every=args.eval_every, seed=args.seed)
    best = min(history, key=lambda r: r["val_nll"])
    print(f"validation NLL {history[0]['val_nll']:.3f} -> {best['val_nll']:.3f} "
          f"(step {best['step']}; {time.time() - t0:.0f} s)")
    print(json.dumps(history))
    save_model(args.out, model, vocab, ec, extra=extra)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
