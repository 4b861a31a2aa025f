"""A model file's serve (or strike) head refitted alone on its frozen decoder's states, read
once (`train.head_fit`), as `scripts/fit_head.py` runs it.

The rallies are the file's own training data and split (`extra.split`: the data config, the
validation fraction and seed), so the validation NLL is on the rallies its last stage held
out, and with `more_points` N also N points generated from the same config with another seed
(training only), or with `more_data` the points of that data config (e.g. synthetic_named,
the named players' round robins); with `own_serves` also the serve head's states at the
serves the model plays from its own tosses, each paired with the record's serve of the same
point (`train.own_states`, training and validation). The head ends at its best validation NLL.
Everything else in the file (other weights, sampling defaults, calibrator) is copied
unchanged. `states` (a file) keeps the states read (minutes for the strike head) and reads
them from there on the next run with the same model and options.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import torch

from sportsngen.data.tokens import rally_arrays
from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.export import load_model, read_extra, save_model
from sportsngen.sim.simulator import Simulator, model_path
from sportsngen.train.datamodule import load_rally_data, split_rallies
from sportsngen.train.evaluate import data_config
from sportsngen.train.finetune import with_strike_roles
from sportsngen.train.head_fit import HeadStates, cached_states, collect_head_states, fit_head
from sportsngen.train.own_states import own_serve_states

MORE_SEED = 1000        # the more points' seed where none is given


def split_head_states(model: SportsNGEN, vocab, split: dict, head: str, flip: bool = True,
                      own_serves_of: str | Path | None = None, seed: int = 0,
                      more_points: int = 0, more_seed: int | None = None,
                      more_data: str | None = None) -> tuple[HeadStates, HeadStates]:
    """The head's states on the file's training and validation rallies (`split`: its
    `extra.split`) -> (train, val); with `own_serves_of` (the model file) also at the serves
    it plays from its own tosses (`seed`), and on the training side the more points."""
    data = load_rally_data(split["data"])
    arrays = rally_arrays(data, vocab)
    train, val = split_rallies(arrays, float(split["val_fraction"]), int(split["seed"]))
    tr = collect_head_states(model, train, head, flip=flip)
    va = collect_head_states(model, val, head, progress=False)
    if own_serves_of:
        sim = Simulator.from_pretrained(own_serves_of)
        own = [own_serve_states(sim, data, part, seed=seed + i, progress=True,
                                record=states)[1]
               for i, (part, states) in enumerate(((train, tr), (val, va)))]
        print(f"{len(own[0])} training and {len(own[1])} validation serves played from the "
              "model's own tosses")
        tr, va = HeadStates.concat([tr, own[0]]), HeadStates.concat([va, own[1]])
    if more_data or more_points > 0:
        more = data_config(more_data) if more_data else dict(split["data"])
        if more_points > 0:
            more["n_points"] = more_points
        if not more_data or more_seed is not None:
            more["seed"] = MORE_SEED if more_seed is None else more_seed
        if more == split["data"] or (not more_data and int(more["seed"]) == int(
                split["data"].get("seed", 0))):
            raise SystemExit("the more points would repeat the file's own data: give another "
                             "--more-seed")
        extra_arrays = rally_arrays(load_rally_data(more), vocab)
        tr = HeadStates.concat([tr, collect_head_states(model, extra_arrays, head, flip=flip)])
    return tr, va


def fit_head_file(model: str | None, out: str, head: str = "serve", steps: int = 4000,
                  lr: float = 1e-3, batch_size: int = 256, eval_every: int = 250,
                  seed: int = 0, threads: int = 2, more_points: int = 0,
                  more_seed: int | None = None, more_data: str | None = None,
                  no_flip: bool = False, strike_roles: bool = False, own_serves: bool = False,
                  states: str | None = None) -> list[dict]:
    """The module's fit on the model file `model`, written to `out`; `strike_roles` adds the
    strike head's shift by the hitter's role and the serve (`model.strike_roles`) and fits it
    with the head -> the fit's history."""
    torch.set_num_threads(threads)
    path = model_path(model)
    net, ec, vocab, _ = load_model(path)
    if own_serves and head != "serve":
        raise SystemExit("--own-serves pairs the model's own serves with the record's: use "
                         "--head serve")
    if strike_roles:
        if head != "strike":
            raise SystemExit("--strike-roles shifts the strike head's input: use --head strike")
        net = with_strike_roles(net)
    extra = read_extra(path)
    split = extra.get("split")
    if not split or "data" not in split:
        raise SystemExit(f"{path} records no training data split (extra.split): it cannot "
                         "say which rallies it learnt from")
    t0 = time.time()
    key = {"model": str(path), "head": head, "flip": not no_flip, "more_points": more_points,
           "more_seed": MORE_SEED if more_seed is None else more_seed}
    if more_data:        # (caches written before the option keep their key)
        key["more_data"] = more_data
    if own_serves:       # (caches written before the option keep their key)
        key.update(own_serves=True, seed=seed)
    try:
        got, cached = cached_states(states, key, lambda: dict(zip(("train", "val"), (
            split_head_states(net, vocab, split, head, flip=not no_flip,
                              own_serves_of=path if own_serves else None, seed=seed,
                              more_points=more_points, more_seed=more_seed,
                              more_data=more_data)))))
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    tr, va = got["train"], got["val"]
    print(f"{len(tr)} training and {len(va)} validation {head} targets "
          + (f"read from {states}" if cached else f"({time.time() - t0:.0f} s)"))
    t0 = time.time()
    history = fit_head(net, head, tr, va, steps=steps, lr=lr, batch_size=batch_size,
                       eval_every=eval_every, seed=seed)
    best = min(history, key=lambda r: r["val_nll"])
    print(f"validation NLL {history[0]['val_nll']:.3f} -> {best['val_nll']:.3f} "
          f"(step {best['step']}; {time.time() - t0:.0f} s)")
    print(json.dumps(history))
    save_model(out, net, vocab, ec, extra=extra)
    print(f"wrote {out}")
    return history
