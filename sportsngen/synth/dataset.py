"""Config-driven synthetic datasets: generate on first use, then load from a disk cache.

`load_synthetic(cfg)` reads a ``conf/data/synthetic_*.yaml`` config (a dict or an OmegaConf
node), and returns a `RallyData`. The first call generates the data (tqdm progress bar) and
writes it under ``$SPORTSNGEN_CACHE`` (default ``~/.cache/sportsngen``) in a folder keyed by a
hash of the config, of the generator version and of the calibrated profiles; later calls load
it. Matches are streamed to Parquet one at a time, so generating uses memory flat in the number
of points (loading the finished dataset of course needs room for it).

Config fields (see ``conf/data/synthetic_small.yaml``):

- ``source: synthetic``, ``name``
- ``players.named``: named players (`named_profiles()`); ``players.population``: how many
  population players per gender (``{men: 20, women: 8}``); ``players.population_seed``;
  ``players.population_prefix`` (optional: names "<prefix> M 000", ... instead of "Pop M 000",
  for players no model trained on the default names has seen)
- ``surfaces``: list of surfaces, cycled over matches
- ``n_points``, ``seed``, ``workers`` (null: 1 process), ``fps``
- ``format``: `MatchFormat` fields (``best_of``, ``final_set``, ...)

Matchups: a round robin within each gender (named and population players together), in an
order shuffled by the seed, cycled.
"""

from __future__ import annotations

import errno
import hashlib
import itertools
import json
import os
import re
import shutil
import socket
import tempfile
import uuid
import warnings
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from sportsngen.data.tracking import (
    FRAME_COLUMNS,
    RALLY_COLUMNS,
    SHOT_COLUMNS,
    RallyData,
    TrackingDataError,
)
from sportsngen.synth.generate import _check_n_points, _workers, iter_match_tables, match_specs
from sportsngen.synth.profiles import (
    GENDERS,
    PROFILES_JSON,
    PlayerProfile,
    get_profile,
    sample_population,
)
from sportsngen.tennis.scoring import MatchFormat

GENERATOR_VERSION = "6.4"  # bump when the generated tracks change (3: still through the toss;
#                           4: players run at balls they cannot reach; 5: contacts from
#                           0.3-1.2 m beside the body; 6: causal movement, one shot-cycle
#                           kernel, ball flights and positions calibrated to Hawk-Eye;
#                           6.1: the server settles by the return, the serve's initiative
#                           holds through the point, slower pace fallbacks, recalibrated;
#                           6.2: clay passes on less of the serve's weight, each returner's
#                           composure under a rushed return, recalibrated;
#                           6.3: per-surface profile fields (Nadal's second-serve return
#                           depth, composure, clay return pace), Williams' flatter ball;
#                           6.4: Federer per surface: less rally noise and serve initiative
#                           on hard, more arc and more noise on clay, his serve mix on each;
#                           Nadal's composure on hard 2.85 -> 3.1)
_ARROW = {"int64": pa.int64(), "float64": pa.float64(), "string": pa.string(), "bool": pa.bool_()}


def _plain(cfg) -> dict:
    """A plain dict from a dict or an OmegaConf node."""
    try:
        from omegaconf import DictConfig, OmegaConf
        if isinstance(cfg, DictConfig):
            return OmegaConf.to_container(cfg, resolve=True)
    except ImportError:  # pragma: no cover - hydra-core is a dependency
        pass
    if not isinstance(cfg, dict):
        raise ValueError(f"synthetic data config must be a mapping, got {type(cfg).__name__}")
    return json.loads(json.dumps(cfg))


