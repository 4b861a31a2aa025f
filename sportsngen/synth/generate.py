"""Whole matches of synthetic tracking: `generate_matches(players, surface, n_points, seed)`.

Points are played through `MatchState`, so the score, server, serving side, ends and second
serves after a fault are right; a point played on a second serve is two rallies (the fault, then
the second-serve rally). Frames are built as numpy arrays per rally and turned into DataFrames
once per match, so memory per worker stays flat in the number of points.

Determinism: match `i` draws from ``SeedSequence(seed, spawn_key=(i,))`` (the i-th child a
`SeedSequence(seed).spawn` would give), whatever the number of worker processes; matches are
concatenated in order and the last one is cut at `n_points` points.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
import pyarrow as pa

from sportsngen.data.points import score_row
from sportsngen.data.tracking import (
    FPS_DEFAULT,
    FRAME_COLUMNS,
    RALLY_COLUMNS,
    SHOT_COLUMNS,
    SURFACES,
    RallyData,
)
from sportsngen.synth.profiles import PlayerProfile, get_profile
from sportsngen.synth.rally import RallyResult, play_rally
from sportsngen.tennis.scoring import MatchFormat, MatchState
from sportsngen.workers import pool_context

TOURNAMENT = "synthetic"
PlayersArg = Sequence["str | PlayerProfile | tuple[str | PlayerProfile, str | PlayerProfile]"]


@dataclass(frozen=True)
class MatchSpec:
    """Everything one match needs; picklable for worker processes."""

    index: int
    players: tuple[PlayerProfile, PlayerProfile]
    surface: str
    fmt: MatchFormat
    seed: int
    max_points: int
    fps: float
    render: bool


@dataclass
class MatchTables:
    """One match's tables, rally ids local to the match (0-based)."""

    frames: pd.DataFrame | None
    rallies: pd.DataFrame
    shots: pd.DataFrame
    n_points: int


def resolve_matchups(players: PlayersArg) -> list[tuple[PlayerProfile, PlayerProfile]]:
    """The matchups of a `players` argument.

    - a list of players (names of named players, or `PlayerProfile`s): a round robin of every
      pair, in order (p0-p1, p0-p2, ..., p1-p2, ...), cycled;
    - a list of pairs ``[(a, b), ...]``: exactly those matches, cycled.
    """
    if isinstance(players, (str, PlayerProfile)) or not isinstance(players, Sequence) \
            or len(players) == 0:
        raise ValueError("players must be a non-empty list of players or of (player, player) "
                         f"pairs, got {players!r}")
    pairs_given = [isinstance(p, (tuple, list)) for p in players]
    if all(pairs_given):
        for p in players:
            if len(p) != 2:
                raise ValueError(f"a matchup must be a pair of players, got {p!r}")
        pairs = [(get_profile(a), get_profile(b)) for a, b in players]
    elif not any(pairs_given):
        profiles = [get_profile(p) for p in players]
        if len(profiles) < 2:
            raise ValueError(f"need at least two players for a match, got {players!r}")
        pairs = list(itertools.combinations(profiles, 2))
    else:
        raise ValueError("players must be all players or all (player, player) pairs, not both")
    for a, b in pairs:
        if a.name == b.name:
            raise ValueError(f"a match needs two different players, got {a.name!r} twice")
    return pairs


def _surfaces(surface: str | Sequence[str]) -> list[str]:
    seq = [surface] if isinstance(surface, str) else list(surface)
    if not seq:
        raise ValueError("surface must be a surface name or a non-empty list of them")
    for s in seq:
        if s not in SURFACES:
            raise ValueError(f"unknown surface {s!r}; known surfaces: {list(SURFACES)}")
    return seq


