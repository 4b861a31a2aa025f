"""Command line of `sportsngen.eval`: the realism report and the leak check.

    python -m sportsngen.eval report --sim FOLDER --ref FOLDER --out DIR
    python -m sportsngen.eval report --sim FOLDER --ref-synthetic "Roger Federer,Rafael Nadal" \\
        [--surface hard] [--points N] [--seed 0] [--real-year 2011 | --no-real] --out DIR
    python -m sportsngen.eval leaks FOLDER [--k 6 12] [--boot N] [--seed S] [--csv PATH] \\
        [--band 0.4 0.6] [--min-pairs 10] [--fail-on outside|sure] [--paths] [--exact]
    python -m sportsngen.eval diagnose [--model PATH] [--points 400] [--seed 0] [--csv PATH]
        [--exact-leaks]
        [--top-p-ball P] [--[no-]contact-odds] [--top-p-contact P] [--[no-]strike-in-reach]
        [--strike-in-reach-from N] [--[no-]strike-in-reach-force] [--top-p-serve P]
    python -m sportsngen.eval strikes [--model PATH] [--points 800] [--shots 1 2 3 4 5]
        [--after -1] [--seed 0] [--csv PATH] [sampling options as diagnose]
    python -m sportsngen.eval strike-draws [--model PATH] [--points 1000] [--draws 6] [--seed 0]
    python -m sportsngen.eval movement [--model PATH] [--shot 2] [--chase] [--points 600]
        [--server NAME] [--seed 0] [--csv PATH] [sampling options as diagnose]
    python -m sportsngen.eval chase [--model PATH] [--points 400] [--seed 0] [--csv PATH]
    python -m sportsngen.eval interventions [--model PATH] [--points 400] [--own]
        [--arms free recorded still swapped] [--boot 1000] [--seed 0] [--csv PATH]
    python -m sportsngen.eval expert [FOLDER] [--shot 3 [4 ...]] [--after 8] [--unplayed]
        [--points 1000] [--seed 0] [--csv PATH]

Folders are `RallyData.save` folders, read without physics validation (simulated rallies may
break physics and are flagged, not refused). `--ref-synthetic` generates the reference with
`sportsngen.synth.generate_matches` (default: the simulated data's surfaces and number of
points). Real slam points of `--real-year` served by the same players form a third column when
the shared data is present; without it the report is written without them and a note says why.
`diagnose` prints the rollout diagnostics of `sportsngen.eval.diagnostics` for a model file
(default the bundled model); `strikes` the model's strikes of recorded approaches shot by shot
(`sportsngen.eval.shot_branches.strike_shares`); `strike-draws` the strike head
teacher-forced at recorded rally strikes, its errors by shot and serve beside the record's
(`sportsngen.eval.strike_draws`); `movement` the hitter's run after his shot,
teacher-forced and rolled out against the record, or with `--chase` the answering player's run
to the ball, teacher-forced against the record (`sportsngen.eval.movement`); `chase` the
model's players rolled out on the record's ball, how often it passes beyond their reach
(`sportsngen.eval.chase`); `interventions` the serves branched with the server's track
forced by hand (recorded, stopped, another serve's run), the return share of each arm against
the recorded track's (`sportsngen.eval.interventions`; `--own`: the model's own serves);
`expert` the
generator's players on a folder's own rally states, their next shot beside the folder's
(`sportsngen.eval.expert_answers`; without a folder, on generated points: the kernel's own
fidelity). `leaks` prints the AUC table of
`sportsngen.eval.leaks` (with `--paths` also the path-matched fault check of
`sportsngen.eval.leak_paths`) and exits with status 1 when some AUC lies outside the band (a
gate for CI; `--fail-on sure` only where the AUC's bootstrap interval also leaves out 0.5,
the others marked unsure); an AUC resting on fewer than `--min-pairs` comparable pairs is
marked thin, not read.
Exit status 2 on a missing folder, empty data or a bad option.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sportsngen.data.tracking import RallyData, TrackingDataError
from sportsngen.errors import ArgumentError
from sportsngen.eval.sampling_options import add_sampling_options, sampling_kwargs

_TABLES = ("frames", "rallies", "shots")


class UsageError(Exception):
    """A problem with the command's inputs, reported as one line and exit status 2."""


