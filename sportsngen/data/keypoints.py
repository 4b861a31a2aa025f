"""Reader for real Hawk-Eye ball keypoint files (the layout of the public ryurko/hawkeye
collection, scraped from the slams' CourtVision pages) into the project's tables.

A folder (searched recursively) holds per match, named ``<league>_<tournament>_<year><code>``
(e.g. ``atp_australian_open_2020MS101``):

- ``<match>_ball_trajectory.csv``: one row a keypoint: ``point_ID, set_num, game_num,
  point_num, serve_num, strike_index, position, x, y, z``. ``position`` is ``hit``, ``peak``,
  ``net``, ``bounce`` or ``last`` (where the tracking stopped); metres, ball centre, the
  project's court frame (origin at the net centre, baselines at x = +-11.885, z up).
- ``<match>_pbp.csv``: one row a serve attempt: ``point_ID, set_num, game_num, point_num,
  serve_num, server_id, returner_id`` and, read when present, ``point_winner_id, court_side,
  serve_speed_kph, is_ace, is_doublefault, is_tiebreak, server_score, returner_score,
  rally_length, player1, player2, p1_cum_games, p2_cum_games``.
- optionally ``player_ids.csv`` (``name, id``): display names of the ids.

What the files mean, as seen in the collection: ``point_ID`` is ``set_game_point_serve``, one id
a serve attempt (a point played on a second serve has two). A strike's keypoints are in time
order and start with its hit; after its first bounce a strike may have another peak (the
rebound) before the next hit; a ball into the net has a net keypoint below the cord and no
bounce beyond it. ``serve_speed_kph`` reads "157 KPH", "0 KPH" where none was measured (faults):
NaN. ``court_side`` is DeuceCourt / AdCourt; ``is_*`` flags are 0/1; ``server_score`` /
``returner_score`` count the points won in the game before the point; ``p1_cum_games`` /
``p2_cum_games`` the games won in the set before it (``player1``/``player2`` order);
``rally_length`` the shots in play (0 on a double fault, 1 on a first-serve fault).

`read_keypoints(folder)` returns a `KeypointData`: ``points`` (`sportsngen.data.points`),
``attempts`` (one row a serve attempt, i.e. a rally), ``shots`` (the `SHOT_COLUMNS` layout:
contact and first bounce per strike; no frames, strokes or labels in these files: NA) and
``keypoints`` (one row a keypoint: rally, strike, order, kind, x, y, z). The Hawk-Eye statistics
run on it through `sportsngen.eval.hawkeye_strikes.keypoint_strikes`.

Every problem raises `KeypointDataError` naming the file, the data row (1 = the line after the
header), the point and the column; nothing is dropped unless `repair=True`, which drops the
offending serve attempts (exactly those named) and lists them in ``meta["repaired"]``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from sportsngen.data.points import as_points_table
from sportsngen.data.tracking import MAX_ABS_X_M, MAX_ABS_Y_M, MAX_Z_M, SHOT_COLUMNS
from sportsngen.tennis.scoring import point_label

KEYPOINT_KINDS = ("hit", "peak", "net", "bounce", "last")
TRAJECTORY_COLUMNS = ("point_ID", "set_num", "game_num", "point_num", "serve_num",
                      "strike_index", "position", "x", "y", "z")
PBP_REQUIRED = ("point_ID", "set_num", "game_num", "point_num", "serve_num", "server_id",
                "returner_id")
TOURNAMENT_SURFACES = {"australian_open": "hard", "roland_garros": "clay", "us_open": "hard",
                       "wimbledon": "grass"}
LEAGUE_TOURS = {"atp": "ATP", "wta": "WTA"}
COURT_SIDES = {"DeuceCourt": "deuce", "AdCourt": "ad"}
_NAME = re.compile(r"^(?P<league>[A-Za-z]+)_(?P<tournament>[a-z_]+?)_(?P<year>\d{4})"
                   r"(?P<code>[A-Za-z0-9]+)_(?P<kind>ball_trajectory|pbp)\.csv$")
_MISSING = ("", "NA", "NaN", "nan", "null", "None")
_FLAGS = {"0": False, "1": True, "False": False, "True": True, "FALSE": False, "TRUE": True}
_INT_COLUMNS = ("set_num", "game_num", "point_num", "serve_num")


class KeypointDataError(ValueError):
    """Keypoint files that break the layout; the message names the file, row, point, column."""


@dataclass
class KeypointData:
    """Real keypoint data: ``points``, ``attempts``, ``shots``, ``keypoints`` (module doc)."""

    points: pd.DataFrame
    attempts: pd.DataFrame
    shots: pd.DataFrame
    keypoints: pd.DataFrame
    meta: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        return (f"KeypointData({self.attempts['match_id'].nunique()} matches, "
                f"{len(self.points)} points, {len(self.attempts)} serve attempts, "
                f"{len(self.shots)} strikes, {len(self.keypoints)} keypoints)")


class _Problems:
    """Problems found, each (match, point_ID, message)."""

    def __init__(self) -> None:
        self.items: list[tuple[str, str, str]] = []

    def flag(self, path: Path, match: str, df: pd.DataFrame, bad, column: str, what) -> None:
        for i in np.flatnonzero(np.asarray(bad, dtype=bool)):
            pid = str(df["point_ID"].iat[i])
            text = what(i) if callable(what) else what
            self.items.append((match, pid, f"{path} row {i + 1} (point {pid}), column "
                                            f"{column!r}: {text}"))


def _missing(raw: pd.Series) -> np.ndarray:
    return raw.str.strip().isin(_MISSING).to_numpy()


def _numbers(raw: pd.Series) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(values with NaN where missing or unreadable, missing mask, unreadable mask)."""
    miss = _missing(raw)
    vals = pd.to_numeric(raw.str.strip().where(~miss), errors="coerce").to_numpy(float)
    return vals, miss, np.isnan(vals) & ~miss


