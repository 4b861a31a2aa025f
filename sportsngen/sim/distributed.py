"""A season of simulated matches spread over processes with Lightning `predict` (DDP on CPU:
gloo), gathered into one points table.

    python -m sportsngen.sim.distributed --model model.pt --matchups "A,B;C,D" --surface hard \
        --matches-per-pair 8 --seed 0 --chunk-size 8 --devices 2 --out outputs/season

Matches in one `Simulator.simulate_matches` call share one random stream (lockstep rounds), so
a match's result depends on which matches it is rolled with. To make the table independent of
the number of processes, the season is cut into fixed chunks of `chunk_size` matches; chunk `k`
is always one `simulate_matches` call with seed `seed + k`, whichever process runs it. Chunks
are dealt to ranks round-robin (no padding, so no chunk is simulated twice); each chunk's points
go to `out_dir/chunk_{k:05d}.parquet`, and rank 0 joins them into `out_dir/points.parquet`.

With `devices > 1` and one torch thread a process (the default) the ranks are forked from the
calling process (Lightning's `ddp_fork`): nothing is imported again, and an interactive session
can call `simulate_season`. With more threads a process Lightning re-launches the running script
for the other ranks instead (`ddp`), so call it from a script or this module's command line: a
forked child that starts an OpenMP thread pool hangs when its parent already ran one.
"""

from __future__ import annotations

import argparse
import os
import warnings
from collections.abc import Sequence
from pathlib import Path

import lightning as L
import pandas as pd
import torch
from lightning.pytorch.callbacks import BasePredictionWriter
from torch.utils.data import DataLoader, Dataset

from sportsngen.data.points import as_points_table, empty_points
from sportsngen.sim.simulator import Simulator
from sportsngen.tennis.scoring import MatchFormat

POINTS_FILE = "points.parquet"


def chunk_file(out_dir: str | Path, k: int) -> Path:
    return Path(out_dir) / f"chunk_{k:05d}.parquet"


def season_match_id(index: int, chunk_match_id: str) -> str:
    """The season-wide id of a match: its global index, then the id its chunk's call gave it
    ("00012:sim-1-0004"), unique within the season and the same for any number of processes."""
    return f"{index:05d}:{chunk_match_id}"


def match_index(match_id: pd.Series) -> pd.Series:
    """Global match index from `season_match_id` ids (numeric, so it sorts past 99999)."""
    return match_id.str.split(":", n=1).str[0].astype("int64")