def load_tracking(folder: str | Path, what: str) -> RallyData:
    """A `RallyData.save` folder, columns cast but physics not validated; UsageError when the
    folder or a table is missing or it holds no rallies."""
    folder = Path(folder)
    if not folder.is_dir():
        raise UsageError(f"{what}: no tracking folder at {folder}")
    absent = [f"{n}.parquet" for n in _TABLES if not (folder / f"{n}.parquet").is_file()]
    if absent:
        raise UsageError(f"{what}: {folder} is not a RallyData folder (lacks {absent})")
    try:
        data = _read(folder)
    except TrackingDataError as exc:
        raise UsageError(f"{what}: {folder}: {exc}") from exc
    if len(data.rallies) == 0:
        raise UsageError(f"{what}: {folder} holds no rallies")
    return data


def _read(folder: Path) -> RallyData:
    """A RallyData folder, without validation (simulated rallies may break physics)."""
    return RallyData.load(folder, validate=False)


def synthetic_reference(players: str, surface: list[str], n_points: int, seed: int) -> RallyData:
    """Ground truth of the matchup "A,B" from the generator (one worker process)."""
    from sportsngen.synth import generate_matches

    names = [p.strip() for p in players.split(",") if p.strip()]
    if len(names) != 2:
        raise UsageError(f"--ref-synthetic wants two players 'A,B', got {players!r}")
    try:
        return generate_matches([tuple(names)], surface, n_points, seed=seed, workers=1)
    except ValueError as exc:
        raise UsageError(f"--ref-synthetic: {exc}") from exc


def _real_points(sim: RallyData, year: int):
    """Real points of `year` served by the simulated players, or None with a note why not."""
    from sportsngen.eval.report import load_real_points

    players = sorted(set(sim.rallies["server"].astype(str)) | set(sim.rallies["receiver"]
                                                                   .astype(str)))
    try:
        return load_real_points(players, year)
    except (FileNotFoundError, ValueError) as exc:
        print(f"note: report written without real figures: {exc}", file=sys.stderr)
        return None


def run_report(args: argparse.Namespace) -> Path:
    from sportsngen.eval.report import write_report

    sim = load_tracking(args.sim, "--sim")
    if args.ref is not None:
        ref = load_tracking(args.ref, "--ref")
    else:
        surface = args.surface or sorted(set(sim.rallies["surface"].astype(str)))
        n_points = args.points or int(sim.rallies.groupby(["match_id", "point"]).ngroups)
        if n_points < 1:
            raise UsageError(f"--points must be positive, got {n_points}")
        ref = synthetic_reference(args.ref_synthetic, surface, n_points, args.seed)
    labels = tuple(s.strip() for s in args.labels.split(",")) if args.labels else \
        ("simulated", "synthetic truth" if args.ref is None else "reference")
    if len(labels) != 2:
        raise UsageError(f"--labels wants two names 'A,B', got {args.labels!r}")
    real = None if args.no_real else _real_points(sim, args.real_year)
    return write_report(sim, ref, args.out, real_points=real, labels=labels)


def run_leaks(args: argparse.Namespace) -> int:
    """The leak check on a folder: prints the table, writes the CSV; 1 if an AUC is outside
    the band, else 0."""
    import pandas as pd

    from sportsngen.eval.leaks import check_leaks, outside_band, render_leaks, sure_leaks

    lo, hi = args.band
    if not 0.0 <= lo < hi <= 1.0:
        raise UsageError(f"--band wants 0 <= LOW < HIGH <= 1, got {lo:g} {hi:g}")
    if min(args.k) < 0:
        raise UsageError(f"--k wants frame offsets >= 0, got {args.k}")
    if args.boot < 0 or args.seed < 0 or args.min_pairs < 1:
        raise UsageError(f"--boot and --seed must be >= 0 and --min-pairs >= 1, got "
                         f"{args.boot}, {args.seed}, {args.min_pairs}")
    data = load_tracking(args.folder, "leaks")
    try:
        table = check_leaks(data, ks=args.k, n_boot=args.boot, seed=args.seed,
                            stratify=not args.raw, resolution={} if args.exact else None)
    except ValueError as exc:
        raise UsageError(f"leaks: {args.folder}: {exc}") from exc
    print(render_leaks(table, (lo, hi), args.min_pairs))
    if args.paths:
        from sportsngen.eval.leak_paths import check_fault_paths

        paths = check_fault_paths(data, ks=args.k, n_boot=args.boot, seed=args.seed)
        print("\nPath-matched, fault against in (sportsngen.eval.leak_paths):\n")
        print(render_leaks(paths, (lo, hi), args.min_pairs))
        table = pd.concat([table, paths.assign(check="path_matched")], ignore_index=True)
    if args.csv is not None:
        args.csv.parent.mkdir(parents=True, exist_ok=True)
        table.to_csv(args.csv, index=False)
        print(f"wrote {args.csv}")
    fail = outside_band if args.fail_on == "outside" else sure_leaks
    return int(fail(table, (lo, hi), args.min_pairs).any())


