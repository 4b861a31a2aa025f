"""The generator as expert on a model's own rollouts: write the rallies to train on
(`sportsngen.train.expert_files`).

    python scripts/expert_data.py --model sportsngen/model/bundled/sportsngen-small.pt
        --out outputs/expert/bundled.npz [--branches 3000] [--data synthetic_small] [--seed 0]
    python scripts/expert_data.py --model M --out X.npz --from-sims FOLDER [FOLDER ...]
        [--shots 2 3 4 5 6] [--repeat 1]

Train on them with `python train.py init=<the same model> expert.path=<out> ...`.
"""

from __future__ import annotations

import argparse

from sportsngen.train.expert import ExpertConfig
from sportsngen.train.expert_files import write_expert_data, write_simulated_answers


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
                    help="only print the share of recorded serves the kernel returns from the "
                         "record's state these frames after the branch (writes nothing)")
    ap.add_argument("--late-contacts", type=int, nargs="+", default=None, metavar="FRAMES",
                    help="instead: recorded shots whose ball flies on unstruck for one of "
                         "these delays, answered by the kernel")
    ap.add_argument("--from-sims", nargs="+", default=None, metavar="FOLDER",
                    help="answer whole simulated points of these RallyData folders instead")
    ap.add_argument("--shots", type=int, nargs="+", default=[2, 3, 4, 5, 6],
                    help="with --from-sims: the shots answered (default 2 3 4 5 6)")
    ap.add_argument("--repeat", type=int, default=1,
                    help="with --from-sims: write each rally this many times (its weight)")
    a = ap.parse_args()
    if a.from_sims:
        write_simulated_answers(a.model, a.out, a.from_sims, shots=a.shots, repeat=a.repeat,
                                seed=a.seed, threads=a.threads)
        return
    config = ExpertConfig(n_branches=a.branches, min_model_frames=a.min_model_frames,
                          max_model_frames=a.max_model_frames, keep_frames=a.keep_frames,
                          seed=a.seed)
    write_expert_data(a.model, a.out, a.data, config, val_fraction=a.val_fraction,
                      split_seed=a.split_seed, fidelity=a.fidelity,
                      late_contacts=a.late_contacts, threads=a.threads)


if __name__ == "__main__":
    main()
