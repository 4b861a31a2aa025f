"""The tracking schema: `RallyData`, three pandas tables saved as Parquet files in one folder.

What users bring and what the synthetic generator writes. Units: metres, seconds, m/s.

- ``frames``: one row per (rally_id, frame, object). ``t`` is seconds from the rally start,
  ``object`` is ``"ball"`` or a player id; players are 2-D (z = 0), the ball is 3-D. The shot
  labels (``stroke``, ``direction``, ``outcome``, ``error_kind``) are those of the shot in
  progress at that frame.
- ``rallies``: one row per rally. A rally is one serve and what follows it, so a point played on
  a second serve has two rallies: the first-serve fault (``end_reason == "fault"``, no winner)
  and the second-serve rally. ``point`` numbers points within a match (1-based).
- ``shots``: one row per racket contact.

Reading validates every table and raises `TrackingDataError` naming the rally and the row;
nothing is dropped unless `repair=True`, which drops the offending rallies and reports them.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from sportsngen.data.points import as_points_table
from sportsngen.errors import TrackingDataError
from sportsngen.tennis.rally import END_DETAILS, END_REASONS
from sportsngen.tennis.scoring import point_label

FPS_DEFAULT = 25.0
MAX_ABS_X_M = 30.0  # anything further from the net is off any plausible court
MAX_ABS_Y_M = 20.0
MAX_Z_M = 30.0

SURFACES = ("hard", "clay", "grass")
STROKES = ("none", "serve", "forehand", "backhand", "forehand_volley", "backhand_volley",
           "overhead")
SPINS = ("none", "flat", "topspin", "slice", "kick")
DIRECTIONS = ("none", "wide", "body", "T", "cross_court", "down_the_line", "middle",
              "inside_out", "inside_in")
OUTCOMES = ("none", "in_play", "winner", "error")
ERROR_KINDS = ("none", "forced", "unforced", "fault")

FRAME_COLUMNS: dict[str, str] = {
    "rally_id": "int64", "frame": "int64", "t": "float64", "object": "string",
    "x": "float64", "y": "float64", "z": "float64",
    "stroke": "string", "direction": "string", "outcome": "string", "error_kind": "string",
}
RALLY_COLUMNS: dict[str, str] = {
    "rally_id": "int64", "match_id": "string", "point": "int64",
    "server": "string", "receiver": "string", "serve_number": "int64",
    "side": "string",            # "deuce" or "ad": the server's side of the centre mark
    "server_end": "int64",       # sign of x of the server's baseline (+1 or -1)
    "surface": "string", "tournament": "string",
    "set_no": "int64", "server_sets": "int64", "receiver_sets": "int64",
    "server_games": "int64", "receiver_games": "int64",
    "server_points": "int64", "receiver_points": "int64",  # points won in the game/tie-break
    "in_tiebreak": "bool",
    "score": "string",           # score before the point, from the match's first player (score_str)
    "winner": "string",          # player id; "" for a first-serve fault
    "end_reason": "string", "end_detail": "string",
    "serve_kmh": "float64",      # speed of this rally's serve at contact
    "rally_length": "int64",     # slam definition: shots that landed in (0 on a double fault)
}
SHOT_COLUMNS: dict[str, str] = {
    "rally_id": "int64", "shot_index": "int64", "frame": "int64", "hitter": "string",
    "stroke": "string", "spin": "string", "direction": "string", "outcome": "string",
    "error_kind": "string",
    "contact_x": "float64", "contact_y": "float64", "contact_z": "float64",
    "speed_mps": "float64",
    "bounce_x": "float64", "bounce_y": "float64",  # NaN where the ball never bounced
}

# Name columns that must not be empty (categories are checked against their vocabularies).
_NAME_COLUMNS: dict[str, tuple[str, ...]] = {
    "frames": ("object",), "shots": ("hitter",),
    "rallies": ("match_id", "server", "receiver", "tournament", "score", "winner"),
}
_CATEGORIES: dict[str, dict[str, tuple[str, ...]]] = {
    "frames": {"stroke": STROKES, "direction": DIRECTIONS, "outcome": OUTCOMES,
               "error_kind": ERROR_KINDS},
    "rallies": {"surface": SURFACES, "end_reason": END_REASONS, "end_detail": END_DETAILS,
                "side": ("deuce", "ad")},
    "shots": {"stroke": STROKES, "spin": SPINS, "direction": DIRECTIONS, "outcome": OUTCOMES,
              "error_kind": ERROR_KINDS},
}


STEP_TOLERANCE = 0.1      # a frame's t step may be off 1/fps by this fraction (jitter)
FPS_TOLERANCE = 0.02      # the median t step must match meta.json's fps this closely


def _where(origin: str | None, table: str) -> str:
    return f"{origin}/{table}.parquet" if origin else table


def _first_bad(values: pd.Series, bad: np.ndarray) -> str:
    i = int(np.flatnonzero(bad)[0])
    value = values.iat[i]
    value = value.item() if isinstance(value, np.generic) else value
    more = f" (and {int(bad.sum()) - 1} more rows)" if bad.sum() > 1 else ""
    return f"row {i} holds {value!r}{more}"


_STRING = pd.StringDtype()


def _cast_column(s: pd.Series, dtype: str, where: str, col: str) -> pd.Series:
    """One column as `dtype`, refusing what a plain astype would silently change: 0.5 -> 0 in an
    integer column, "False" -> True or None -> False in a boolean one."""
    what = {"int64": "integers", "float64": "numbers", "bool": "booleans (True/False)"}
    if dtype == "string":
        # "str" (NaN for missing) also compares equal to "string": only the exact dtype is kept.
        return s if s.dtype == _STRING else s.astype("string")
    if s.dtype == dtype:                # already right: a table read back or cast before
        return s
    if (dtype == "int64" and pd.api.types.is_integer_dtype(s) and not s.isna().any()) or \
            (dtype == "float64" and pd.api.types.is_float_dtype(s)):
        return s.astype(dtype)          # another width of the same kind: no values to check
    if dtype == "bool":
        if pd.api.types.is_bool_dtype(s) and not s.isna().any():
            return s.astype(bool)
        ok = s.map(lambda v: isinstance(v, (bool, np.bool_)) or
                   (isinstance(v, (int, np.integer)) and v in (0, 1))).to_numpy(dtype=bool)
    elif pd.api.types.is_bool_dtype(s):
        ok = np.zeros(len(s), dtype=bool)
    else:
        num = pd.to_numeric(s, errors="coerce").to_numpy(dtype="float64", na_value=np.nan)
        if dtype == "float64":
            ok = ~np.isnan(num) | s.isna().to_numpy()   # NaN stays NaN; text does not
        else:
            with np.errstate(invalid="ignore"):
                ok = np.isfinite(num) & (num == np.round(num))
    if not ok.all():
        raise TrackingDataError(f"{where}: column {col!r} must hold {what[dtype]}; "
                                f"{_first_bad(s, ~ok)}")
    if dtype == "bool":
        return s.map(bool).astype(bool)
    return pd.to_numeric(s).astype(dtype)


def _cast(df: pd.DataFrame, columns: dict[str, str], table: str, keep_extra: bool = False,
          origin: str | None = None) -> pd.DataFrame:
    where = _where(origin, table)
    if not isinstance(df, pd.DataFrame):
        raise TrackingDataError(f"{where} must be a pandas DataFrame, got {type(df).__name__}")
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise TrackingDataError(f"{where}: missing columns {missing}")
    twice = sorted({str(c) for c in df.columns[df.columns.duplicated()]})
    if twice:
        raise TrackingDataError(f"{where}: columns named more than once: {twice}")
    extra = [c for c in df.columns if c not in columns] if keep_extra else []
    # One frame built from its columns' arrays: setting them one by one on a copy took 13 ms
    # for a simulated rally's three tables, most of the tiny model's per-rally assembly.
    out = {col: _cast_column(df[col], dtype, where, col).array for col, dtype in columns.items()}
    out.update({col: df[col].array for col in extra})
    return pd.DataFrame(out, index=pd.RangeIndex(len(df)), copy=True)


def _per_rally(rallies: pd.DataFrame, rally_id: pd.Series, col: str) -> pd.Series:
    """`rallies[col]` of each row's rally ("" where the rally is not in the table)."""
    first = rallies.drop_duplicates("rally_id").set_index("rally_id")[col]
    return rally_id.map(first).astype("string").fillna("")