def _simulator(args: argparse.Namespace):
    """The model file of `args.model` (default the bundled one) with the sampling options."""
    from sportsngen.sim import Simulator

    if args.points < 20 or args.seed < 0:
        raise UsageError(f"--points must be >= 20 and --seed >= 0, got {args.points}, "
                         f"{args.seed}")
    try:
        kw = sampling_kwargs(args)
    except ArgumentError as exc:
        raise UsageError(str(exc)) from exc
    try:
        return Simulator.from_pretrained(args.model, **kw)
    except FileNotFoundError as exc:
        raise UsageError(f"--model: {exc}") from exc


def _print_table(table, csv: Path | None, footer: str, notes: tuple[str, ...] = (),
                 csv_table=None) -> None:
    """Print `table`, any `notes` and the `footer`; write `csv_table` (default the table) to
    `csv` when given."""
    import pandas as pd

    with pd.option_context("display.width", 160, "display.max_colwidth", 60):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    for line in notes:
        print(line)
    print(footer)
    if csv is not None:
        csv.parent.mkdir(parents=True, exist_ok=True)
        (table if csv_table is None else csv_table).to_csv(csv, index=False)
        print(f"wrote {csv}")


def _run_model_table(args: argparse.Namespace, name: str, compute, notes=None,
                     **setup_kw) -> int:
    """A model's table over generated truth: the model file and sampling of `args`, the truth
    of its matchup, `compute(sim, setup)` -> the table, printed with `notes(table)`'s lines
    (and written as CSV)."""
    import time

    from sportsngen.eval.diagnostics import DiagnosticsSetup

    sim = _simulator(args)
    t0 = time.perf_counter()
    setup = DiagnosticsSetup(server=args.server, receiver=args.receiver, surface=args.surface,
                             n_points=args.points, seed=args.seed, **setup_kw)
    try:
        table = compute(sim, setup)
    except ValueError as exc:
        raise UsageError(f"{name}: {exc}") from exc
    _print_table(table, args.csv, f"({time.perf_counter() - t0:.0f} s, {setup.n_points} points "
                 f"of {setup.server} serving to {setup.receiver} on {setup.surface}, seed "
                 f"{setup.seed})", notes=() if notes is None else tuple(notes(table)))
    return 0


def run_diagnose(args: argparse.Namespace) -> int:
    """The rollout diagnostics of a model: prints the table (and writes the CSV)."""
    from sportsngen.eval.diagnostics import leak_rows_advice, leak_rows_summary, run_diagnostics

    if args.boot < 0:
        raise UsageError(f"--boot must be >= 0, got {args.boot}")
    advice = leak_rows_advice(args.points)
    return _run_model_table(args, "diagnose", run_diagnostics,
                            notes=lambda t: (leak_rows_summary(t),) + ((advice,) if advice else ()),
                            leak_boot=args.boot, leak_exact=args.exact_leaks)


def run_strikes(args: argparse.Namespace) -> int:
    """The model's strikes of recorded approaches, shot by shot: prints the table."""
    from sportsngen.eval.diagnostics import truth_points
    from sportsngen.eval.shot_branches import strike_shares

    if not args.shots or min(args.shots) < 1:
        raise UsageError(f"--shots count contacts after the serve (>= 1), got {args.shots}")
    return _run_model_table(args, "strikes", lambda sim, setup: strike_shares(
        sim, truth_points(setup), tuple(args.shots), after_frames=args.after, seed=args.seed))


def _run_head_draws(args: argparse.Namespace, name: str, table) -> int:
    """A head teacher-forced at the recorded strikes of generated truth: `table(sim, truth,
    draws=, seed=)` printed."""
    from sportsngen.eval.diagnostics import truth_points

    if args.draws < 1:
        raise UsageError(f"--draws must be >= 1, got {args.draws}")
    return _run_model_table(args, name, lambda sim, setup: table(
        sim, truth_points(setup), draws=args.draws, seed=args.seed))


