"""Realism metrics of tracking: physical quantities per shot and bounce, and the comparison of
two `RallyData` (simulated against a reference) with real slam figures beside them.

Quantities (one sample a shot or a bounce; speeds in km/h, heights in metres):

- ``toss_contact_height_m``: height of the serve's contact (``contact_z`` of shot 0);
- ``first_serve_kmh`` / ``second_serve_kmh``: speed of every serve struck (faults included),
  by the rally's ``serve_number``;
- ``return_kmh``: speed of shot 1, whatever the stroke;
- ``groundstroke_kmh``: forehands and backhands after the return (shot 2 on);
- ``bounce_speed_ratio``: ball speed just after over just before a bounce, by surface.

Speeds are measured from the ball track by default (`speed_from="tracks"`): the ball's speed
over one to two frame times after the contact, read off the track wherever the contact fell
between frames (`tennis.contact_speed`); a simulator strikes on a frame and reads there. The
generator's ``speed_mps`` is the launch speed, about 5 % above that on serves (drag over the
first 60 ms), so taking both from the tracks compares like with like. (Read as the first whole
frame after the shot's contact frame, a serve's speed depended on where its contact fell in the
frame, which the generator fixes per player: Williams' serves were read 0.16 of a frame sooner
after their contact than a simulator's, Sharapova's and the men's 0.25-0.34 later.) A
bounce's speeds are over the segments (f-2, f-1) and (f+1, f+2) around its frame f (events
from the rally rules, `sportsngen.tennis.rally`); a bounce with a racket contact within two
frames is left out.

Simulated rallies carry ``realistic`` and may end undecided (end_reason "none"). Physical
quantities keep the rallies that are realistic and decided; point statistics keep the points all
of whose rallies are (`realistic_points`), so a point is never half counted. Data without the
column (ground truth, user tracking) counts as all realistic.

`compare` returns the long metrics table, `METRIC_COLUMNS`: one row per (section, metric,
group, statistic) with a value per source in ``sim``, ``ref`` and ``real``. Statistics are
``n``, ``median``, ``iqr`` (75th minus 25th percentile), ``mean``, ``value``, ``share_<bin>``
and ``wasserstein``; on a wasserstein row ``ref`` and ``real`` hold the distance
(`scipy.stats.wasserstein_distance`) of that source's distribution from the simulated one and
``sim`` is NaN. A statistic a source lacks is NaN.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.stats import wasserstein_distance

from sportsngen.data.tracking import RallyData
from sportsngen.eval.stats import SERVE_STATS_COLUMNS, rally_distribution, serve_stats
from sportsngen.tennis.contact_speed import speed_frame_after_contact_mps
from sportsngen.tennis.rally import BALL, RECEIVER, SERVER, analyse_rallies

KMH_PER_MPS = 3.6
QUANTITIES: dict[str, str] = {  # name -> unit
    "toss_contact_height_m": "m",
    "first_serve_kmh": "km/h",
    "second_serve_kmh": "km/h",
    "return_kmh": "km/h",
    "groundstroke_kmh": "km/h",
}
REAL_QUANTITIES = ("first_serve_kmh", "second_serve_kmh")  # what slam files record
GROUNDSTROKES = ("forehand", "backhand")
BOUNCE_CONTACT_GAP_FRAMES = 2  # a contact this close to a bounce spoils its speeds
METRIC_COLUMNS = ("section", "metric", "group", "statistic", "sim", "ref", "real")
ALL = "all"
_CHUNK_RALLIES = 256  # rallies per padded track array (memory stays flat in the data size)


# -- which rallies and points count -----------------------------------------------------------
def counted_rallies(rallies: pd.DataFrame) -> np.ndarray:
    """(n,) bool: rallies that are realistic (where flagged) and decided (end_reason not
    "none")."""
    ok = rallies["end_reason"].astype(str).to_numpy() != "none"
    if "realistic" in rallies.columns:
        ok &= rallies["realistic"].astype(bool).to_numpy()
    return ok


def realistic_points(data: RallyData) -> pd.DataFrame:
    """The points table of the points all of whose rallies count (`counted_rallies`)."""
    r = data.rallies
    key = pd.Series(list(zip(r["match_id"].astype(str), r["point"].astype(int))), index=r.index)
    bad = set(key[~counted_rallies(r)])
    keep = r[~key.isin(bad).to_numpy()]
    # points() reads only the rallies table: no need to copy frames and shots.
    return RallyData(data.frames.iloc[:0], keep, data.shots.iloc[:0], data.fps).points()


def realism_shares(data: RallyData) -> dict[str, float]:
    """Rally counts and shares: ``n_rallies``, ``non_realistic_share`` (rallies flagged
    unrealistic), ``undecided_share`` (end_reason "none"); shares NaN without rallies."""
    r = data.rallies
    n = len(r)
    flagged = (~r["realistic"].astype(bool)).sum() if "realistic" in r.columns else 0
    undecided = (r["end_reason"].astype(str) == "none").sum()
    share = (lambda k: float(k) / n) if n else (lambda k: float("nan"))
    return {"n_rallies": float(n), "non_realistic_share": share(flagged),
            "undecided_share": share(undecided)}


# -- tracks -----------------------------------------------------------------------------------
@dataclass
class Tracks:
    """Padded tracks of some rallies: `pos_m` (B, T, 3, 3) [server, receiver, ball] (NaN after
    `length`), `first_frame` (B,) the frame number of index 0, `rallies` their rows."""

    rallies: pd.DataFrame
    pos_m: np.ndarray
    length: np.ndarray
    first_frame: np.ndarray


def iter_tracks(data: RallyData, rally_ids=None, chunk: int = _CHUNK_RALLIES) -> Iterator[Tracks]:
    """`Tracks` of the given rallies (default all), `chunk` rallies at a time, in rally_id
    order. Raises ValueError on an object that is neither the server, the receiver nor the
    ball."""
    r = data.rallies.drop_duplicates("rally_id").set_index("rally_id", drop=False)
    ids = np.sort(r.index.to_numpy(np.int64) if rally_ids is None
                  else np.asarray(list(rally_ids), dtype=np.int64))
    f = data.frames
    rid = f["rally_id"].to_numpy(np.int64)
    order = np.argsort(rid, kind="stable")
    rid_sorted = rid[order]
    for s in range(0, len(ids), chunk):
        cid = ids[s:s + chunk]
        rows = order[np.searchsorted(rid_sorted, cid[0], "left"):
                     np.searchsorted(rid_sorted, cid[-1], "right")]
        rows = rows[np.isin(rid[rows], cid)]
        sub = r.loc[cid].reset_index(drop=True)
        ri = np.searchsorted(cid, rid[rows])
        obj = f["object"].to_numpy(dtype=object)[rows]
        slot = np.full(len(rows), -1, dtype=np.int64)
        slot[obj == "ball"] = BALL
        slot[obj == sub["server"].to_numpy(dtype=object)[ri]] = SERVER
        slot[obj == sub["receiver"].to_numpy(dtype=object)[ri]] = RECEIVER
        if (slot < 0).any():
            i = int(np.flatnonzero(slot < 0)[0])
            raise ValueError(f"rally {int(cid[ri[i]])}: object {obj[i]!r} is neither the server, "
                             "the receiver nor the ball")
        frame = f["frame"].to_numpy(np.int64)[rows]
        first = np.full(len(cid), np.iinfo(np.int64).max)
        np.minimum.at(first, ri, frame)
        last = np.full(len(cid), -1, dtype=np.int64)
        np.maximum.at(last, ri, frame)
        first = np.where(last < 0, 0, first)
        length = np.maximum(last - first + 1, 0)
        pos = np.full((len(cid), max(int(length.max(initial=0)), 1), 3, 3), np.nan)
        pos[ri, frame - first[ri], slot] = f[["x", "y", "z"]].to_numpy(float)[rows]
        yield Tracks(sub, pos, length, first)


def rally_events(tracks: Tracks, fps: float) -> pd.DataFrame:
    """The rally rules (`sportsngen.tennis.rally.analyse_rallies`) over `tracks`, indexed by
    rally_id; frames in the results count from each rally's first frame. No duration cap: a
    long recorded rally is followed to its end."""
    if len(tracks.rallies) == 0:
        return pd.DataFrame()
    t = tracks.rallies
    out = analyse_rallies(tracks.pos_m, tracks.length, t["server_end"].to_numpy(),
                          t["side"].to_numpy(), t["serve_number"].to_numpy(), fps,
                          max_duration_s=tracks.pos_m.shape[1] / fps + 1.0)
    out.index = pd.Index(t["rally_id"].to_numpy(np.int64), name="rally_id")
    return out


# -- shots ------------------------------------------------------------------------------------
def _track_speeds_mps(data: RallyData, shots: pd.DataFrame) -> np.ndarray:
    """Ball speed over one to two frame times after each shot's contact (its position in the
    shots table; `tennis.contact_speed`) read off the three frames after its contact frame
    (NaN where the track ends first), in the order of `shots`. The contact frame is the one
    nearest the contact, so the first of them lies 0.5-1.5 frame times after it."""
    out = np.full(len(shots), np.nan)
    if len(shots) == 0:
        return out
    pos_of = pd.Series(np.arange(len(shots)), index=shots.index)
    for tr in iter_tracks(data, np.unique(shots["rally_id"].to_numpy(np.int64))):
        ids = tr.rallies["rally_id"].to_numpy(np.int64)
        mine = shots[shots["rally_id"].isin(ids)]
        ri = np.searchsorted(ids, mine["rally_id"].to_numpy(np.int64))
        k = mine["frame"].to_numpy(np.int64) - tr.first_frame[ri]
        ok = (k + 1 >= 0) & (k + 3 < tr.length[ri])
        after = np.stack([tr.pos_m[ri[ok], k[ok] + j, BALL] for j in (1, 2, 3)], axis=1)
        contact = mine.loc[ok, ["contact_x", "contact_y", "contact_z"]].to_numpy(float)
        out[pos_of[mine.index[ok]].to_numpy()] = speed_frame_after_contact_mps(
            contact, after, data.fps, first_offset=(0.5, 1.5))
    return out


def shot_quantities(data: RallyData, speed_from: str = "tracks",
                    realistic_only: bool = True) -> pd.DataFrame:
    """One row a sample of `QUANTITIES`: columns rally_id, shot_index, hitter, surface,
    quantity, value (km/h or m). `speed_from`: "tracks" (measured from the ball track, see the
    module doc) or "shots" (the shots table's ``speed_mps``). Samples with an unknown value are
    left out."""
    if speed_from not in ("tracks", "shots"):
        raise ValueError(f"speed_from must be 'tracks' or 'shots', got {speed_from!r}")
    r = data.rallies
    keep = r[counted_rallies(r)] if realistic_only else r
    s = data.shots[data.shots["rally_id"].isin(keep["rally_id"])].reset_index(drop=True)
    info = keep.set_index("rally_id")
    s["surface"] = info["surface"].reindex(s["rally_id"]).to_numpy()
    s["serve_number"] = info["serve_number"].reindex(s["rally_id"]).to_numpy()
    speed = (_track_speeds_mps(data, s) if speed_from == "tracks"
             else s["speed_mps"].to_numpy(float))
    s["kmh"] = speed * KMH_PER_MPS
    idx = s["shot_index"].to_numpy()
    serve = idx == 0
    picks = {
        "toss_contact_height_m": (serve, "contact_z"),
        "first_serve_kmh": (serve & (s["serve_number"].to_numpy() == 1), "kmh"),
        "second_serve_kmh": (serve & (s["serve_number"].to_numpy() == 2), "kmh"),
        "return_kmh": (idx == 1, "kmh"),
        "groundstroke_kmh": ((idx >= 2) & s["stroke"].isin(GROUNDSTROKES).to_numpy(), "kmh"),
    }
    parts = []
    for name, (mask, col) in picks.items():
        part = s.loc[mask, ["rally_id", "shot_index", "hitter", "surface"]].copy()
        part["quantity"] = name
        part["value"] = s.loc[mask, col].to_numpy(float)
        parts.append(part)
    out = pd.concat(parts, ignore_index=True)
    return out[np.isfinite(out["value"].to_numpy())].reset_index(drop=True)


# -- bounces ----------------------------------------------------------------------------------
def bounce_speeds(ball_m: np.ndarray, bounce_frames, fps: float,
                  contact_frames=()) -> tuple[np.ndarray, np.ndarray]:
    """Speeds (m/s) just before and just after each bounce of one ball track `ball_m` (T, 3):
    over the segments (f-2, f-1) and (f+1, f+2) around the bounce frame f. NaN where the window
    leaves the track or a contact lies within `BOUNCE_CONTACT_GAP_FRAMES` of the bounce."""
    ball = np.asarray(ball_m, dtype=float)
    f = np.asarray(bounce_frames, dtype=np.int64).reshape(-1)
    c = np.asarray(contact_frames, dtype=np.int64).reshape(-1)
    ok = (f - 2 >= 0) & (f + 2 < len(ball))
    if len(c):
        ok &= (np.abs(f[:, None] - c[None, :]) > BOUNCE_CONTACT_GAP_FRAMES).all(axis=1)
    v_in, v_out = np.full(len(f), np.nan), np.full(len(f), np.nan)
    g = f[ok]
    v_in[ok] = np.linalg.norm(ball[g - 1] - ball[g - 2], axis=1) * fps
    v_out[ok] = np.linalg.norm(ball[g + 2] - ball[g + 1], axis=1) * fps
    return v_in, v_out


def bounce_ratios(data: RallyData, events: pd.DataFrame | None = None,
                  realistic_only: bool = True) -> pd.DataFrame:
    """One row a measurable bounce: rally_id, surface, frame (from the rally's first frame),
    speed_in_mps, speed_out_mps, ratio (out / in). `events`: rows of `rally_events` (indexed by
    rally_id, with bounce_frames and contact_frames) to reuse; computed when None."""
    r = data.rallies
    keep = r[counted_rallies(r)] if realistic_only else r
    cols = ["rally_id", "surface", "frame", "speed_in_mps", "speed_out_mps", "ratio"]
    rows: list[pd.DataFrame] = []
    for tr in iter_tracks(data, keep["rally_id"]):
        ev = rally_events(tr, data.fps) if events is None else events
        for i, (rid, surface) in enumerate(zip(tr.rallies["rally_id"], tr.rallies["surface"])):
            if rid not in ev.index:
                continue
            e = ev.loc[rid]
            v_in, v_out = bounce_speeds(tr.pos_m[i, :tr.length[i], BALL], e["bounce_frames"],
                                        data.fps, e["contact_frames"])
            rows.append(pd.DataFrame({"rally_id": int(rid), "surface": surface,
                                      "frame": np.asarray(e["bounce_frames"], dtype=np.int64),
                                      "speed_in_mps": v_in, "speed_out_mps": v_out}))
    if not rows:
        return pd.DataFrame({c: pd.Series(dtype=float) for c in cols})
    out = pd.concat(rows, ignore_index=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        out["ratio"] = out["speed_out_mps"] / out["speed_in_mps"]
    good = np.isfinite(out["ratio"].to_numpy()) & (out["speed_in_mps"].to_numpy() > 0)
    return out.loc[good, cols].reset_index(drop=True)


# -- one source, then two -------------------------------------------------------------------
@dataclass
class Sample:
    """Everything `compare` needs from one `RallyData`: shot quantities (`shot_quantities`),
    bounces (`bounce_ratios`), the counted points table and the realism shares."""

    shots: pd.DataFrame
    bounces: pd.DataFrame
    points: pd.DataFrame
    realism: dict[str, float]


def collect(data: RallyData, speed_from: str = "tracks", realistic_only: bool = True) -> Sample:
    """The `Sample` of one `RallyData` (the rally rules run once over its counted rallies)."""
    return Sample(shots=shot_quantities(data, speed_from, realistic_only),
                  bounces=bounce_ratios(data, realistic_only=realistic_only),
                  points=realistic_points(data) if realistic_only else data.points(),
                  realism=realism_shares(data))


def summary(values) -> dict[str, float]:
    """``n``, ``median`` and ``iqr`` of the finite values (NaN statistics when there are none)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return {"n": 0.0, "median": np.nan, "iqr": np.nan}
    q25, q50, q75 = np.percentile(v, [25, 50, 75])
    return {"n": float(len(v)), "median": float(q50), "iqr": float(q75 - q25)}


def wasserstein(a, b) -> float:
    """`scipy.stats.wasserstein_distance` of the finite values; NaN when either is empty."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    return float(wasserstein_distance(a, b)) if len(a) and len(b) else float("nan")


def _row(section: str, metric: str, group: str, statistic: str, sim, ref, real) -> dict:
    return {"section": section, "metric": metric, "group": group, "statistic": statistic,
            "sim": float(sim), "ref": float(ref), "real": float(real)}


def _distribution_rows(section: str, metric: str, group: str, sim, ref, real) -> list[dict]:
    """n, median, iqr of each source, then the Wasserstein distances from the simulated one.
    `real` None: the statistic does not exist in real data (NaN)."""
    ss, sr = summary(sim), summary(ref)
    sq = summary(real) if real is not None else dict.fromkeys(ss, np.nan)
    rows = [_row(section, metric, group, k, ss[k], sr[k], sq[k]) for k in ("n", "median", "iqr")]
    w_real = wasserstein(sim, real) if real is not None else np.nan
    rows.append(_row(section, metric, group, "wasserstein", np.nan, wasserstein(sim, ref), w_real))
    return rows


def real_serve_speeds(points: pd.DataFrame) -> pd.DataFrame:
    """Serve speeds of a real points table as `shot_quantities` rows (hitter = server): the
    recorded speed of first serves in and of second serves (slam files record no fault's
    speed)."""
    fsi = points["first_serve_in"].astype("boolean")
    kmh = pd.to_numeric(points["serve_kmh"]).astype(float)
    parts = []
    for name, mask in (("first_serve_kmh", fsi.fillna(False)), ("second_serve_kmh",
                                                                ~fsi.fillna(True))):
        m = mask.to_numpy(bool) & np.isfinite(kmh.to_numpy())
        parts.append(pd.DataFrame({"hitter": points["server"].astype(str).to_numpy()[m],
                                   "quantity": name, "value": kmh.to_numpy()[m]}))
    return pd.concat(parts, ignore_index=True)


def _names(*columns: pd.Series) -> list[str]:
    return sorted(set().union(*(set(c.astype(str)) for c in columns)))


def _values(df: pd.DataFrame, col: str, group: str, **eq) -> np.ndarray:
    m = np.ones(len(df), dtype=bool)
    for k, v in eq.items():
        m &= df[k].to_numpy() == v
    if group != ALL:
        m &= df[col].astype(str).to_numpy() == group
    return df.loc[m, "value"].to_numpy(float)


def _pooled(points: pd.DataFrame) -> pd.DataFrame:
    """The points twice: as they are, and with every server (and a server's winning) renamed
    `ALL`, the pooled group."""
    won = (points["winner"].astype("string") == points["server"].astype("string")).fillna(False)
    pooled = points.assign(server=ALL, winner=points["winner"].astype("string").mask(won, ALL))
    return pd.concat([points, pooled], ignore_index=True)


def _physical_rows(sim: Sample, ref: Sample, real_speeds: pd.DataFrame | None,
                   groups: list[str]) -> list[dict]:
    rows: list[dict] = []
    for q in QUANTITIES:
        for g in groups:
            real = None
            if real_speeds is not None and q in REAL_QUANTITIES:
                real = _values(real_speeds, "hitter", g, quantity=q)
            rows += _distribution_rows("physical", q, g,
                                       _values(sim.shots, "hitter", g, quantity=q),
                                       _values(ref.shots, "hitter", g, quantity=q), real)
    return rows


def _bounce_rows(sim: Sample, ref: Sample) -> list[dict]:
    rows: list[dict] = []
    for surf in _names(sim.bounces["surface"], ref.bounces["surface"]):
        sim_r, ref_r = (b.loc[b["surface"].astype(str) == surf, "ratio"].to_numpy(float)
                        for b in (sim.bounces, ref.bounces))
        rows += _distribution_rows("bounce", "bounce_speed_ratio", surf, sim_r, ref_r, None)
    return rows


def _rally_lengths(points: pd.DataFrame | None, group: str) -> np.ndarray | None:
    if points is None:
        return None
    p = points if group == ALL else points[points["server"].astype(str) == group]
    v = pd.to_numeric(p["rally"]).astype("Float64").astype(float).to_numpy()
    return v[np.isfinite(v)]


def _points_rows(points: dict[str, pd.DataFrame | None], groups: list[str]) -> list[dict]:
    """Serving statistics (`serve_stats`) and rally lengths (`rally_distribution`, mean,
    Wasserstein) of the points tables of sim, ref and real (None: absent)."""
    def per(fn):
        return {k: fn(_pooled(p)) if p is not None and len(p) else None
                for k, p in points.items()}

    def cell(tables, g, col):
        return [tables[k].at[g, col] if tables[k] is not None and g in tables[k].index
                else np.nan for k in ("sim", "ref", "real")]

    stats, dist = per(serve_stats), per(rally_distribution)
    bins = next((d.columns for d in dist.values() if d is not None), [])
    rows: list[dict] = []
    for g in groups:
        rows += [_row("serve", col, g, "value", *cell(stats, g, col))
                 for col in SERVE_STATS_COLUMNS]
    for g in groups:
        rows += [_row("rally", "rally_length", g, f"share_{b}", *cell(dist, g, b)) for b in bins]
        rl = {k: _rally_lengths(p, g) for k, p in points.items()}
        rows.append(_row("rally", "rally_length", g, "mean", *(
            float(np.mean(rl[k])) if rl[k] is not None and len(rl[k]) else np.nan
            for k in ("sim", "ref", "real"))))
        w_real = wasserstein(rl["sim"], rl["real"]) if rl["real"] is not None else np.nan
        rows.append(_row("rally", "rally_length", g, "wasserstein", np.nan,
                         wasserstein(rl["sim"], rl["ref"]), w_real))
    return rows


def compare(sim: Sample, ref: Sample, real_points: pd.DataFrame | None = None) -> pd.DataFrame:
    """The metrics table (`METRIC_COLUMNS`) of `sim` against `ref`, with the real figures of
    `real_points` (a slam points table) where the statistic exists: serve speeds, serving
    statistics and rally lengths. Groups: `ALL` and each player of `sim` or `ref` (as hitter or
    server); bounces by surface. Real points of other servers are left out."""
    players = _names(sim.shots["hitter"], ref.shots["hitter"], sim.points["server"],
                     ref.points["server"])
    groups = [ALL] + players
    real = None
    if real_points is not None:
        real = real_points[real_points["server"].astype(str).isin(players)]
    rows = _physical_rows(sim, ref, real_serve_speeds(real) if real is not None else None,
                          groups)
    rows += _bounce_rows(sim, ref)
    rows += _points_rows({"sim": sim.points, "ref": ref.points, "real": real}, groups)
    for key in ("n_rallies", "non_realistic_share", "undecided_share"):
        rows.append(_row("realism", key, ALL, "value", sim.realism[key], ref.realism[key],
                         np.nan))
    rows.append(_row("realism", "n_points_counted", ALL, "value", len(sim.points),
                     len(ref.points), len(real) if real is not None else np.nan))
    return pd.DataFrame(rows, columns=list(METRIC_COLUMNS))


def compare_data(sim: RallyData, ref: RallyData, real_points: pd.DataFrame | None = None,
                 speed_from: str = "tracks") -> pd.DataFrame:
    """`compare` of two `RallyData` (each `collect`ed first)."""
    return compare(collect(sim, speed_from), collect(ref, speed_from), real_points)