def _problems(frames: pd.DataFrame, rallies: pd.DataFrame, shots: pd.DataFrame,
              fps: float, fps_source: str = "fps") -> list[tuple[int, str]]:
    """Every schema violation as (rally_id, message). A frame rate that the `t` column
    contradicts is a property of the whole dataset: it raises at once."""
    found: list[tuple[int, str]] = []

    def flag(table: str, df: pd.DataFrame, bad: np.ndarray, what: str) -> None:
        for idx in np.flatnonzero(bad):
            found.append((int(df["rally_id"].iat[idx]),
                          f"{table} row {idx} (rally {int(df['rally_id'].iat[idx])}): {what}"))

    for name, df in (("frames", frames), ("rallies", rallies), ("shots", shots)):
        for col, allowed in _CATEGORIES[name].items():
            bad = ~df[col].isin(allowed).to_numpy()
            if bad.any():
                vals = sorted(set(df.loc[bad, col].astype(str)))
                flag(name, df, bad, f"unknown {col} {vals[:5]}; allowed: {list(allowed)}")
        for col in _NAME_COLUMNS[name]:
            flag(name, df, df[col].isna().to_numpy(), f"missing {col}")

    dup = rallies["rally_id"].duplicated().to_numpy()
    flag("rallies", rallies, dup, "duplicate rally_id")
    flag("rallies", rallies, (rallies["server"] == rallies["receiver"]).fillna(False)
         .to_numpy(bool), "server and receiver are the same player")
    for name, df in (("frames", frames), ("shots", shots)):
        orphan = ~df["rally_id"].isin(rallies["rally_id"]).to_numpy()
        flag(name, df, orphan, "rally_id not in the rallies table")

    xyz = frames[["x", "y", "z"]].to_numpy()
    flag("frames", frames, ~np.isfinite(xyz).all(axis=1), "NaN or infinite coordinate")
    with np.errstate(invalid="ignore"):
        off = (np.abs(xyz[:, 0]) > MAX_ABS_X_M) | (np.abs(xyz[:, 1]) > MAX_ABS_Y_M) | \
              (xyz[:, 2] > MAX_Z_M) | (xyz[:, 2] < -0.5)
    flag("frames", frames, off, f"object off any plausible court (|x| > {MAX_ABS_X_M} m, "
                                f"|y| > {MAX_ABS_Y_M} m or z outside [-0.5, {MAX_Z_M}] m)")
    flag("frames", frames, ~np.isfinite(frames["t"].to_numpy()), "t is NaN or infinite")

    # Singles: every object is the rally's server, its receiver or the ball (judged once per
    # (rally, object) pair, then the rows of the bad pairs are named).
    span = frames.groupby(["rally_id", "object"])["frame"].agg(["min", "max"])
    pairs = span.index.to_frame(index=False)
    obj = pairs["object"].fillna("")
    known = (obj == "ball") | (obj == _per_rally(rallies, pairs["rally_id"], "server")) | \
        (obj == _per_rally(rallies, pairs["rally_id"], "receiver"))
    if not known.all():
        bad_pairs = span.index[~known.to_numpy(bool)]
        rows = pd.MultiIndex.from_frame(frames[["rally_id", "object"]]).isin(bad_pairs)
        flag("frames", frames, rows, "object is neither the rally's server, its receiver nor "
                                     "the ball")

    # Time and frame order, per (rally, object) in frame order (rows may come in any order):
    # frames consecutive, t increasing by 1/fps.
    # The objects as codes in their sorted order (missing ones last), so one stable lexsort
    # orders the rows as sorting the table by (rally_id, object, frame) did, without comparing
    # strings row by row (half of the check's time).
    obj, names = pd.factorize(frames["object"], sort=True)
    obj = np.where(obj < 0, len(names), obj)
    rid, frame = frames["rally_id"].to_numpy(), frames["frame"].to_numpy()
    order = np.lexsort((frame, obj, rid))
    rid, obj = rid[order], obj[order]
    same = (rid[1:] == rid[:-1]) & (obj[1:] == obj[:-1])
    dframe = np.diff(frame[order])
    dt = np.diff(frames["t"].to_numpy()[order])
    step = same & (dframe == 1) & np.isfinite(dt)
    if step.any():
        median_s = float(np.median(dt[step]))
        if not abs(median_s * fps - 1.0) <= FPS_TOLERANCE:
            raise TrackingDataError(
                f"{fps_source} is {fps:g}, but the t column steps {median_s:.4g} s a frame "
                f"(median), i.e. {1 / median_s if median_s > 0 else float('nan'):.4g} Hz: "
                "fix the frame rate or the t column")
    idx = frames.index.to_numpy()[order][1:]
    with np.errstate(invalid="ignore"):
        checks = ((same & (dframe != 1), "frame gap or repeated frame"),
                  (same & (dt <= 0), "time not increasing"),
                  (step & (dt > 0) & (np.abs(dt * fps - 1.0) > STEP_TOLERANCE),
                   f"t step is not 1/fps = {1 / fps:.4g} s"))
    for mask, what in checks:
        for i in np.flatnonzero(mask):
            found.append((int(frames["rally_id"].iat[idx[i]]),
                          f"frames row {idx[i]} (rally {int(frames['rally_id'].iat[idx[i]])}, "
                          f"object {frames['object'].iat[idx[i]]}): {what}"))

    # Every rally has the server's, the receiver's and the ball's tracks, over the same frames.
    whole = frames.groupby("rally_id")["frame"].agg(["min", "max"])
    for role in ("server", "receiver", "ball"):
        who = rallies[role] if role != "ball" else pd.Series("ball", index=rallies.index)
        key = pd.MultiIndex.from_arrays([rallies["rally_id"], who.fillna("")])
        have = span.reindex(key)
        full = whole.reindex(rallies["rally_id"])
        absent = have["min"].isna().to_numpy()
        short = ~absent & ((have["min"].to_numpy() != full["min"].to_numpy()) |
                           (have["max"].to_numpy() != full["max"].to_numpy()))
        label = "the ball" if role == "ball" else f"the {role}"
        flag("rallies", rallies, absent, f"no frames of {label}")
        for i in np.flatnonzero(short):
            rid = int(rallies["rally_id"].iat[i])
            found.append((rid, f"rallies row {i} (rally {rid}): {label}'s track covers frames "
                               f"{int(have['min'].iat[i])}..{int(have['max'].iat[i])}, the "
                               f"rally {int(full['min'].iat[i])}..{int(full['max'].iat[i])}"))

    # Shots: one row a shot, struck by a player of the rally within the rally's frames.
    flag("shots", shots, shots.duplicated(["rally_id", "shot_index"]).to_numpy(),
         "duplicate shot_index (a repeated row?)")
    hitter = shots["hitter"].fillna("")
    ok = (hitter == _per_rally(rallies, shots["rally_id"], "server")) | \
        (hitter == _per_rally(rallies, shots["rally_id"], "receiver"))
    flag("shots", shots, ~ok.to_numpy(bool), "hitter is neither the server nor the receiver")
    lo = shots["rally_id"].map(whole["min"]).to_numpy(dtype=float)
    hi = shots["rally_id"].map(whole["max"]).to_numpy(dtype=float)
    sf = shots["frame"].to_numpy()
    outside = ~np.isnan(lo) & ((sf < lo) | (sf > hi))
    for i in np.flatnonzero(outside):
        rid = int(shots["rally_id"].iat[i])
        found.append((rid, f"shots row {i} (rally {rid}): frame {int(sf[i])} is outside the "
                           f"rally's frames {int(lo[i])}..{int(hi[i])}"))
    return found