def cache_root() -> Path:
    """``$SPORTSNGEN_CACHE`` or ``~/.cache/sportsngen``."""
    env = os.environ.get("SPORTSNGEN_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "sportsngen"


def config_key(cfg) -> str:
    """Hash of what determines the data: the config (minus workers), the generator version and
    the calibrated profiles."""
    c = _plain(cfg)
    c.pop("workers", None)
    c.pop("cache_dir", None)
    blob = json.dumps(c, sort_keys=True) + GENERATOR_VERSION + PROFILES_JSON.read_text()
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def matchups(cfg) -> list[tuple[PlayerProfile, PlayerProfile]]:
    """The config's matchups: a round robin within each gender, shuffled by the seed."""
    c = _plain(cfg)
    players = c.get("players") or {}
    named = [get_profile(n) for n in players.get("named") or []]
    population = players.get("population") or {}
    if isinstance(population, int):
        population = {"men": population}
    unknown = sorted(set(population) - set(GENDERS))
    if unknown:
        raise ValueError(f"players.population genders {unknown} unknown; use {list(GENDERS)}")
    pop_seed = int(players.get("population_seed", 0))
    prefix = players.get("population_prefix")
    pairs = []
    for k, gender in enumerate(GENDERS):
        group = [p for p in named if p.gender == gender]
        n_pop = int(population.get(gender, 0))
        if n_pop:
            group += sample_population(
                n_pop, seed=pop_seed + k, gender=gender,
                prefix=None if prefix is None else f"{prefix} {gender[0].upper()}")
        pairs += list(itertools.combinations(group, 2))
    if not pairs:
        raise ValueError("the config's players give no matchup: list at least two named players "
                         "of one gender or ask for population players")
    order = np.random.default_rng(int(c.get("seed", 0))).permutation(len(pairs))
    return [pairs[i] for i in order]


def _writer_schema(columns: dict[str, str]) -> pa.Schema:
    return pa.schema([(name, _ARROW[dtype]) for name, dtype in columns.items()])


def generate_to_folder(cfg, folder: str | Path, progress: bool = True) -> Path:
    """Generate the dataset of `cfg` into `folder` (Parquet, the `RallyData.save` layout),
    streaming match by match."""
    c = _plain(cfg)
    n_points = c.get("n_points")
    _check_n_points(n_points)
    fmt = MatchFormat(**(c.get("format") or {}))
    fps = float(c.get("fps", 25.0))
    specs = match_specs(matchups(c), c.get("surfaces", "hard"), int(n_points),
                        int(c.get("seed", 0)), fmt, fps, render=True)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    tables = {"frames": FRAME_COLUMNS, "rallies": RALLY_COLUMNS, "shots": SHOT_COLUMNS}
    writers = {name: pq.ParquetWriter(folder / f"{name}.parquet", _writer_schema(cols))
               for name, cols in tables.items()}
    try:
        for t in iter_match_tables(specs, int(n_points), _workers(c.get("workers")), progress):
            for name, df in (("frames", t.frames), ("rallies", t.rallies), ("shots", t.shots)):
                df = df.astype(tables[name])
                writers[name].write_table(pa.Table.from_pandas(df, schema=writers[name].schema,
                                                               preserve_index=False))
    finally:
        for w in writers.values():
            w.close()
    meta = {"fps": fps, "generator": "sportsngen.synth", "config": c,
            "generator_version": GENERATOR_VERSION}
    (folder / "meta.json").write_text(json.dumps(meta, indent=2, default=str))
    return folder


def load_synthetic(cfg, progress: bool = True) -> RallyData:
    """The synthetic dataset of `cfg`, generated on first use and cached on disk.

    A finished cache is checked before it is trusted (its files against the checksums written
    with it, then the load's validation); a damaged one is regenerated with a warning."""
    c = _plain(cfg)
    if c.get("source", "synthetic") != "synthetic":
        raise ValueError(f"load_synthetic needs a config with source: synthetic, "
                         f"got {c.get('source')!r}")
    root = Path(c["cache_dir"]).expanduser() if c.get("cache_dir") else cache_root()
    folder = root / "synthetic" / f"{c.get('name', 'synthetic')}-{config_key(c)}"
    folder.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_tmp(folder.parent)
    if folder.exists():
        why = cache_damage(folder)
        if why is None:
            try:
                return RallyData.load(folder)
            except (TrackingDataError, OSError) as exc:
                why = str(exc)
        warnings.warn(f"synthetic cache {folder} is damaged ({why}); regenerating it",
                      stacklevel=2)
        _move_aside(folder)
    tmp = Path(tempfile.mkdtemp(prefix=f"{folder.name}.tmp{os.getpid()}-",
                                suffix=f"@{socket.gethostname()}", dir=folder.parent))
    try:
        generate_to_folder(c, tmp, progress=progress)
        write_checksums(tmp)
        publish(tmp, folder)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return RallyData.load(folder)


# --- the cache's integrity and publication ---------------------------------------------------
# A cache is generated into a temporary folder "<name>.tmp<pid>-<random>@<host>" beside it and
# published by one rename, which is atomic and refuses a non-empty target: so a reader never
# sees half a cache, and when two processes finish the same cache, the second finds the first's
# (verified by its checksums) and drops its own copy.

CHECKSUMS = "checksums.json"


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(1 << 22):
            h.update(chunk)
    return h.hexdigest()


def write_checksums(folder: Path) -> None:
    """Record the SHA-256 of every file of a generated folder in checksums.json."""
    sums = {p.name: _sha256(p) for p in sorted(folder.iterdir()) if p.name != CHECKSUMS}
    (folder / CHECKSUMS).write_text(json.dumps(sums, indent=2))


def cache_damage(folder: Path) -> str | None:
    """Why a finished cache folder cannot be trusted, or None. A cache written before
    checksums were recorded has none: only the load checks it."""
    if not (folder / "meta.json").is_file():
        return "no meta.json"
    path = folder / CHECKSUMS
    if not path.is_file():
        return None
    try:
        sums = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError):
        return f"{CHECKSUMS} is not valid JSON"
    for name, digest in sums.items():
        if not (folder / name).is_file():
            return f"{name} is missing"
        if _sha256(folder / name) != digest:
            return f"{name} does not match its checksum"
    return None