def _integers(path, match, df, col, probs: _Problems, optional: bool = False) -> np.ndarray:
    vals, miss, bad = _numbers(df[col])
    bad |= np.isfinite(vals) & (vals != np.round(vals))
    probs.flag(path, match, df, bad, col, lambda i: f"cannot be read as an integer: "
                                                      f"{df[col].iat[i]!r}")
    if not optional:
        probs.flag(path, match, df, miss, col, "missing value")
    return np.where(bad, np.nan, vals)


def _read_csv(path: Path, required: tuple[str, ...]) -> pd.DataFrame:
    df = pd.read_csv(path, dtype=str, keep_default_na=False)
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise KeypointDataError(f"{path}: missing columns {missing}")
    return df


def _common_checks(path, match, df, probs: _Problems) -> dict[str, np.ndarray]:
    """Set/game/point/serve numbers, serve number 1 or 2, and point_ID consistent with them."""
    ints = {c: _integers(path, match, df, c, probs) for c in _INT_COLUMNS}
    serve = ints["serve_num"]
    probs.flag(path, match, df, np.isfinite(serve) & ~np.isin(serve, (1, 2)), "serve_num",
               lambda i: f"unknown serve number {df['serve_num'].iat[i]!r}; allowed: [1, 2]")
    ok = np.all([np.isfinite(v) for v in ints.values()], axis=0)
    parts = [pd.Series(np.where(ok, ints[c], 0)).astype("int64").astype(str) for c in _INT_COLUMNS]
    expect = parts[0].str.cat(parts[1:], sep="_").to_numpy()
    probs.flag(path, match, df, ok & (df["point_ID"].str.strip().to_numpy() != expect),
               "point_ID", lambda i: f"{df['point_ID'].iat[i]!r} does not match set/game/point/"
                                     f"serve {expect[i]!r}")
    return ints


def _check_trajectory(path: Path, match: str, df: pd.DataFrame, pbp_ids: set[str],
                      pbp_path: Path, probs: _Problems) -> dict[str, np.ndarray]:
    ints = _common_checks(path, match, df, probs)
    strike = _integers(path, match, df, "strike_index", probs)
    pos = df["position"].str.strip().to_numpy()
    probs.flag(path, match, df, ~np.isin(pos, KEYPOINT_KINDS), "position",
               lambda i: f"unknown keypoint {pos[i]!r}; allowed: {list(KEYPOINT_KINDS)}")
    xyz = {}
    for c in ("x", "y", "z"):
        vals, miss, bad = _numbers(df[c])
        probs.flag(path, match, df, miss, c, "NaN coordinate")
        probs.flag(path, match, df, bad, c, lambda i, c=c: f"cannot be read as a number: "
                                                            f"{df[c].iat[i]!r}")
        xyz[c] = vals
    with np.errstate(invalid="ignore"):
        for c, off in (("x", np.abs(xyz["x"]) > MAX_ABS_X_M), ("y", np.abs(xyz["y"]) > MAX_ABS_Y_M),
                       ("z", (xyz["z"] > MAX_Z_M) | (xyz["z"] < -0.5))):
            probs.flag(path, match, df, off, c, lambda i, c=c: f"{xyz[c][i]:g} m is off any "
                       f"plausible court (|x| <= {MAX_ABS_X_M}, |y| <= {MAX_ABS_Y_M}, "
                       f"-0.5 <= z <= {MAX_Z_M})")
    dup = df.duplicated(list(TRAJECTORY_COLUMNS), keep="first").to_numpy()
    first_of = df.groupby(list(TRAJECTORY_COLUMNS), sort=False).ngroup().to_numpy()
    first_row = pd.Series(np.arange(len(df))).groupby(first_of).transform("first").to_numpy()
    probs.flag(path, match, df, dup, "point_ID", lambda i: f"duplicate of row {first_row[i] + 1}")
    pid = df["point_ID"].str.strip().to_numpy()
    probs.flag(path, match, df, ~np.isin(pid, list(pbp_ids)), "point_ID",
               f"no row for this point in the play-by-play file {pbp_path}")
    _check_order(path, match, df, pid, strike, pos, probs)
    return {**ints, "strike": strike, **xyz}


