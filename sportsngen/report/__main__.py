"""Match reports from the command line.

    python -m sportsngen.report real 2011-usopen-1208 [--data FOLDER] [--out report.html]
    python -m sportsngen.report matches 2011-usopen [--data FOLDER]
    python -m sportsngen.report backtest [--data FOLDER] [--out DIR] [--n-boot 1000]
    python -m sportsngen.report check report.html [--out DIR]

`real` writes the report of a recorded slam match (score, live win probability, importance,
key moments, statistics); `matches` lists an event's matches; `backtest` writes the calibration
back-test of the live win probability over every match of the slam files; `check` opens a
report in headless Chromium, takes its screenshots and fails on any JavaScript error or
network request. `--data` defaults to the shared slam folder (see `sportsngen.data.paths`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path


def _real(args: argparse.Namespace) -> int:
    from sportsngen.report.real import recorded_match_report

    t0 = time.perf_counter()
    out = args.out or Path(f"report-{args.match_id}.html")
    path = recorded_match_report(args.match_id, out, args.data)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB) in "
          f"{time.perf_counter() - t0:.1f} s")
    return 0


def _matches(args: argparse.Namespace) -> int:
    from sportsngen.data.slam import _event_files, read_slam_raw
    from sportsngen.report.real import slam_folder

    raw = read_slam_raw(*_event_files(slam_folder(args.data), args.event), repair=True)
    g = raw.groupby("match_id", sort=True)
    table = g[["player1", "player2"]].first().assign(points=g.size())
    print(table.sort_values("points", ascending=False).to_string())
    return 0


def _backtest(args: argparse.Namespace) -> int:
    from sportsngen.report.backtest import run_backtest

    res = run_backtest(args.out, args.data, args.events, n_boot=args.n_boot, seed=args.seed)
    print(res["markdown"])
    print(f"\n{res['n_unfinished']} unfinished matches left out; wrote {args.out}/"
          "backtest.md, backtest.json, backtest_reliability.png")
    return 0


def _check(args: argparse.Namespace) -> int:
    from sportsngen.report.browser import assert_clean, check_report

    seen = check_report(args.html, args.out, rally_play_s=args.rally_play_s,
                        whatif_index=args.whatif)
    print(json.dumps(seen, indent=1))
    try:
        assert_clean(seen)
    except AssertionError as exc:
        print(exc, file=sys.stderr)
        return 1
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m sportsngen.report",
                                 description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    p = sub.add_parser("real", help="report of a recorded slam match")
    p.add_argument("match_id", help='e.g. "2011-usopen-1208"')
    p.add_argument("--data", type=Path, default=None, help="folder of the slam files")
    p.add_argument("--out", type=Path, default=None, help="HTML file to write")
    p.set_defaults(func=_real)
    p = sub.add_parser("matches", help="list the matches of an event, longest first")
    p.add_argument("event", help='e.g. "2011-usopen"')
    p.add_argument("--data", type=Path, default=None)
    p.set_defaults(func=_matches)
    p = sub.add_parser("backtest", help="calibration back-test of the live win probability")
    p.add_argument("--data", type=Path, default=None)
    p.add_argument("--events", nargs="*", default=None, help="default: every event found")
    p.add_argument("--out", type=Path, default=Path("outputs/backtest"))
    p.add_argument("--n-boot", type=int, default=1000)
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=_backtest)
    p = sub.add_parser("check", help="open a report in headless Chromium, take screenshots")
    p.add_argument("html", type=Path)
    p.add_argument("--out", type=Path, default=None, help="folder for the screenshots")
    p.add_argument("--rally-play-s", type=float, default=1.5,
                   help="let the clicked rally play this long before its screenshot")
    p.add_argument("--whatif", type=int, default=0, help="which what-if shot to open (0: first)")
    p.set_defaults(func=_check)
    args = ap.parse_args(argv)
    try:
        return args.func(args)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