def match_specs(players: PlayersArg, surface: str | Sequence[str], n_points: int, seed: int,
                fmt: MatchFormat | None = None, fps: float = FPS_DEFAULT,
                render: bool = True) -> Iterator[MatchSpec]:
    """The deterministic sequence of matches `generate_matches` draws from: enough of them to
    reach `n_points` even if every match were won in straight sets and love games (a finite
    list keeps a worker pool from queueing without end)."""
    pairs = resolve_matchups(players)
    surfaces = _surfaces(surface)
    fmt = fmt or MatchFormat()
    shortest = min(n_points, 4 * fmt.games_per_set * fmt.sets_to_win)
    for i in range(-(-n_points // shortest)):
        child = np.random.SeedSequence(seed, spawn_key=(i,))
        yield MatchSpec(i, pairs[i % len(pairs)], surfaces[i % len(surfaces)], fmt,
                        int(child.generate_state(1, dtype=np.uint64)[0]), n_points, fps, render)


def play_match(spec: MatchSpec) -> MatchTables:
    """Play one match (or its first `spec.max_points` points) and build its tables."""
    rng = np.random.default_rng(spec.seed)
    names = (spec.players[0].name, spec.players[1].name)
    match_id = f"synth-{spec.index:06d}"
    state = MatchState.new(spec.fmt, first_server=int(rng.integers(2)))
    rally_rows: list[dict] = []
    shot_parts: list[dict] = []
    frame_parts: list[tuple[int, RallyResult, str, str]] = []
    n_points = 0
    while not state.is_over and n_points < spec.max_points:
        n_points += 1
        server = state.server
        server_end = state.ends[server]
        base = {"match_id": match_id, "point": n_points, "server": names[server],
                "receiver": names[1 - server], "side": state.serving_side,
                "server_end": server_end, "surface": spec.surface, "tournament": TOURNAMENT,
                **score_row(state, server)}
        for serve_number in (1, 2):
            res = play_rally(spec.players[server], spec.players[1 - server], server_end,
                             state.serving_side, serve_number, spec.surface, rng, fps=spec.fps,
                             render=spec.render)
            rid = len(rally_rows)
            winner = "" if res.winner_role is None else \
                names[server if res.winner_role == 0 else 1 - server]
            rally_rows.append({"rally_id": rid, **base, "serve_number": serve_number,
                               "winner": winner, "end_reason": res.end_reason,
                               "end_detail": res.end_detail, "serve_kmh": res.serve_kmh,
                               "rally_length": res.rally_length})
            hitters = (names[server], names[1 - server])
            for k, s in enumerate(res.shots):
                bx, by = s.bounce_xy if s.bounce_xy is not None else (np.nan, np.nan)
                shot_parts.append({
                    "rally_id": rid, "shot_index": k, "frame": int(round(s.t_s * spec.fps)),
                    "hitter": hitters[s.hitter], "stroke": s.stroke, "spin": s.spin,
                    "direction": s.direction, "outcome": s.outcome, "error_kind": s.error_kind,
                    "contact_x": s.contact_m[0], "contact_y": s.contact_m[1],
                    "contact_z": s.contact_m[2], "speed_mps": s.speed_mps,
                    "bounce_x": bx, "bounce_y": by})
            if spec.render:
                frame_parts.append((rid, res, names[server], names[1 - server]))
            if res.end_reason != "fault":
                break
        state = state.point_won(server if res.winner_role == 0 else 1 - server)
    rallies = pd.DataFrame(rally_rows, columns=list(RALLY_COLUMNS))
    shots = pd.DataFrame(shot_parts, columns=list(SHOT_COLUMNS))
    frames = _frames_table(frame_parts, spec.fps) if spec.render else None
    return MatchTables(frames, rallies, shots, n_points)


_TEXT_COLUMNS = ("object", "stroke", "direction", "outcome", "error_kind")


def _frames_table(parts: list[tuple[int, RallyResult, str, str]], fps: float) -> pd.DataFrame:
    """Frames of many rallies: per rally the ball block, then the server's, then the receiver's,
    each in frame order. Built from numpy arrays in one go; each text column from integer codes
    into its few words, made Arrow strings once (one Python string a row to convert cost 6 % of
    the generator's time)."""
    if not parts:
        return pd.DataFrame({c: pd.Series(dtype=d) for c, d in FRAME_COLUMNS.items()})
    words: dict[str, dict[str, int]] = {c: {} for c in _TEXT_COLUMNS}

    def codes(col: str, values) -> np.ndarray:
        lut = words[col]
        return np.array([lut.setdefault(v, len(lut)) for v in values], dtype=np.int64)

    cols: dict[str, list[np.ndarray]] = {c: [] for c in FRAME_COLUMNS}
    for rid, res, server, receiver in parts:
        n = res.n_frames
        frame = np.arange(n)
        xyz = np.concatenate([res.ball_m,
                              np.column_stack([res.players_m[0], np.zeros(n)]),
                              np.column_stack([res.players_m[1], np.zeros(n)])])
        cols["rally_id"].append(np.full(3 * n, rid, dtype=np.int64))
        cols["frame"].append(np.tile(frame, 3))
        cols["t"].append(np.tile(frame / fps, 3))
        cols["object"].append(np.repeat(codes("object", ("ball", server, receiver)), n))
        cols["x"].append(xyz[:, 0])
        cols["y"].append(xyz[:, 1])
        cols["z"].append(xyz[:, 2])
        for key in _TEXT_COLUMNS[1:]:
            per_shot = codes(key, [getattr(s, key) for s in res.shots])
            cols[key].append(np.tile(per_shot[res.frame_shot], 3))
    out = {}
    for c, v in cols.items():
        out[c] = np.concatenate(v)
        if c in words:
            text = pa.array(list(words[c]), type=pa.large_string()).take(pa.array(out[c]))
            out[c] = pd.array(text, dtype=pd.StringDtype())
    return pd.DataFrame(out)


def iter_match_tables(specs: Iterator[MatchSpec], n_points: int, workers: int = 1,
                      progress: bool = False) -> Iterator[MatchTables]:
    """Play matches in order until `n_points` points (the last match cut to fit), yielding each
    match's tables with rally ids made global (consecutive from 0 across matches)."""
    bar = None
    if progress:
        from tqdm.auto import tqdm
        bar = tqdm(total=n_points, unit="pt", desc="synthetic points")
    total = offset = 0
    pool = pool_context(__name__).Pool(workers) if workers > 1 else None
    try:
        results = pool.imap(play_match, specs) if pool is not None else map(play_match, specs)
        for tables in results:
            keep = min(tables.n_points, n_points - total)
            if keep < tables.n_points:
                tables = _cut(tables, keep)
            for df in (tables.frames, tables.rallies, tables.shots):
                if df is not None:
                    df["rally_id"] += offset
            offset += len(tables.rallies)
            total += keep
            if bar is not None:
                bar.update(keep)
            yield tables
            if total >= n_points:
                break
    finally:
        if pool is not None:
            pool.terminate()
        if bar is not None:
            bar.close()


def _cut(t: MatchTables, n_points: int) -> MatchTables:
    keep = t.rallies.loc[t.rallies["point"] <= n_points, "rally_id"]
    sel = lambda df: None if df is None else \
        df[df["rally_id"].isin(keep)].reset_index(drop=True)  # noqa: E731
    return MatchTables(sel(t.frames), sel(t.rallies), sel(t.shots), n_points)


def _workers(workers: int | None) -> int:
    if workers is None:
        return 1
    if int(workers) != workers or workers < 1:
        raise ValueError(f"workers must be a positive integer or None, got {workers!r}")
    return min(int(workers), os.cpu_count() or 1)


def _check_n_points(n_points: int) -> None:
    if isinstance(n_points, bool) or int(n_points) != n_points or n_points <= 0:
        raise ValueError(f"n_points must be a positive integer, got {n_points!r}")


def generate_matches(players: PlayersArg, surface: str | Sequence[str], n_points: int,
                     seed: int, fmt: MatchFormat | None = None, workers: int | None = None,
                     fps: float = FPS_DEFAULT, progress: bool = False) -> RallyData:
    """Synthetic tracking of `n_points` points of tennis.

    `players`: names of named players (`named_profiles()`) or `PlayerProfile`s (e.g. from
    `sample_population`) -> a round robin of all pairs; or a list of pairs
    ``[("Roger Federer", "Rafael Nadal"), ...]`` -> those matches. Matches cycle through the
    matchups and through `surface` (a name, or a list of names for a mix). `fmt` defaults to
    `MatchFormat()` (best of 3 sets, tie-breaks). `workers` > 1 plays matches in that many
    processes; the output is identical for any number of workers.
    """
    _check_n_points(n_points)
    specs = match_specs(players, surface, int(n_points), int(seed), fmt, fps, render=True)
    frames, rallies, shots = [], [], []
    for t in iter_match_tables(specs, int(n_points), _workers(workers), progress):
        frames.append(t.frames)
        rallies.append(t.rallies)
        shots.append(t.shots)
    meta = {"generator": "sportsngen.synth", "seed": int(seed), "n_points": int(n_points)}
    return RallyData.from_tables(pd.concat(frames, ignore_index=True),
                                 pd.concat(rallies, ignore_index=True),
                                 pd.concat(shots, ignore_index=True), fps=fps, meta=meta)


def service_points(players: PlayersArg, surface: str | Sequence[str], n_points: int,
                   seed: int, fmt: MatchFormat | None = None,
                   workers: int | None = None) -> pd.DataFrame:
    """The points table (`sportsngen.data.points`) of `n_points` generated points, without
    building frames: the fast path for calibration and statistics."""
    _check_n_points(n_points)
    specs = match_specs(players, surface, int(n_points), int(seed), fmt, render=False)
    rallies = [t.rallies for t in iter_match_tables(specs, int(n_points), _workers(workers))]
    data = RallyData(frames=pd.DataFrame(columns=list(FRAME_COLUMNS)),
                     rallies=pd.concat(rallies, ignore_index=True).astype(RALLY_COLUMNS),
                     shots=pd.DataFrame(columns=list(SHOT_COLUMNS)))
    return data.points()