def _check_order(path, match, df, pid, strike, pos, probs: _Problems) -> None:
    """Rows of a point together; strikes 1, 2, ... in order; each strike starts with its one hit;
    a 'last' keypoint only in the point's last strike."""
    n = len(df)
    new_point = np.r_[True, pid[1:] != pid[:-1]] if n else np.zeros(0, bool)
    start_rows = np.flatnonzero(new_point)
    began = pd.Series(start_rows).groupby(pid[start_rows]).transform("first").to_numpy()
    again = np.zeros(n, bool)
    again[start_rows[began != start_rows]] = True
    began_at = np.zeros(n, np.int64)
    began_at[start_rows] = began
    probs.flag(path, match, df, again, "point_ID",
               lambda i: f"rows of this point are not together (it began at row "
                         f"{began_at[i] + 1})")
    prev = np.r_[np.nan, strike[:-1]]
    step = strike - prev
    known = np.isfinite(strike) & (new_point | np.isfinite(prev))
    probs.flag(path, match, df, known & new_point & (strike != 1), "strike_index",
               lambda i: f"the point starts at strike {strike[i]:g}, not 1")
    probs.flag(path, match, df, known & ~new_point & ~np.isin(step, (0, 1)), "strike_index",
               lambda i: f"strike {strike[i]:g} follows strike {prev[i]:g}")
    new_strike = new_point | (step == 1)
    probs.flag(path, match, df, known & new_strike & (pos != "hit"), "position",
               lambda i: f"strike {strike[i]:g} starts with {pos[i]!r}, not 'hit'")
    probs.flag(path, match, df, known & ~new_strike & (pos == "hit"), "position",
               lambda i: f"a second 'hit' in strike {strike[i]:g}")
    last_strike = pd.Series(strike).groupby(pid).transform("max").to_numpy()
    probs.flag(path, match, df, (pos == "last") & (strike < last_strike), "position",
               lambda i: f"a 'last' keypoint in strike {strike[i]:g}, before the point's last "
                         f"strike {last_strike[i]:g}")


def _check_pbp(path: Path, match: str, df: pd.DataFrame, probs: _Problems) -> dict:
    ints = _common_checks(path, match, df, probs)
    pid = df["point_ID"].str.strip()
    dup = pid.duplicated(keep="first").to_numpy()
    first_row = pd.Series(np.arange(len(df))).groupby(pid.to_numpy()).transform("first")
    probs.flag(path, match, df, dup, "point_ID",
               lambda i: f"duplicate point_ID (also row {first_row.iat[i] + 1})")
    for c in ("server_id", "returner_id"):
        probs.flag(path, match, df, _missing(df[c]), c, "missing player id")
    probs.flag(path, match, df, df["server_id"].str.strip() == df["returner_id"].str.strip(),
               "returner_id", "the same player as the server")
    out: dict = {"ints": ints}
    if "court_side" in df.columns:
        side = df["court_side"].str.strip()
        bad = ~side.isin(list(COURT_SIDES)) & ~_missing(df["court_side"])
        probs.flag(path, match, df, bad, "court_side", lambda i: f"unknown court side "
                   f"{side.iat[i]!r}; allowed: {list(COURT_SIDES)}")
        out["side"] = side.map(COURT_SIDES)
    if "serve_speed_kph" in df.columns:
        raw = df["serve_speed_kph"].str.strip()
        m = raw.str.extract(r"^(\d+(?:\.\d+)?)\s*(?:KPH|kph|km/h)?$")[0]
        bad = m.isna() & ~_missing(raw)
        probs.flag(path, match, df, bad, "serve_speed_kph",
                   lambda i: f"cannot be read as a speed: {raw.iat[i]!r}")
        kmh = pd.to_numeric(m, errors="coerce").to_numpy(float)
        out["serve_kmh"] = np.where(kmh > 0, kmh, np.nan)  # "0 KPH": not measured
    for c in ("is_ace", "is_doublefault", "is_tiebreak"):
        if c in df.columns:
            raw = df[c].str.strip()
            bad = ~raw.isin(list(_FLAGS)) & ~_missing(raw)
            probs.flag(path, match, df, bad, c, lambda i, raw=raw: f"unknown flag {raw.iat[i]!r};"
                       " allowed: 0, 1, True, False")
            out[c] = raw.map(_FLAGS).astype("boolean")
    for c in ("server_score", "returner_score", "p1_cum_games", "p2_cum_games", "rally_length"):
        if c in df.columns:
            out[c] = _integers(path, match, df, c, probs, optional=True)
    return out