def run_serves(args: argparse.Namespace) -> int:
    """The serve head teacher-forced at recorded serves, by serve number: prints the table."""
    from sportsngen.eval.serve_draws import serve_draw_table

    return _run_head_draws(args, "serves", serve_draw_table)


def run_strike_draws(args: argparse.Namespace) -> int:
    """The strike head teacher-forced at recorded rally strikes, by shot and serve."""
    from sportsngen.eval.strike_draws import strike_draw_table

    return _run_head_draws(args, "strike-draws", strike_draw_table)


def run_movement(args: argparse.Namespace) -> int:
    """The hitter's run after his shot, record / teacher-forced / rolled out, or with
    --chase the answering player's run to the ball, record / teacher-forced: prints it."""
    from sportsngen.eval.diagnostics import truth_points
    from sportsngen.eval.movement import chase_curves, recovery_curves

    if args.chase:
        shot = 1 if args.shot is None else args.shot
        if shot < 0:
            raise UsageError(f"--shot counts contacts from the serve (>= 0), got {shot}")
        return _run_model_table(args, "movement", lambda sim, setup: chase_curves(
            sim, truth_points(setup), shot=shot, seed=args.seed))
    shot = 2 if args.shot is None else args.shot
    if shot < 0:
        raise UsageError(f"--shot counts contacts from the serve (>= 0), got {shot}")
    return _run_model_table(args, "movement", lambda sim, setup: recovery_curves(
        sim, truth_points(setup), shot=shot, seed=args.seed))


def run_chase(args: argparse.Namespace) -> int:
    """The model's players on the record's ball: prints the shares of balls out of reach."""
    import pandas as pd

    from sportsngen.eval.chase import along_table, chase_table, players_on_the_record
    from sportsngen.eval.diagnostics import truth_points

    def compute(sim, setup):
        rows = players_on_the_record(sim.model, sim.vocab, truth_points(setup),
                                     top_p_player=sim.top_p_player, seed=setup.seed,
                                     keep_chasing=sim.keep_chasing)
        along = along_table(rows)
        with pd.option_context("display.width", 160):
            print(along.to_string(index=False, float_format=lambda v: f"{v:.2f}"))
        return chase_table(rows)

    return _run_model_table(args, "chase", compute)


def run_interventions(args: argparse.Namespace) -> int:
    """Serves branched with the server's track forced in each arm: prints the return shares."""
    from sportsngen.eval.diagnostics import own_serves, truth_points
    from sportsngen.eval.interventions import ARMS, intervention_outcomes, intervention_table

    arms = tuple(dict.fromkeys(args.arms or ARMS))
    if set(arms) - set(ARMS):
        raise UsageError(f"--arms: unknown {sorted(set(arms) - set(ARMS))}, choose from {ARMS}")
    if "recorded" not in arms:
        raise UsageError(f"--arms must include 'recorded' (the arm the others are read "
                         f"against), got {list(arms)}")
    if args.boot < 0:
        raise UsageError(f"--boot must be >= 0, got {args.boot}")

    def compute(sim, setup):
        truth = truth_points(setup)
        data = own_serves(sim, truth, seed=setup.seed) if args.own else truth
        out = intervention_outcomes(sim, data, arms, setup.seed)
        return intervention_table(out, n_boot=args.boot, seed=setup.seed)

    return _run_model_table(args, "interventions", compute)


def run_expert(args: argparse.Namespace) -> int:
    """The kernel's next shot on a folder's (or generated points') own states: prints it."""
    import time

    from sportsngen.eval.expert_answers import (
        expert_shots,
        paired_expert_gaps,
        summarise_expert_shots,
    )

    t0 = time.perf_counter()
    if args.folder is not None:
        data, what = load_tracking(args.folder, "expert"), str(args.folder)
    else:
        from sportsngen.synth import generate_matches

        if args.points < 20:
            raise UsageError(f"--points must be >= 20, got {args.points}")
        data = generate_matches([(args.server, args.receiver)], args.surface,
                                n_points=args.points, seed=args.seed, workers=1)
        what = f"{args.points} generated points of {args.server} v {args.receiver}"
    try:
        rows = expert_shots(data, shot=tuple(args.shot), after_frames=args.after,
                            seed=args.seed, unplayed=args.unplayed)
        gaps = paired_expert_gaps(rows)
    except ValueError as exc:
        raise UsageError(f"expert: {exc}") from exc
    ends = rows.loc[rows["expert_end"] != "", "expert_end"].value_counts()
    notes = ["the kernel struck nothing: " + ", ".join(f"{k} {v}" for k, v in ends.items())
             ] if len(ends) else []
    notes += ["", "in play of the shots both struck from the same states, by hitter and role "
              "(gap: the rally's less the kernel's, with its standard error):",
              gaps.to_string(index=False, float_format=lambda v: f"{v:.3f}")]
    shots = " ".join(str(s) for s in args.shot)
    _print_table(summarise_expert_shots(rows), args.csv,
                 f"({time.perf_counter() - t0:.0f} s, shots {shots} each handed over "
                 f"{args.after} frames after the shot before, {what})", tuple(notes), rows)
    return 0