def publish(tmp: Path, folder: Path, attempts: int = 3) -> None:
    """Rename the finished `tmp` to `folder`. If another process published it first, its
    copy is kept (ours is left for the caller to remove); a damaged copy in the way is moved
    aside and the rename tried again."""
    for _ in range(attempts):
        try:
            os.rename(tmp, folder)
            return
        except OSError as exc:
            if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                raise
        if cache_damage(folder) is None:
            return               # the other process's copy, verified
        _move_aside(folder)
    raise RuntimeError(f"could not publish the synthetic cache {folder}: another copy kept "
                       f"appearing damaged in its place ({attempts} attempts)")


def _move_aside(folder: Path) -> None:
    """Rename a damaged cache to a temporary name (so that a crash leaves a folder that
    `remove_stale_tmp` recognises), then delete it. Gone already: another process did it."""
    aside = folder.with_name(f"{folder.name}.tmp{os.getpid()}-stale{uuid.uuid4().hex[:8]}"
                             f"@{socket.gethostname()}")
    try:
        os.rename(folder, aside)
    except FileNotFoundError:
        return
    shutil.rmtree(aside, ignore_errors=True)


_TMP_NAME = re.compile(r"\.tmp(\d+)(?:-[^@]*)?(?:@(.+))?$")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:      # someone else's live process
        return True
    return True


def remove_stale_tmp(root: Path) -> list[Path]:
    """Delete the temporary folders under `root` left by generations on this host whose
    process is dead (killed mid-generation) -> the folders removed."""
    removed = []
    host = socket.gethostname()
    for path in root.iterdir() if root.is_dir() else ():
        m = _TMP_NAME.search(path.name)
        if m and path.is_dir() and (m.group(2) or host) == host and not _alive(int(m.group(1))):
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path)
    return removed