class SeasonChunks(Dataset):
    """Chunk `k` of a season: matches [k * chunk_size, (k + 1) * chunk_size), as a dict with the
    chunk index, its first global match index and its (player1, player2) pairs. Only the chunks
    in `ranks_chunks` are served (a rank's share); all of them by default."""

    def __init__(self, matchups: Sequence[tuple[str, str]], chunk_size: int,
                 ranks_chunks: Sequence[int] | None = None):
        if chunk_size < 1:
            raise ValueError(f"chunk_size must be >= 1, got {chunk_size}")
        self.matchups = [tuple(m) for m in matchups]
        self.chunk_size = int(chunk_size)
        self.n_chunks = -(-len(self.matchups) // self.chunk_size)
        self.chunks = list(range(self.n_chunks)) if ranks_chunks is None else list(ranks_chunks)

    def __len__(self) -> int:
        return len(self.chunks)

    def __getitem__(self, i: int) -> dict:
        k = self.chunks[i]
        lo = k * self.chunk_size
        return {"chunk": k, "start": lo, "matchups": self.matchups[lo:lo + self.chunk_size]}


def _only_item(items: list[dict]) -> dict:
    """Collate for batches of one chunk: the chunk itself (strings stay strings)."""
    return items[0]


class SeasonSimulator(L.LightningModule):
    """`predict_step` simulates one chunk of a season -> its points table. The Simulator is
    loaded once per process in `setup`; the predict dataloader serves this rank's chunks."""

    def __init__(self, model_path: str | Path | None, matchups: Sequence[tuple[str, str]],
                 surface: str, fmt: MatchFormat | None = None, seed: int = 0,
                 chunk_size: int = 8, first_server: int | None = None,
                 sim_kwargs: dict | None = None, threads: int | None = None):
        super().__init__()
        self.model_path = None if model_path is None else str(model_path)
        self.matchups = [tuple(m) for m in matchups]
        self.surface = surface
        self.fmt = fmt
        self.seed = int(seed)
        self.chunk_size = int(chunk_size)
        self.first_server = first_server
        self.sim_kwargs = dict(sim_kwargs or {})
        self.threads = threads
        self.sim: Simulator | None = None

    def setup(self, stage: str) -> None:
        threads = self.threads or (1 if self.trainer.world_size > 1 else None)
        if threads:
            # Intra-op threads beyond the free cores spin against each other (measured: a
            # tiny-model season 10-30x slower with 2 threads than 1 on a busy 2-core machine).
            torch.set_num_threads(threads)
        if self.sim is None:
            self.sim = Simulator.from_pretrained(self.model_path, **self.sim_kwargs)

    def predict_dataloader(self) -> DataLoader:
        rank, world = self.trainer.global_rank, self.trainer.world_size
        n_chunks = SeasonChunks(self.matchups, self.chunk_size).n_chunks
        mine = range(rank, n_chunks, world)
        return DataLoader(SeasonChunks(self.matchups, self.chunk_size, mine), batch_size=1,
                          shuffle=False, collate_fn=_only_item)

    def predict_step(self, batch: dict, batch_idx: int = 0) -> pd.DataFrame:
        return simulate_chunk(self.sim, batch["chunk"], batch["start"], batch["matchups"],
                              self.surface, self.fmt, self.seed, self.first_server)


def simulate_chunk(sim: Simulator, k: int, start: int, matchups: Sequence[tuple[str, str]],
                   surface: str, fmt: MatchFormat | None, seed: int,
                   first_server: int | None = None) -> pd.DataFrame:
    """Chunk `k` (matches from global index `start`) in one call with seed `seed + k` -> its
    points table, match ids made season-wide with `season_match_id`."""
    results = sim.simulate_matches(list(matchups), surface, fmt=fmt, seed=seed + k,
                                   first_server=first_server, progress=False)
    tables = []
    for i, res in enumerate(results):
        pts = res.points.copy()
        pts["match_id"] = [season_match_id(start + i, m) for m in pts["match_id"]]
        tables.append(pts)
    return as_points_table(pd.concat(tables, ignore_index=True))


class ChunkWriter(BasePredictionWriter):
    """Writes each chunk's points table to `out_dir/chunk_{k:05d}.parquet` as it is done."""

    def __init__(self, out_dir: str | Path):
        super().__init__(write_interval="batch")
        self.out_dir = Path(out_dir)

    def write_on_batch_end(self, trainer, pl_module, prediction, batch_indices, batch,
                           batch_idx, dataloader_idx=0) -> None:
        path = chunk_file(self.out_dir, batch["chunk"])
        tmp = path.with_suffix(f".tmp{trainer.global_rank}")
        prediction.to_parquet(tmp, index=False)
        os.replace(tmp, path)       # rank 0 never reads a half-written file


def gather_chunks(out_dir: str | Path, n_chunks: int) -> pd.DataFrame:
    """Join chunk files 0..n_chunks-1 (stale ones beyond are ignored) -> one points table
    sorted by global match index, then point."""
    tables = [pd.read_parquet(chunk_file(out_dir, k)) for k in range(n_chunks)]
    if not tables:
        return empty_points()
    pts = as_points_table(pd.concat(tables, ignore_index=True))
    order = pd.DataFrame({"m": match_index(pts["match_id"]), "p": pts["point"]})
    idx = order.sort_values(["m", "p"], kind="stable").index
    return pts.loc[idx].reset_index(drop=True)


def season_strategy(devices: int, threads: int | None) -> str:
    """Lightning's strategy for a season on `devices` CPU processes of `threads` torch threads
    each (None: 1 when devices > 1). Forking the ranks (`ddp_fork`) skips the re-launched
    script's imports: the DDP season CLI of the tests 17.2 / 19.0 -> 11.9 / 12.4 s of wall time,
    21.1 / 22.3 -> 14.0 / 14.7 s of CPU over all its processes, the same table. It is safe only
    for one thread a rank (see the module's docstring), so more threads re-launch (`ddp`)."""
    if devices <= 1:
        return "auto"
    return "ddp_fork" if (threads or 1) == 1 else "ddp"


def simulate_season(model_path: str | Path | None, matchups: Sequence[tuple[str, str]],
                    surface: str, fmt: MatchFormat | None = None, seed: int = 0,
                    chunk_size: int = 8, devices: int = 1,
                    out_dir: str | Path = "outputs/season", first_server: int | None = None,
                    sim_kwargs: dict | None = None,
                    threads: int | None = None) -> pd.DataFrame | None:
    """Simulate every (player1, player2) of `matchups` with the learned engine on `devices` CPU
    processes -> the points table of all matches (also `out_dir/points.parquet`) on rank 0,
    None on the other ranks. The table is the same for any `devices` (fixed chunks, seed
    `seed + k` for chunk `k`). `sim_kwargs` go to `Simulator.from_pretrained`
    (max_duration_s, max_retries, top_p_player, ...). `threads`: torch threads per process
    (None: 1 when devices > 1, torch's default otherwise); the caller's setting is restored."""
    matchups = [tuple(m) for m in matchups]
    if not matchups:
        raise ValueError("matchups must not be empty")
    if devices < 1:
        raise ValueError(f"devices must be >= 1, got {devices}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    module = SeasonSimulator(model_path, matchups, surface, fmt, seed, chunk_size,
                             first_server, sim_kwargs, threads)
    trainer = L.Trainer(accelerator="cpu", devices=devices,
                        strategy=season_strategy(devices, threads), logger=False,
                        enable_checkpointing=False, enable_progress_bar=False,
                        enable_model_summary=False, use_distributed_sampler=False,
                        callbacks=[ChunkWriter(out_dir)])
    saved_threads = torch.get_num_threads()
    try:
        with warnings.catch_warnings():
            # A chunk is seconds of work; loader workers would only add start-up time.
            warnings.filterwarnings("ignore", message=".*does not have many workers.*")
            trainer.predict(module, return_predictions=False)
    finally:
        torch.set_num_threads(saved_threads)
    trainer.strategy.barrier("simulate_season")      # every rank's chunks are on disk
    if trainer.global_rank != 0:
        return None
    pts = gather_chunks(out_dir, SeasonChunks(matchups, chunk_size).n_chunks)
    pts.to_parquet(out_dir / POINTS_FILE, index=False)
    return pts


def parse_matchups(text: str) -> list[tuple[str, str]]:
    """"A,B;C,D" -> [("A", "B"), ("C", "D")]."""
    pairs = []
    for item in text.split(";"):
        if not item.strip():
            continue
        names = [s.strip() for s in item.split(",")]
        if len(names) != 2 or not all(names):
            raise ValueError(f"matchup {item!r} is not 'player1,player2'")
        pairs.append((names[0], names[1]))
    return pairs


def main(argv: Sequence[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", default=None, help="model file or bundled name (default: bundled)")
    ap.add_argument("--matchups", required=True, help='"player1,player2;player3,player4;..."')
    ap.add_argument("--surface", default="hard")
    ap.add_argument("--matches-per-pair", type=int, default=1,
                    help="each pair plays this many matches, one after another in the season")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--chunk-size", type=int, default=8)
    ap.add_argument("--devices", type=int, default=1, help="CPU processes (DDP, gloo)")
    ap.add_argument("--threads", type=int, default=None,
                    help="torch threads per process (default: 1 when devices > 1)")
    ap.add_argument("--out", default="outputs/season")
    ap.add_argument("--first-server", type=int, default=None, choices=(0, 1))
    ap.add_argument("--best-of", type=int, default=3)
    ap.add_argument("--games-per-set", type=int, default=6)
    ap.add_argument("--tiebreak-at", type=int, default=6)
    ap.add_argument("--tiebreak-points", type=int, default=7)
    ap.add_argument("--final-set", default="tiebreak7")
    ap.add_argument("--no-ad", action="store_true")
    ap.add_argument("--match-tiebreak-points", type=int, default=None)
    ap.add_argument("--max-duration-s", type=float, default=None)
    ap.add_argument("--max-retries", type=int, default=None)
    ap.add_argument("--top-p", type=float, default=None, help="nucleus for players and ball")
    ap.add_argument("--batch-size", type=int, default=None, help="rallies per rollout batch")
    ap.add_argument("--no-physical-limits", action="store_true",
                    help="accept every sampled frame (no reach, jolt or net rules)")
    a = ap.parse_args(argv)
    fmt = MatchFormat(best_of=a.best_of, games_per_set=a.games_per_set,
                      tiebreak_at=a.tiebreak_at, tiebreak_points=a.tiebreak_points,
                      final_set=a.final_set, no_ad=a.no_ad,
                      match_tiebreak_points=a.match_tiebreak_points)
    sim_kwargs = {k: v for k, v in (("max_duration_s", a.max_duration_s),
                                    ("max_retries", a.max_retries),
                                    ("top_p_player", a.top_p), ("top_p_ball", a.top_p),
                                    ("batch_size", a.batch_size)) if v is not None}
    if a.no_physical_limits:
        sim_kwargs["physical_limits"] = False
    season = [p for p in parse_matchups(a.matchups) for _ in range(a.matches_per_pair)]
    pts = simulate_season(a.model, season, a.surface, fmt=fmt, seed=a.seed,
                          chunk_size=a.chunk_size, devices=a.devices, out_dir=a.out,
                          first_server=a.first_server, sim_kwargs=sim_kwargs,
                          threads=a.threads)
    if pts is not None:
        print(f"{pts['match_id'].nunique()} matches, {len(pts)} points -> "
              f"{Path(a.out) / POINTS_FILE}")


if __name__ == "__main__":
    main()