def _check_fps(fps, source: str) -> float:
    if isinstance(fps, bool) or not isinstance(fps, (int, float, np.integer, np.floating)) \
            or not np.isfinite(fps) or fps <= 0:
        raise TrackingDataError(f"{source} must be a positive number of frames a second, "
                                f"got {fps!r}")
    return float(fps)


@dataclass
class RallyData:
    """Tracking of many rallies: ``frames``, ``rallies`` and ``shots`` tables (see module doc)."""

    frames: pd.DataFrame
    rallies: pd.DataFrame
    shots: pd.DataFrame
    fps: float = FPS_DEFAULT
    meta: dict = field(default_factory=dict)

    @classmethod
    def from_tables(cls, frames: pd.DataFrame, rallies: pd.DataFrame, shots: pd.DataFrame,
                    fps: float = FPS_DEFAULT, meta: dict | None = None,
                    repair: bool = False, validate: bool = True,
                    origin: str | None = None) -> RallyData:
        """Build and validate. With `repair=True`, rallies with problems are dropped (only
        those, with a warning) and listed in ``meta["repaired"]``; a repair that would drop
        every rally is an error. Otherwise the first problems raise `TrackingDataError`.
        Columns of the rallies table beyond the schema are kept (e.g. the simulator's
        ``realistic`` flag). `validate=False` only casts the columns: for simulated rallies,
        which may break physics and are flagged rather than refused. `origin` (a folder) is
        named in the errors."""
        fps_source = f"{origin}/meta.json's fps" if origin else "fps"
        fps = _check_fps(fps, fps_source)
        frames = _cast(frames, FRAME_COLUMNS, "frames", origin=origin)
        rallies = _cast(rallies, RALLY_COLUMNS, "rallies", keep_extra=True, origin=origin)
        shots = _cast(shots, SHOT_COLUMNS, "shots", origin=origin)
        problems = _problems(frames, rallies, shots, fps, fps_source) if validate else []
        meta = dict(meta or {})
        where = f"{origin}: " if origin else ""
        bad = sorted({rid for rid, _ in problems})
        if problems and (not repair or set(rallies["rally_id"]) <= set(bad)):
            head = "\n  ".join(msg for _, msg in problems[:10])
            more = f"\n  ... and {len(problems) - 10} more" if len(problems) > 10 else ""
            why = (f"repair would drop every rally ({len(bad)}); " if repair else "")
            raise TrackingDataError(f"{where}{why}{len(problems)} problem(s) in tracking data:"
                                    f"\n  {head}{more}")
        if problems:
            meta["repaired"] = {"dropped_rallies": bad, "problems": [m for _, m in problems]}
            warnings.warn(f"{where}repair dropped {len(bad)} of {rallies['rally_id'].nunique()} "
                          f"rallies ({len(problems)} problems; first: {problems[0][1]}); "
                          "the list is in meta['repaired']", stacklevel=2)
            frames = frames[~frames["rally_id"].isin(bad)].reset_index(drop=True)
            rallies = rallies[~rallies["rally_id"].isin(bad)].reset_index(drop=True)
            shots = shots[~shots["rally_id"].isin(bad)].reset_index(drop=True)
        return cls(frames=frames, rallies=rallies, shots=shots, fps=fps, meta=meta)

    def __len__(self) -> int:
        return len(self.rallies)

    def __repr__(self) -> str:
        n_points = self.rallies.groupby(["match_id", "point"]).ngroups if len(self.rallies) else 0
        return (f"RallyData({len(self.rallies)} rallies, {n_points} points, "
                f"{len(self.frames)} frame rows, {len(self.shots)} shots, fps={self.fps:g})")

    def subset(self, rally_ids) -> RallyData:
        """The rallies with these ids (order of the tables kept)."""
        keep = set(int(r) for r in rally_ids)
        sel = lambda df: df[df["rally_id"].isin(keep)].reset_index(drop=True)  # noqa: E731
        return RallyData(sel(self.frames), sel(self.rallies), sel(self.shots), self.fps,
                         dict(self.meta))

    @staticmethod
    def concat(parts: list[RallyData], renumber: bool = False) -> RallyData:
        """Concatenate; rally ids must already be unique across parts, unless `renumber`: then
        each part's rally ids are shifted past the previous parts' and its match ids prefixed
        with "<part index>-" (the parts themselves are left unchanged)."""
        if not parts:
            raise ValueError("concat needs at least one RallyData")
        fps = {p.fps for p in parts}
        if len(fps) != 1:
            raise ValueError(f"cannot concatenate RallyData with different fps {sorted(fps)}")
        if renumber:
            shifted, offset = [], 0
            for k, p in enumerate(parts):
                tables = [t.assign(rally_id=t["rally_id"] + offset)
                          for t in (p.frames, p.rallies, p.shots)]
                tables[1]["match_id"] = f"{k}-" + tables[1]["match_id"].astype(str)
                shifted.append(RallyData(*tables, p.fps, dict(p.meta)))
                if len(p.rallies):
                    offset += int(p.rallies["rally_id"].max()) + 1
            parts = shifted
        cat = lambda name: pd.concat([getattr(p, name) for p in parts], ignore_index=True)  # noqa: E731
        return RallyData(cat("frames"), cat("rallies"), cat("shots"), parts[0].fps,
                         dict(parts[0].meta))

    def points(self) -> pd.DataFrame:
        """The points table (`sportsngen.data.points`) of these rallies, one row a point.

        A point's first_serve_in is False when it has a first-serve fault rally; its serve speed,
        rally length and end come from its last rally.
        """
        r = self.rallies.sort_values(["match_id", "point", "serve_number"], kind="stable")
        g = r.groupby(["match_id", "point"], sort=False)
        last = g.tail(1).set_index(["match_id", "point"])
        first = g.head(1).set_index(["match_id", "point"])
        complete = last["end_reason"] != "fault"  # a point cut short after a fault is not a point
        last, first = last[complete], first[complete]
        reason = last["end_reason"]
        out = pd.DataFrame({
            "match_id": last.index.get_level_values(0),
            "point": last.index.get_level_values(1),
            "server": last["server"].to_numpy(),
            "receiver": last["receiver"].to_numpy(),
            "winner": last["winner"].to_numpy(),
            "surface": last["surface"].to_numpy(),
            "event": last["tournament"].to_numpy(),
            "serve_number": last["serve_number"].to_numpy(),
            "first_serve_in": (first["end_reason"] != "fault").to_numpy(),
            "ace": (reason == "ace").to_numpy(),
            "double_fault": (reason == "double_fault").to_numpy(),
            "serve_kmh": np.where(reason == "double_fault", np.nan, last["serve_kmh"]),
            "rally": last["rally_length"].to_numpy(),
            "set_no": last["set_no"].to_numpy(),
            "server_games": last["server_games"].to_numpy(),
            "receiver_games": last["receiver_games"].to_numpy(),
            "server_score": [point_label(a, b, tb) for a, b, tb in zip(
                last["server_points"], last["receiver_points"], last["in_tiebreak"])],
            "receiver_score": [point_label(b, a, tb) for a, b, tb in zip(
                last["server_points"], last["receiver_points"], last["in_tiebreak"])],
        })
        return as_points_table(out)

    def save(self, folder: str | Path) -> Path:
        """Write frames/rallies/shots Parquet files and meta.json into `folder`."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        self.frames.to_parquet(folder / "frames.parquet", index=False)
        self.rallies.to_parquet(folder / "rallies.parquet", index=False)
        self.shots.to_parquet(folder / "shots.parquet", index=False)
        (folder / "meta.json").write_text(json.dumps({"fps": self.fps, **self.meta},
                                                     indent=2, default=str))
        return folder

    @classmethod
    def load(cls, folder: str | Path, repair: bool = False, validate: bool = True) -> RallyData:
        """Read a folder written by `save` (or by hand in the same layout) and validate it
        (`validate=False`: cast only, for simulated rallies that may break physics)."""
        folder = Path(folder)
        if not folder.is_dir():
            raise FileNotFoundError(f"no tracking folder at {folder}")
        paths = {n: folder / f"{n}.parquet" for n in ("frames", "rallies", "shots")}
        absent = [str(p) for p in paths.values() if not p.exists()]
        if absent:
            raise FileNotFoundError(f"tracking folder {folder} lacks {absent}")
        meta = read_meta(folder / "meta.json")
        fps = meta.pop("fps", FPS_DEFAULT)
        tables = []
        for path in paths.values():
            try:
                tables.append(pd.read_parquet(path))
            except Exception as exc:  # pyarrow raises several types for a damaged file
                raise TrackingDataError(f"{path} is not a readable Parquet file "
                                        f"({type(exc).__name__}: {exc})") from exc
        return cls.from_tables(*tables, fps=fps, meta=meta, repair=repair, validate=validate,
                               origin=str(folder))


def read_meta(path: Path) -> dict:
    """A tracking folder's meta.json as a dict ({} when the file is absent)."""
    if not path.exists():
        return {}
    try:
        meta = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise TrackingDataError(f"{path} is not valid JSON ({exc})") from exc
    if not isinstance(meta, dict):
        raise TrackingDataError(f"{path} must hold a JSON object such as {{\"fps\": 25}}, "
                                f"got a {type(meta).__name__}")
    return meta