def _player_names(folder: Path) -> dict[str, str]:
    found = sorted(folder.rglob("player_ids.csv"))
    if not found:
        return {}
    ids = pd.read_csv(found[0], dtype=str, keep_default_na=False)
    if not {"name", "id"} <= set(ids.columns):
        raise KeypointDataError(f"{found[0]}: missing columns {sorted({'name', 'id'} - set(ids))}")
    ids = ids.drop_duplicates("id")
    return dict(zip(ids["id"].str.strip(), ids["name"].str.strip()))


def _match_files(folder: Path) -> list[tuple[str, dict, Path, Path]]:
    """(match, name fields, trajectory path, pbp path) of every trajectory file."""
    out = []
    pbps = {p.name: p for p in folder.rglob("*_pbp.csv")}
    for path in sorted(folder.rglob("*_ball_trajectory.csv")):
        m = _NAME.match(path.name)
        if m is None:
            raise KeypointDataError(f"{path}: file name not of the form "
                                    "<league>_<tournament>_<year><code>_ball_trajectory.csv")
        fields = m.groupdict()
        if fields["league"].lower() not in LEAGUE_TOURS:
            raise KeypointDataError(f"{path}: unknown league {fields['league']!r} in the file "
                                    f"name; known: {list(LEAGUE_TOURS)}")
        if fields["tournament"] not in TOURNAMENT_SURFACES:
            raise KeypointDataError(f"{path}: unknown tournament {fields['tournament']!r} in the "
                                    f"file name; known: {list(TOURNAMENT_SURFACES)}")
        match = path.name[: -len("_ball_trajectory.csv")]
        pbp_name = f"{match}_pbp.csv"
        if pbp_name not in pbps:
            raise KeypointDataError(f"{path}: no play-by-play file {pbp_name} for it under "
                                    f"{folder}")
        out.append((match, fields, path, pbps[pbp_name]))
    return out


