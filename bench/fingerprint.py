"""What a refactor must not change, as one JSON file per tree: the generated data (120 points of
`conf/data/synthetic_tiny.yaml` at seed 5, each table hashed), the per-step training losses of
`train.py experiment=tiny` over its first 200 steps (and 20 of the event classifier), and the
score lines `simulate.py` prints for two learned matches and three Markov ones.

    python bench/fingerprint.py OUT.json [--tree DIR]      # DIR: a checkout (default: this one)
    python bench/fingerprint.py --compare BASE.json HEAD.json

Issue 21's check: 064aa79 and the refactored tree gave the same file (docs/architecture.md).
About 3 minutes on 2 idle cores.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MATCHES = (["seed=0"], ["seed=1", "player1=Novak Djokovic", "player2=Andy Murray"],
           ["engine=markov", "n_matches=3"])

_DATA = """
import hashlib, json, sys
from pathlib import Path
import pandas as pd
from omegaconf import OmegaConf
from sportsngen.synth.dataset import generate_to_folder
cfg = OmegaConf.load(Path(sys.argv[1]) / "conf/data/synthetic_tiny.yaml")
cfg.n_points, cfg.seed = 120, 5
folder = generate_to_folder(cfg, Path(sys.argv[2]) / "d", progress=False)
out = {}
for f in sorted(Path(folder).rglob("*.parquet")):
    df = pd.read_parquet(f)
    b = pd.util.hash_pandas_object(df, index=True).values.tobytes() + str(list(df.columns)).encode()
    out[f"data/{f.name}"] = hashlib.sha256(b).hexdigest()[:16]
print(json.dumps(out))
"""


def _run(tree: Path, args: list[str]) -> str:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    return subprocess.run([sys.executable, *args], cwd=tree, env=env, check=True,
                          capture_output=True, text=True).stdout


def fingerprint(tree: Path) -> dict:
    """The tree's data hashes, training losses and score lines (module doc)."""
    import pandas as pd

    with tempfile.TemporaryDirectory() as tmp:
        out = json.loads(_run(tree, ["-c", _DATA, str(tree), tmp]).strip().splitlines()[-1])
        _run(tree, ["train.py", "experiment=tiny", "trainer.max_steps=200",
                    "trainer.log_every_n_steps=1", "events.max_steps=20",
                    f"hydra.run.dir={tmp}/run"])
        for csv in sorted(Path(tmp).rglob("metrics.csv")):
            metrics = pd.read_csv(csv)
            for col in (c for c in metrics.columns if "loss" in c and "train" in c):
                losses = metrics[col].dropna().tolist()
                out[f"train/{csv.parent.name}/{col}"] = {
                    "n": len(losses), "first": losses[:3], "last": losses[-3:],
                    "sha": hashlib.sha256(repr(losses).encode()).hexdigest()[:16]}
    for args in MATCHES:
        with tempfile.TemporaryDirectory() as tmp:
            text = _run(tree, ["simulate.py", "report=false", *args, f"hydra.run.dir={tmp}/s"])
        out["simulate/" + " ".join(args)] = [ln for ln in text.splitlines()
                                             if re.match(r"match \d+:", ln)]
    return out


def compare(base: dict, head: dict) -> bool:
    """Print each entry SAME or DIFF; True when all are the same."""
    same = True
    for key in sorted(set(base) | set(head)):
        ok = base.get(key) == head.get(key)
        same &= ok
        print(f"{'SAME' if ok else 'DIFF'}  {key}" + ("" if ok else
                                                     f"\n  {base.get(key)}\n  {head.get(key)}"))
    return same


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", type=Path, help="write the tree's fingerprint here")
    parser.add_argument("--tree", type=Path, default=REPO)
    parser.add_argument("--compare", nargs=2, type=Path, metavar=("BASE", "HEAD"))
    args = parser.parse_args()
    if args.compare:
        sys.exit(0 if compare(*(json.loads(p.read_text()) for p in args.compare)) else 1)
    if args.out is None:
        parser.error("give OUT.json or --compare BASE HEAD")
    args.out.write_text(json.dumps(fingerprint(args.tree.resolve()), indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
