"""Read where the players' offsets fall inside the player head's bins, from a model file's
recorded rallies, and write the table into a copy of the file (`extra.player_bin_quantiles`,
`sportsngen.model.bin_quantiles`) with the sampling default that places every player draw by it
(`player_bin_quantiles=true`).

    .venv/bin/python scripts/fit_player_bins.py --model MODEL --more-data synthetic_named \\
        --out OUT.pt

The offsets read are the file's training split and, with --more-data, every rally of that data
config, in the model's frame; a bin with fewer than --min-offsets keeps the uniform spread.
"""

from __future__ import annotations

import numpy as np

from sportsngen.model.bin_quantiles import (
    MIN_OFFSETS,
    N_QUANTILES,
    fit_bin_quantiles,
    player_offsets,
)
from sportsngen.model.export import load_model
from sportsngen.sim.simulator import model_path
from sportsngen.train.evaluate import training_rally_data
from sportsngen.train.table_cli import rule_table_parser, write_rule_tables


def main() -> None:
    args = rule_table_parser(__doc__, (
        ("--quantiles", int, N_QUANTILES, "quantiles stored per bin (0, 1/Q, ..., 1)"),
        ("--min-offsets", int, MIN_OFFSETS,
         "a bin's offsets for its own spread (fewer: uniform)"))).parse_args()
    src = model_path(args.model)
    model = load_model(src)[0]
    server_frame = model.cfg.frame != "world"
    try:
        parts = training_rally_data(src, args.more_data)
        offsets = np.concatenate([player_offsets(p.frames, p.rallies, server_frame)
                                  for p in parts])
        edges = model.player_bins.edges.double().numpy()
        table = fit_bin_quantiles(offsets, edges, args.quantiles, args.min_offsets)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    mid = table.shape[1] // 2
    print(f"{len(offsets)} player offsets in the model's frame")
    for k in range(mid, mid + 8):
        print(f"bin {k}: [{edges[1, k]:.4f}, {edges[1, k + 1]:.4f}] m, lateral quantiles "
              f"{' '.join(f'{v:.4f}' for v in table[1, k, ::args.quantiles // 4 or 1])}")
    out = write_rule_tables(src, args.out, {"player_bin_quantiles": table.tolist()},
                            player_bin_quantiles=True)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
