"""The gallery of `docs/synthetic-data.md`: four generated rallies drawn with
`sportsngen.viz.court_plot.plot_rally` (an ace, a long rally, a net approach, a forced error).

    python scripts/render_gallery.py [--points 300] [--seed 4] [--out docs/figures/synthetic]

Rallies of `generate_matches([("Roger Federer", "Rafael Nadal")], "grass", points, seed)`; each
picture is the first rally of its kind (the longest for the long rally).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.synth import generate_matches
from sportsngen.viz.court_plot import plot_rally


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=300)
    ap.add_argument("--seed", type=int, default=4)
    ap.add_argument("--out", type=Path, default=Path("docs/figures/synthetic"))
    args = ap.parse_args()
    data = generate_matches([("Roger Federer", "Rafael Nadal")], "grass", args.points,
                            seed=args.seed)
    r, s = data.rallies, data.shots
    volleyed = s.loc[s["stroke"].str.contains("volley"), "rally_id"]
    kinds = {
        "ace": r.loc[r["end_reason"] == "ace", "rally_id"],
        "long_rally": r.loc[[r["rally_length"].idxmax()], "rally_id"],
        "net_play": volleyed,
        "forced_error": r.loc[(r["end_reason"] == "forced_error") & (r["rally_length"] >= 4),
                              "rally_id"],
    }
    missing = [name for name, ids in kinds.items() if ids.empty]
    if missing:
        raise SystemExit(f"no {', '.join(missing)} rally in {args.points} points (seed "
                         f"{args.seed}): try more --points")
    picks = {name: ids.iloc[0] for name, ids in kinds.items()}
    args.out.mkdir(parents=True, exist_ok=True)
    for name, rid in picks.items():
        row = r.set_index("rally_id").loc[rid]
        plot_rally(data, int(rid), args.out / f"{name}.png")
        print(f"{name}: rally {rid}, {row['rally_length']} shots, {row['end_reason']}")


if __name__ == "__main__":
    main()
