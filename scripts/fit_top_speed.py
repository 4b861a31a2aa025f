"""Read each player's top running speed from a model file's recorded rallies and write it into a
copy of the file (`extra.top_speed`, `sportsngen.sim.top_speed`) with the sampling default
that bounds every rollout frame by it (`player_top_speed=true`).

    .venv/bin/python scripts/fit_top_speed.py --model MODEL --more-data synthetic_named \\
        --out OUT.pt

The frames read are the file's training split and, with --more-data, every rally of that data
config; a player's top speed is the --quantile of his frame-to-frame speeds, and a player with
fewer than --min-frames frames plays the pooled one.
"""

from __future__ import annotations

from sportsngen.sim.simulator import model_path
from sportsngen.sim.top_speed import MIN_FRAMES, QUANTILE, top_speeds_from_data
from sportsngen.train.evaluate import training_rally_data
from sportsngen.train.table_cli import rule_table_parser, write_rule_tables


def main() -> None:
    args = rule_table_parser(__doc__, (
        ("--quantile", float, QUANTILE, "a player's top speed: this quantile of his frame speeds"),
        ("--min-frames", int, MIN_FRAMES,
         "a player's frames for his own row (fewer: the pooled one)"))).parse_args()
    src = model_path(args.model)
    try:
        parts = training_rally_data(src, args.more_data)
        table, speeds = top_speeds_from_data(parts, args.quantile, args.min_frames)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    print(f"{len(speeds)} player frames; pooled top speed {table.pooled_mps:.2f} m/s")
    counts = speeds["player"].value_counts()
    for name, v in sorted(table.players_mps.items()):
        print(f"{name:<20} {counts[name]:8d} frames: top speed {v:.2f} m/s")
    out = write_rule_tables(src, args.out, {"top_speed": table.to_dict()}, player_top_speed=True)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
