"""The leak check of issue 16 on generated play: Federer v Nadal on hard and Djokovic v Murray on
clay, `sportsngen.eval.leaks.check_leaks` at k = 6 and 12 frames and the path-matched fault
check (`sportsngen.eval.leak_paths`), written as csv and markdown tables;
`scripts/leak_report.py` is the command line.

Matchup k is generated from seed + k. Points saved by another generator version
(`save_matchups`, run from that version's tree) are read back by `leak_report(data=...)`, so a
replaced generator is measured with today's check; `compare` tables two runs side by side.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from sportsngen.data.tracking import RallyData
from sportsngen.eval.leak_paths import check_fault_paths
from sportsngen.eval.leaks import check_leaks, outside_band, render_leaks, sure_leaks, thin_cells
from sportsngen.eval.markdown import markdown_table
from sportsngen.synth import generate_matches
from sportsngen.synth.dataset import GENERATOR_VERSION

MATCHUPS = ((("Roger Federer", "Rafael Nadal"), "hard"),
            (("Novak Djokovic", "Andy Murray"), "clay"))


def matchup_name(players: tuple[str, str], surface: str) -> str:
    """The file-name part of a matchup: "federer_nadal_hard"."""
    a, b = players
    return f"{a.split()[-1]}_{b.split()[-1]}_{surface}".lower()


def _matchup_path(prefix: Path, name: str, suffix: str = "") -> Path:
    return prefix.parent / f"{prefix.name}_{name}{suffix}"


def _matchup_data(k: int, players: tuple[str, str], surface: str, n_points: int, seed: int,
                  data: Path | None) -> RallyData:
    if data is not None:
        return RallyData.load(_matchup_path(data, matchup_name(players, surface)))
    return generate_matches([players], surface, n_points, seed=seed + k)


def save_matchups(prefix: Path, n_points: int, seed: int, data: Path | None = None) -> None:
    """Generate each matchup's points (or read them from ``<data>_<matchup>``) and save them in
    ``<prefix>_<matchup>`` folders."""
    for k, (players, surface) in enumerate(MATCHUPS):
        name = matchup_name(players, surface)
        _matchup_data(k, players, surface, n_points, seed, data).save(
            _matchup_path(prefix, name))
        print(f"saved {prefix}_{name} (generator version {GENERATOR_VERSION})")


def leak_report(out: Path, n_points: int, seed: int, n_boot: int, data: Path | None = None,
                before: Path | None = None) -> None:
    """Check each matchup (generated, or read from ``<data>_<matchup>`` folders), write
    ``<out>_<matchup>.csv``, ``<out>_<matchup>_paths.csv`` and ``<out>.md`` (the tables) and
    print how many AUCs lie outside [0.4, 0.6]; with `before` (another run's `out`) also
    ``<out>_compare.md``, the two runs side by side (`compare`)."""
    out.parent.mkdir(parents=True, exist_ok=True)
    source = (f"points read from {data}_*" if data is not None else
              f"generator version {GENERATOR_VERSION}: {n_points} points a matchup, seed "
              f"{seed} + k")
    parts = [f"# Leak check, {source}, {n_boot} bootstrap resamples\n"]
    for k, ((a, b), surface) in enumerate(MATCHUPS):
        name = matchup_name((a, b), surface)
        rallies = _matchup_data(k, (a, b), surface, n_points, seed, data)
        table = check_leaks(rallies, ks=(6, 12), n_boot=n_boot, seed=0)
        table.to_csv(_matchup_path(out, name, ".csv"), index=False)
        parts += [f"## {a} v {b}, {surface}\n", render_leaks(table), ""]
        few = outside_band(table, min_pairs=0) & thin_cells(table)
        thin = (f" ({int(sure_leaks(table).sum())} with an interval that leaves out 0.5; "
                f"{int(few.sum())} more on too few pairs to read)")
        print(f"{a} v {b} ({surface}): {int(outside_band(table).sum())} of {len(table)} AUCs "
              f"outside [0.4, 0.6]{thin}", flush=True)
        paths = check_fault_paths(rallies, ks=(6, 12), n_boot=n_boot)
        paths.to_csv(_matchup_path(out, name, "_paths.csv"), index=False)
        parts += ["Path-matched, fault against in (`eval.leak_paths`):\n",
                  render_leaks(paths), ""]
        print(f"  path-matched faults: {int(outside_band(paths).sum())} of {len(paths)} "
              "outside", flush=True)
    out.with_suffix(".md").write_text("\n".join(parts))
    print(f"wrote {out.with_suffix('.md')}")
    if before is not None:
        path = out.parent / f"{out.name}_compare.md"
        path.write_text(compare(before, out))
        print(f"wrote {path}")


def _cell(row: pd.Series) -> str:
    text = f"{row['auc']:.2f} [{row['lo']:.2f}, {row['hi']:.2f}]"
    return f"**{text}**" if not 0.4 <= row["auc"] <= 0.6 else text


def compare(before: Path, now: Path) -> str:
    """A markdown table of two runs' csv files (``--out`` prefixes): a row per (pair, role,
    feature), a column per matchup and k, each cell ``before -> now`` (AUC [interval]), bold
    outside [0.4, 0.6]."""
    key = ["pair", "role", "feature"]
    cols, rows = [], None
    for (a, b), surface in MATCHUPS:
        name = matchup_name((a, b), surface)
        old, new = (pd.read_csv(_matchup_path(d, name, ".csv")) for d in (before, now))
        for k in sorted(new["k"].unique()):
            o, n = (t[t["k"] == k].set_index(key) for t in (old, new))
            col = f"{a.split()[-1]} v {b.split()[-1]} k={k}"
            cell = pd.Series({i: f"{_cell(o.loc[i])} → {_cell(n.loc[i])}" for i in n.index},
                             name=col)
            rows = cell.to_frame() if rows is None else rows.join(cell)
            cols.append(col)
    lines = markdown_table(["pair", "role", "feature", *cols],
                           ([pair, role, feature.split("_")[0], *r]
                            for (pair, role, feature), r in rows.iterrows()))
    return "\n".join(lines) + "\n"
