"""The leak check of issue 16 on generated play: Federer v Nadal on hard and Djokovic v Murray on
clay, `--points` each, `sportsngen.eval.leaks.check_leaks` at k = 6 and 12 frames, and the
path-matched fault check (`sportsngen.eval.leak_paths`).

    python scripts/leak_report.py [--points 800] [--seed 1] [--boot 1000] [--out /tmp/leaks]
        [--before /tmp/leaks_v5] [--data /tmp/v5data/p800 | --save-data /tmp/v5data/p800]

Matchup k is generated from seed + k. Writes ``<out>_<matchup>.csv``,
``<out>_<matchup>_paths.csv`` and ``<out>.md`` (the tables) and prints how many AUCs lie outside
[0.4, 0.6]. Run it from another revision's tree (PYTHONPATH) to measure that generator with the
same check; ``--before`` names such a run's ``--out`` and adds ``<out>_compare.md``, one table
of both (before -> now, bold outside). Where today's check has changed since a generator version
was replaced, ``--save-data PREFIX`` run from that version's tree (PYTHONPATH) only generates
the points and saves them in ``<PREFIX>_<matchup>`` folders (`RallyData.save`), and ``--data
PREFIX`` here reads them instead of generating.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from sportsngen.data.tracking import RallyData
from sportsngen.synth import generate_matches
from sportsngen.synth.dataset import GENERATOR_VERSION

try:  # absent from trees older than the check (a --save-data run)
    from sportsngen.eval.leaks import check_leaks, outside_band, render_leaks
except ImportError:
    check_leaks = None
try:  # absent from trees older than the thin cells (a --before run)
    from sportsngen.eval.leaks import sure_leaks, thin_cells
except ImportError:
    thin_cells = None
try:  # absent from trees older than the path-matched check (a --before run)
    from sportsngen.eval.leak_paths import check_fault_paths
except ImportError:
    check_fault_paths = None

MATCHUPS = ((("Roger Federer", "Rafael Nadal"), "hard"),
            (("Novak Djokovic", "Andy Murray"), "clay"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=800)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--boot", type=int, default=1000)
    ap.add_argument("--out", type=Path, default=Path("/tmp/leaks"))
    ap.add_argument("--before", type=Path, default=None,
                    help="--out of a run on another revision: also write a comparison table")
    ap.add_argument("--data", type=Path, default=None,
                    help="read the points from <DATA>_<matchup> folders (module doc)")
    ap.add_argument("--save-data", type=Path, default=None,
                    help="only generate the points and save them in <SAVE_DATA>_<matchup>")
    args = ap.parse_args()
    if check_leaks is None and args.save_data is None:
        raise SystemExit("this tree has no sportsngen.eval.leaks: only --save-data runs here")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    source = (f"points read from {args.data}_*" if args.data is not None else
              f"generator version {GENERATOR_VERSION}: {args.points} points a matchup, seed "
              f"{args.seed} + k")
    parts = [f"# Leak check, {source}, {args.boot} bootstrap resamples\n"]
    for k, ((a, b), surface) in enumerate(MATCHUPS):
        name = f"{a.split()[-1]}_{b.split()[-1]}_{surface}".lower()
        if args.data is not None:
            data = RallyData.load(args.data.parent / f"{args.data.name}_{name}")
        else:
            data = generate_matches([(a, b)], surface, args.points, seed=args.seed + k)
        if args.save_data is not None:
            data.save(args.save_data.parent / f"{args.save_data.name}_{name}")
            print(f"saved {args.save_data}_{name} (generator version {GENERATOR_VERSION})")
            continue
        table = check_leaks(data, ks=(6, 12), n_boot=args.boot, seed=0)
        table.to_csv(args.out.parent / f"{args.out.name}_{name}.csv", index=False)
        parts += [f"## {a} v {b}, {surface}\n", render_leaks(table), ""]
        thin = ""
        if thin_cells is not None:
            few = outside_band(table, min_pairs=0) & thin_cells(table)
            thin = (f" ({int(sure_leaks(table).sum())} with an interval that leaves out 0.5; "
                    f"{int(few.sum())} more on too few pairs to read)")
        print(f"{a} v {b} ({surface}): {int(outside_band(table).sum())} of {len(table)} AUCs "
              f"outside [0.4, 0.6]{thin}", flush=True)
        if check_fault_paths is not None:
            paths = check_fault_paths(data, ks=(6, 12), n_boot=args.boot)
            paths.to_csv(args.out.parent / f"{args.out.name}_{name}_paths.csv", index=False)
            parts += ["Path-matched, fault against in (`eval.leak_paths`):\n",
                      render_leaks(paths), ""]
            print(f"  path-matched faults: {int(outside_band(paths).sum())} of {len(paths)} "
                  "outside", flush=True)
    if args.save_data is not None:
        return
    args.out.with_suffix(".md").write_text("\n".join(parts))
    print(f"wrote {args.out.with_suffix('.md')}")
    if args.before is not None:
        path = args.out.parent / f"{args.out.name}_compare.md"
        path.write_text(compare(args.before, args.out))
        print(f"wrote {path}")


def _cell(row: pd.Series) -> str:
    text = f"{row['auc']:.2f} [{row['lo']:.2f}, {row['hi']:.2f}]"
    return f"**{text}**" if not 0.4 <= row["auc"] <= 0.6 else text


def compare(before: Path, now: Path) -> str:
    """A markdown table: a row per (pair, role, feature), a column per matchup and k, each cell
    ``before -> now`` (AUC [interval]), bold outside [0.4, 0.6]."""
    key = ["pair", "role", "feature"]
    cols, rows = [], None
    for (a, b), surface in MATCHUPS:
        name = f"{a.split()[-1]}_{b.split()[-1]}_{surface}".lower()
        old, new = (pd.read_csv(d.parent / f"{d.name}_{name}.csv") for d in (before, now))
        for k in sorted(new["k"].unique()):
            o, n = (t[t["k"] == k].set_index(key) for t in (old, new))
            col = f"{a.split()[-1]} v {b.split()[-1]} k={k}"
            cell = pd.Series({i: f"{_cell(o.loc[i])} → {_cell(n.loc[i])}" for i in n.index},
                             name=col)
            rows = cell.to_frame() if rows is None else rows.join(cell)
            cols.append(col)
    lines = ["| pair | role | feature | " + " | ".join(cols) + " |",
             "|---|---|---|" + "---|" * len(cols)]
    for (pair, role, feature), r in rows.iterrows():
        lines.append(f"| {pair} | {role} | {feature.split('_')[0]} | " + " | ".join(r) + " |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