def run_reach(args: argparse.Namespace) -> int:
    """Who reaches the ball, by how far he had to go: prints a table per folder (or for
    generated points)."""
    import time

    from sportsngen.eval.reach import (
        answered_by_need,
        contact_rows,
        contact_states,
        reach_rows,
        toward_speeds,
    )

    sources = [(str(f), lambda f=f: load_tracking(f, "reach")) for f in args.folders]
    if not sources:
        from sportsngen.synth import generate_matches

        if args.points < 20:
            raise UsageError(f"--points must be >= 20, got {args.points}")
        sources = [(f"{args.points} generated points of {args.server} v {args.receiver}",
                    lambda: generate_matches([(args.server, args.receiver)], args.surface,
                                             n_points=args.points, seed=args.seed, workers=1))]
    for what, load in sources:
        t0 = time.perf_counter()
        data = load()
        rows = reach_rows(data)
        try:
            table = answered_by_need(rows)
        except ValueError as exc:
            raise UsageError(f"reach: {what}: {exc}") from exc
        speeds = toward_speeds(rows)
        fmt = {"index": False, "float_format": lambda v: f"{v:.3f}"}
        notes = ["by the mean speed the ball asks for (its need over the time it gives):",
                 answered_by_need(rows, by="need_speed_mps").to_string(**fmt),
                 "by how close the ball came to him as he moved (beyond 1.5 m: where he was, "
                 "not whether he struck it):",
                 answered_by_need(rows, by="gap_m").to_string(**fmt),
                 "mean speed toward the ball's nearest point (m/s), needs of 3-7 m:",
                 speeds.to_string(index=False, float_format=lambda v: f"{v:.2f}")]
        if (rows["shot"] == 0).any():
            serves = toward_speeds(rows, need_m=(1.0, 7.0), shots="serve")
            notes += ["good serves, returned by need (a miss is an ace):",
                      answered_by_need(rows, shots="serve").to_string(**fmt),
                      "good serves, returned by how close they came to him:",
                      answered_by_need(rows, by="gap_m", shots="serve").to_string(**fmt),
                      "the receiver's speed toward the serve (m/s), needs of 1-7 m:",
                      serves.to_string(index=False, float_format=lambda v: f"{v:.2f}")]
        contacts = contact_rows(data)
        if len(contacts):
            notes += ["where the ball is struck, medians by shot (behind the baseline, height, "
                      "gap to the hitter in m; speed in and out in m/s):",
                      contact_states(contacts).to_string(index=False,
                                                         float_format=lambda v: f"{v:.2f}")]
        _print_table(table, None, f"({time.perf_counter() - t0:.0f} s, {what})", tuple(notes))
    return 0


