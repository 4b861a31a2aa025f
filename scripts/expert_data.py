"""The generator as expert on a model's own rollouts: write the rallies to train on.

    .venv/bin/python scripts/expert_data.py --model sportsngen/model/bundled/sportsngen-small.pt
        --out outputs/expert/bundled.npz [--branches 3000] [--data synthetic_small] [--seed 0]

Branches of the data's training split (the split `train.py` makes with the same `--val-fraction`
and `--split-seed`) are rolled out by the model at its stored sampling, and the generator's
players play each rally on from the model's state (`sportsngen.train.expert`). Train on them
with `python train.py init=<the same model> expert.path=<out> ...`.

    .venv/bin/python scripts/expert_data.py --model M --out X.npz --from-sims FOLDER [FOLDER ...]
        [--shots 2 3 4 5 6] [--repeat 1]

answers whole simulated points instead (`RallyData` folders, e.g. `check_simulation.py
--save-sim`): every shot of `--shots` from 8 frames after the shot before it
(`sportsngen.eval.expert_answers.simulated_expert_arrays`), each rally written `--repeat` times.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch
from omegaconf import OmegaConf

from sportsngen.data.tokens import rally_arrays
from sportsngen.sim import Simulator
from sportsngen.synth.dataset import matchups
from sportsngen.train.datamodule import load_rally_data, split_positions
from sportsngen.train.expert import (
    ExpertConfig,
    expert_arrays,
    late_contact_arrays,
    save_expert,
    serve_return_fidelity,
)

CONF = Path(__file__).resolve().parents[1] / "conf" / "data"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None, help="model file (default: the bundled model)")
    ap.add_argument("--out", help=".npz file to write")
    ap.add_argument("--data", default="synthetic_small", help="a conf/data config (synthetic)")
    ap.add_argument("--branches", type=int, default=ExpertConfig.n_branches)
    ap.add_argument("--min-model-frames", type=int, default=ExpertConfig.min_model_frames)
    ap.add_argument("--max-model-frames", type=int, default=ExpertConfig.max_model_frames)
    ap.add_argument("--keep-frames", type=int, default=ExpertConfig.keep_frames)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--val-fraction", type=float, default=0.1)
    ap.add_argument("--split-seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--fidelity", type=int, nargs="*", default=None, metavar="FRAMES",
                    help="only measure the expert on recorded serves: hand the record's own "
                         "state to the kernel these frames after the branch frame and print "
                         "the share it returns against the record's (writes nothing)")
    ap.add_argument("--late-contacts", type=int, nargs="+", default=None, metavar="FRAMES",
                    help="instead of the model's rollouts: recorded shots after the serve whose "
                         "ball flies on unstruck for one of these delays, answered by the "
                         "kernel (late_contact_arrays)")
    ap.add_argument("--from-sims", nargs="+", default=None, metavar="FOLDER",
                    help="answer whole simulated points of these RallyData folders instead")
    ap.add_argument("--shots", type=int, nargs="+", default=[2, 3, 4, 5, 6],
                    help="with --from-sims: the shots answered (default 2 3 4 5 6)")
    ap.add_argument("--repeat", type=int, default=1,
                    help="with --from-sims: write each rally this many times (its weight "
                         "among the training windows)")
    args = ap.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    if args.from_sims:
        from_sims(args)
        return
    cfg = OmegaConf.to_container(OmegaConf.load(CONF / f"{args.data}.yaml"), resolve=True)
    if cfg.get("source") != "synthetic":
        raise SystemExit(f"--data {args.data} is not generated: the expert is the generator, "
                         "whose players must be the data's")
    t0 = time.perf_counter()
    data = load_rally_data(cfg)
    profiles = {p.name: p for pair in matchups(cfg) for p in pair}
    sim = Simulator.from_pretrained(args.model)
    arrays = rally_arrays(data, sim.vocab, unknown="generic")
    train, _ = split_positions(len(arrays), args.val_fraction, args.split_seed)
    if args.fidelity is not None:
        for k in args.fidelity or [2, 6]:
            print(json.dumps(serve_return_fidelity(data, arrays, train, profiles, k,
                                                   n_branches=args.branches, seed=args.seed)))
        return
    if not args.out:
        raise SystemExit("--out is required (the .npz file to write)")
    if args.late_contacts:
        out, counts = late_contact_arrays(data, arrays, train, profiles,
                                          tuple(args.late_contacts), args.branches,
                                          args.keep_frames, args.seed, progress=True)
    else:
        ecfg = ExpertConfig(n_branches=args.branches, min_model_frames=args.min_model_frames,
                            max_model_frames=args.max_model_frames,
                            keep_frames=args.keep_frames, seed=args.seed)
        out, counts = expert_arrays(sim, data, arrays, train, profiles, ecfg, progress=True)
    path = save_expert(out, args.out)
    counts["frames"] = int(out.length.sum())
    counts["seconds"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(counts))
    print(f"wrote {path}")


def from_sims(args: argparse.Namespace) -> None:
    """`--from-sims`: the kernel's answers on saved simulated points."""
    from sportsngen.data.tokens import RallyArrays
    from sportsngen.data.tracking import RallyData
    from sportsngen.eval.expert_answers import simulated_expert_arrays

    if not args.out or args.repeat < 1:
        raise SystemExit("--out is required and --repeat must be >= 1")
    t0 = time.perf_counter()
    sim = Simulator.from_pretrained(args.model)
    parts, counts = [], {}
    for folder in args.from_sims:
        data = RallyData.load(folder, validate=False)   # simulated: physics flagged, not refused
        arr, c = simulated_expert_arrays(data, sim.vocab, tuple(args.shots), seed=args.seed)
        parts += [arr] * args.repeat
        counts[str(folder)] = c
    out = RallyArrays.concat(parts)
    path = save_expert(out, args.out)
    counts["frames"] = int(out.length.sum())
    counts["seconds"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(counts))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