def read_keypoints(folder: str | Path, player_names: dict[str, str] | None = None,
                   repair: bool = False, progress: bool = False) -> KeypointData:
    """Read every match's keypoint and play-by-play files under `folder` (see the module doc).

    `player_names` maps ids or the files' names (e.g. ``{"R.NADAL": "Rafael Nadal"}``) to the
    names wanted in the tables. `repair=True` drops the serve attempts with problems (listed in
    ``meta["repaired"]``) instead of raising `KeypointDataError`.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"no keypoint folder at {folder}")
    files = _match_files(folder)
    if not files:
        raise FileNotFoundError(f"no *_ball_trajectory.csv files under {folder}")
    names = _player_names(folder)
    rename = dict(player_names or {})

    def name(pid: str) -> str:
        n = names.get(pid, pid)
        return rename.get(pid, rename.get(n, n))

    probs = _Problems()
    parsed = []
    it = files
    if progress:
        from tqdm.auto import tqdm
        it = tqdm(files, desc="keypoint files", unit="match")
    for match, fields, tpath, ppath in it:
        pbp = _read_csv(ppath, PBP_REQUIRED)
        traj = _read_csv(tpath, TRAJECTORY_COLUMNS)
        pcols = _check_pbp(ppath, match, pbp, probs)
        tcols = _check_trajectory(tpath, match, traj, set(pbp["point_ID"].str.strip()), ppath,
                                  probs)
        parsed.append((match, fields, pbp, pcols, traj, tcols))
    meta: dict = {"source": str(folder)}
    if probs.items and not repair:
        msgs = [m for _, _, m in probs.items]
        head = "\n  ".join(msgs[:10])
        more = f"\n  ... and {len(msgs) - 10} more" if len(msgs) > 10 else ""
        raise KeypointDataError(f"{len(msgs)} problem(s) in keypoint data:\n  {head}{more}")
    bad = {(m, p) for m, p, _ in probs.items}
    if bad:
        meta["repaired"] = {"dropped_points": sorted(bad),
                            "problems": [m for _, _, m in probs.items]}
    return _build(parsed, bad, name, meta)


def _build(parsed, bad: set[tuple[str, str]], name, meta: dict) -> KeypointData:
    attempts, kps = [], []
    offset = 0
    for match, fields, pbp, pc, traj, tc in parsed:
        pid = pbp["point_ID"].str.strip().to_numpy()
        keep = np.array([(match, p) not in bad for p in pid], dtype=bool)
        n = len(pbp)
        ints = pc["ints"]
        a = pd.DataFrame({
            "rally_id": offset + np.arange(n), "match_id": match, "point_id": pid,
            "set_no": ints["set_num"], "game_no": ints["game_num"],
            "point_no": ints["point_num"], "serve_number": ints["serve_num"],
            "server_id": pbp["server_id"].str.strip().to_numpy(),
            "receiver_id": pbp["returner_id"].str.strip().to_numpy(),
            "side": pc.get("side", pd.Series(pd.NA, index=pbp.index)).to_numpy(),
            "surface": TOURNAMENT_SURFACES[fields["tournament"]],
            "tour": LEAGUE_TOURS[fields["league"].lower()],
            "event": f"{fields['year']}-{fields['tournament']}",
            "serve_kmh": pc.get("serve_kmh", np.full(n, np.nan)),
        })
        for c in ("point_winner_id", "player1", "player2"):
            a[c] = pbp[c].str.strip().replace(list(_MISSING), pd.NA).to_numpy() \
                if c in pbp.columns else pd.NA
        for c in ("is_ace", "is_doublefault", "is_tiebreak"):
            a[c] = pc[c].to_numpy() if c in pc else pd.NA
        for c in ("server_score", "returner_score", "p1_cum_games", "p2_cum_games",
                  "rally_length"):
            a[c] = pd.array(pc[c], dtype="Float64").astype("Int64") if c in pc else pd.NA
        a = a[keep]
        offset += n
        t = traj.assign(point_ID=traj["point_ID"].str.strip())
        tkeep = np.array([(match, p) not in bad for p in t["point_ID"]], dtype=bool)
        k = pd.DataFrame({"point_id": t["point_ID"].to_numpy(), "strike": tc["strike"],
                          "kind": t["position"].str.strip().to_numpy(), "x": tc["x"],
                          "y": tc["y"], "z": tc["z"]})[tkeep]
        k = k.merge(a[["point_id", "rally_id"]], on="point_id", how="inner")
        attempts.append(a)
        kps.append(k)
    a = pd.concat(attempts, ignore_index=True)
    k = pd.concat(kps, ignore_index=True)
    k["strike"] = k["strike"].astype("int64")
    k["order"] = k.groupby(["rally_id", "strike"]).cumcount()
    keypoints = k.loc[:, ["rally_id", "strike", "order", "kind", "x", "y", "z"]]
    # Point numbers within each match, in order of play; the server's end from the serve.
    nums = [a[c].astype("int64").astype(str) for c in ("set_no", "game_no", "point_no")]
    a["point"] = nums[0].str.cat(nums[1:], sep="_").groupby(a["match_id"], sort=False) \
        .transform(lambda s: pd.factorize(s)[0] + 1).astype("int64")
    for c in ("set_no", "game_no", "point_no", "serve_number"):
        a[c] = a[c].astype("int64")
    serve_x = keypoints[(keypoints["strike"] == 1) & (keypoints["kind"] == "hit")] \
        .drop_duplicates("rally_id").set_index("rally_id")["x"]
    a["server_end"] = pd.array(np.sign(serve_x.reindex(a["rally_id"]).to_numpy()),
                               dtype="Float64").astype("Int64")
    a["server"] = a["server_id"].map(name).astype("string")
    a["receiver"] = a["receiver_id"].map(name).astype("string")
    a["winner"] = a["point_winner_id"].map(lambda p: name(p) if isinstance(p, str) else pd.NA) \
        .astype("string")
    return KeypointData(points=_points(a), attempts=a.reset_index(drop=True),
                        shots=_shots(keypoints, a), keypoints=keypoints, meta=meta)


def _points(a: pd.DataFrame) -> pd.DataFrame:
    """One row a point: the score from its first attempt, everything else from its last."""
    g = a.groupby(["match_id", "point"], sort=False)
    first, last = g.head(1).set_index(["match_id", "point"]), g.tail(1).set_index(
        ["match_id", "point"])
    sid = first["server_id"].astype("string")
    is1 = (sid == first["player1"].astype("string")).fillna(False).to_numpy(bool)
    is2 = (sid == first["player2"].astype("string")).fillna(False).to_numpy(bool)
    g1, g2 = (first[c].astype("Float64").to_numpy(float, na_value=np.nan)
              for c in ("p1_cum_games", "p2_cum_games"))
    sg = np.where(is1, g1, np.where(is2, g2, np.nan))
    rg = np.where(is1, g2, np.where(is2, g1, np.nan))
    tb = first["is_tiebreak"].fillna(False).astype(bool)
    ss, rs = first["server_score"], first["returner_score"]
    known = ss.notna() & rs.notna()
    dfault = last["is_doublefault"]
    out = pd.DataFrame({
        "match_id": last.index.get_level_values(0), "point": last.index.get_level_values(1),
        "server": last["server"].to_numpy(), "receiver": last["receiver"].to_numpy(),
        "winner": last["winner"].to_numpy(), "surface": last["surface"].to_numpy(),
        "event": last["event"].to_numpy(), "serve_number": last["serve_number"].to_numpy(),
        "first_serve_in": (last["serve_number"] == 1).to_numpy(),
        "ace": last["is_ace"].to_numpy(), "double_fault": dfault.to_numpy(),
        "serve_kmh": np.where(dfault.fillna(False).to_numpy(bool), np.nan,
                              last["serve_kmh"].to_numpy(float)),
        "rally": last["rally_length"].to_numpy(), "set_no": last["set_no"].to_numpy(),
        "server_games": pd.array(sg, dtype="Float64").astype("Int64"),
        "receiver_games": pd.array(rg, dtype="Float64").astype("Int64"),
        "server_score": [point_label(s, r, t) if k else pd.NA
                         for s, r, t, k in zip(ss, rs, tb, known)],
        "receiver_score": [point_label(r, s, t) if k else pd.NA
                           for s, r, t, k in zip(ss, rs, tb, known)],
    })
    out.loc[~known.to_numpy(), ["server_score", "receiver_score"]] = pd.NA
    return as_points_table(out)


def _shots(kp: pd.DataFrame, a: pd.DataFrame) -> pd.DataFrame:
    """One row a strike in the `SHOT_COLUMNS` layout: contact, first bounce, hitter, serve
    speed; what the files do not give is NA."""
    key = ["rally_id", "strike"]
    hit = kp[kp["kind"] == "hit"].drop_duplicates(key)
    bounce = kp[kp["kind"] == "bounce"].drop_duplicates(key).set_index(key)
    att = a.set_index("rally_id").loc[hit["rally_id"]]
    at_serve_end = np.sign(hit["x"].to_numpy()) == att["server_end"].to_numpy(float)
    idx = pd.MultiIndex.from_frame(hit[key])
    out = pd.DataFrame({
        "rally_id": hit["rally_id"].to_numpy(), "shot_index": hit["strike"].to_numpy() - 1,
        "frame": pd.array([pd.NA] * len(hit), dtype="Int64"),
        "hitter": np.where(at_serve_end, att["server"].to_numpy(), att["receiver"].to_numpy()),
        "contact_x": hit["x"].to_numpy(), "contact_y": hit["y"].to_numpy(),
        "contact_z": hit["z"].to_numpy(),
        "speed_mps": np.where(hit["strike"].to_numpy() == 1,
                              att["serve_kmh"].to_numpy(float) / 3.6, np.nan),
        "bounce_x": bounce["x"].reindex(idx).to_numpy(float),
        "bounce_y": bounce["y"].reindex(idx).to_numpy(float),
    })
    for c in ("stroke", "spin", "direction", "outcome", "error_kind"):
        out[c] = pd.array([pd.NA] * len(hit), dtype="string")
    out["hitter"] = out["hitter"].astype("string")
    return out.loc[:, list(SHOT_COLUMNS)].reset_index(drop=True)