EXACT_LEAKS_HELP = ("rank the leak check's speeds and accelerations as exact floats, as recorded "
                    "before its resolution (default: ties within "
                    "sportsngen.eval.leaks.FEATURE_RESOLUTION)")


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m sportsngen.eval",
                                 description="Realism evaluation of simulated tennis tracking.")
    sub = ap.add_subparsers(dest="command", required=True)
    rep = sub.add_parser("report", help="report.md, metrics.csv and figures: simulated play "
                                        "against a reference and real slam figures")
    rep.add_argument("--sim", required=True, help="RallyData folder of the simulated play")
    ref = rep.add_mutually_exclusive_group(required=True)
    ref.add_argument("--ref", help="RallyData folder of the reference")
    ref.add_argument("--ref-synthetic", metavar="'A,B'",
                     help="generate the reference: synthetic matches between players A and B")
    rep.add_argument("--surface", nargs="+", default=None,
                     help="surface(s) of the synthetic reference (default: the simulated ones)")
    rep.add_argument("--points", type=int, default=None,
                     help="points of the synthetic reference (default: as many as simulated)")
    rep.add_argument("--seed", type=int, default=0, help="seed of the synthetic reference")
    rep.add_argument("--real-year", type=int, default=2011,
                     help="year of the real slam points beside them (default 2011)")
    rep.add_argument("--no-real", action="store_true", help="leave the real figures out")
    rep.add_argument("--labels", default=None,
                     help="names of the two sources, 'simulated,reference'")
    rep.add_argument("--out", required=True, type=Path, help="folder to write the report into")
    leaks = sub.add_parser("leaks", help="do players move as if they knew a contact's outcome "
                                         "before it is visible? AUC table; exit 1 outside band")
    leaks.add_argument("folder", type=Path, help="RallyData folder (RallyData.save)")
    leaks.add_argument("--k", type=int, nargs="+", default=[6, 12],
                       help="frames after the contact, at 25 Hz (default 6 12)")
    leaks.add_argument("--boot", type=int, default=1000, help="bootstrap resamples of rallies")
    leaks.add_argument("--seed", type=int, default=0, help="seed of the bootstrap")
    leaks.add_argument("--csv", type=Path, default=None, help="write the table as CSV here")
    leaks.add_argument("--raw", action="store_true",
                       help="raw AUCs, not stratified by what the players could see (pairing, "
                            "serve number, direction, depth, speed, the seen flight and, for "
                            "the opponent, how far aside it passes him, for the hitter, how "
                            "fast and how far across he saw it go)")
    leaks.add_argument("--exact", action="store_true", help=EXACT_LEAKS_HELP)
    leaks.add_argument("--paths", action="store_true",
                       help="also the path-matched check of faults: is the movement before a "
                            "fault explained by the ball's path and the player's position?")
    leaks.add_argument("--band", type=float, nargs=2, default=[0.4, 0.6],
                       metavar=("LOW", "HIGH"), help="AUCs outside it fail (default 0.4 0.6)")
    leaks.add_argument("--fail-on", choices=("outside", "sure"), default="outside",
                       help="exit 1 on any AUC outside the band (default), or only where its "
                            "bootstrap interval also leaves out 0.5 ('sure': small samples put "
                            "cells outside by chance; marked unsure in the table)")
    from sportsngen.eval.leaks import MIN_READ_PAIRS

    leaks.add_argument("--min-pairs", type=int, default=MIN_READ_PAIRS,
                       help="an AUC on fewer comparable pairs is too few to read: marked thin, "
                            f"not failed (default {MIN_READ_PAIRS})")
    model_opts = argparse.ArgumentParser(add_help=False)
    model_opts.add_argument("--model", default=None,
                            help="model file (default: the bundled model)")
    model_opts.add_argument("--seed", type=int, default=0,
                            help="seed of the truth and the rollouts")
    model_opts.add_argument("--server", default="Roger Federer")
    model_opts.add_argument("--receiver", default="Rafael Nadal")
    model_opts.add_argument("--surface", default="hard", choices=["hard", "clay", "grass"])
    model_opts.add_argument("--csv", type=Path, default=None, help="write the table as CSV here")
    add_sampling_options(model_opts)
    diag = sub.add_parser("diagnose", parents=[model_opts],
                          help="rollout diagnostics of a model: branch return share, "
                               "free-flight residual, contact probability, receivers at the "
                               "bounce, leaks on rollouts")
    diag.add_argument("--points", type=int, default=400,
                      help="ground-truth points generated to branch from (default 400)")
    diag.add_argument("--boot", type=int, default=200, help="bootstrap resamples of the leaks")
    diag.add_argument("--exact-leaks", action="store_true", help=EXACT_LEAKS_HELP)
    strikes = sub.add_parser("strikes", parents=[model_opts],
                             help="the model strikes recorded approaches, shot by shot: shares "
                                  "struck and in play by hitter, beside the record")
    strikes.add_argument("--points", type=int, default=800,
                         help="ground-truth points generated to branch from (default 800)")
    strikes.add_argument("--shots", type=int, nargs="+", default=[1, 2, 3, 4, 5],
                         help="contacts after the serve to branch at (default 1 2 3 4 5)")
    strikes.add_argument("--after", type=int, default=-1,
                         help="frames kept after the recorded contact (default -1: the model "
                              "strikes)")
    move = sub.add_parser("movement", parents=[model_opts],
                          help="the hitter's run after his shot: record, teacher-forced and "
                               "rolled out")
    move.add_argument("--points", type=int, default=600,
                      help="ground-truth points generated (default 600)")
    move.add_argument("--shot", type=int, default=None,
                      help="the hitter's shot, counted after the serve (default 2: the "
                           "server's first rally ball; 0 the server's run back from his "
                           "serve); with --chase the shot whose ball is chased (default 1: the "
                           "return, chased by the server)")
    move.add_argument("--chase", action="store_true",
                      help="the answering player's run to the ball, record and teacher-forced, "
                           "by how far he had to go")
    chase = sub.add_parser("chase", parents=[model_opts],
                           help="the model's players on the record's ball: how often it passes "
                                "out of their reach, by shot and by how far the record ran")
    chase.add_argument("--points", type=int, default=400,
                       help="ground-truth points generated (default 400)")
    for name, points, what, help_text in (
            ("serves", 600, "serve", "the serve head teacher-forced at recorded serves: faults "
                                     "(long, wide, net) and speed by serve, beside the record"),
            ("strike-draws", 1000, "strike", "the strike head teacher-forced at recorded rally "
                                             "strikes: errors by shot and serve, beside the "
                                             "record")):
        draws = sub.add_parser(name, parents=[model_opts], help=help_text)
        draws.add_argument("--points", type=int, default=points,
                           help=f"ground-truth points generated (default {points})")
        draws.add_argument("--draws", type=int, default=6, help=f"draws of the head a {what}")
    # Generated points where no folder is given (expert, reach).
    generated = argparse.ArgumentParser(add_help=False)
    generated.add_argument("--seed", type=int, default=0)
    generated.add_argument("--server", default="Roger Federer")
    generated.add_argument("--receiver", default="Rafael Nadal")
    generated.add_argument("--surface", default="hard", choices=["hard", "clay", "grass"])
    inter = sub.add_parser("interventions", parents=[model_opts],
                           help="does the serve's outcome depend on how the server moves after "
                                "it? serves branched with his track forced, arm by arm")
    inter.add_argument("--points", type=int, default=400,
                       help="ground-truth points generated to branch from (default 400)")
    inter.add_argument("--arms", nargs="+", default=None,
                       help="the server's track in each arm, of free, recorded, still and "
                            "swapped (default all four; 'recorded' needed)")
    inter.add_argument("--own", action="store_true",
                       help="branch the model's own serves, played from the toss, not the "
                            "recorded ones")
    inter.add_argument("--boot", type=int, default=1000,
                       help="bootstrap resamples of the paired differences")
    expert = sub.add_parser("expert", parents=[generated],
                            help="the generator's players on a folder's own rally states: "
                                 "their next shot beside the folder's")
    expert.add_argument("folder", type=Path, nargs="?", default=None,
                        help="RallyData folder (default: generated points, the kernel's "
                             "fidelity)")
    expert.add_argument("--shot", type=int, nargs="+", default=[3],
                        help="the shots answered, counted after the serve (default 3)")
    expert.add_argument("--after", type=int, default=8,
                        help="frames after the shot before it that the kernel takes over")
    expert.add_argument("--unplayed", action="store_true",
                        help="also the rallies whose shot never came (a ball let go or "
                             "missed): would the kernel have struck it?")
    expert.add_argument("--points", type=int, default=1000,
                        help="generated points without a folder (default 1000)")
    expert.add_argument("--csv", type=Path, default=None, help="write the rows as CSV here")
    reach = sub.add_parser("reach", parents=[generated],
                           help="who reaches the ball: the good rally balls answered, by how "
                                "far the player had to go and how fast")
    reach.add_argument("folders", type=Path, nargs="*",
                       help="RallyData folders (default: generated points)")
    reach.add_argument("--points", type=int, default=500,
                       help="generated points without a folder (default 500)")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    runners = {"leaks": run_leaks, "diagnose": run_diagnose, "strikes": run_strikes,
               "movement": run_movement, "serves": run_serves, "expert": run_expert,
               "reach": run_reach, "strike-draws": run_strike_draws,
               "chase": run_chase, "interventions": run_interventions}
    try:
        if args.command in runners:
            return runners[args.command](args)
        path = run_report(args)
    except UsageError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {path} (+ metrics.csv, figures/)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
