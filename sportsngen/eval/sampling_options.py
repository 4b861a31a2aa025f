"""The simulator's sampling options on a command line: one set of flags for every command that
rolls a model out (`python -m sportsngen.eval ...`, `scripts/check_simulation.py`), each
defaulting to the model file's `sim_defaults`."""

from __future__ import annotations

import argparse

from sportsngen.errors import ArgumentError
from sportsngen.sim.kinematics import check_player_rules

_NUCLEI = ("top_p_ball", "top_p_contact", "top_p_serve")
_FLAGS = ("contact_odds", "strike_in_reach", "strike_in_reach_from", "strike_in_reach_force",
          "strike_in_reach_m", "ball_net", "keep_chasing", "contact_reach_m",
          "return_reach_m", "strike_in_reach_return_m", "physical_bounce",
          "player_accel_mps2", "chase_high_balls", "return_reach_draw", "rally_reach_draw",
          "player_top_speed", "player_accel_full_frac", "player_keep_heading_deg")

# The rules that read a table of the model file's extra, switched on and off by name.
_TABLE_SWITCHES = (
    ("--return-reach-draw", "each serve's return reach drawn from its receiver's row of the "
                            "file's table (scripts/fit_return_reach.py)"),
    ("--rally-reach-draw", "each rally ball's reach drawn from the row of the player due in the "
                           "file's table (scripts/fit_return_reach.py --rally)"),
    ("--player-top-speed", "each player runs no faster than his record's top speed, the file's "
                           "table (scripts/fit_top_speed.py)"),
)


def add_sampling_options(parser: argparse.ArgumentParser) -> None:
    """Add the `Simulator` sampling flags to `parser` (every default None: the model file's)."""
    parser.add_argument("--top-p-ball", type=float, default=None,
                        help="the ball's nucleus (default: the model file's, else 1)")
    parser.add_argument("--contact-odds", action=argparse.BooleanOptionalAction, default=None,
                        help="the ball's nucleus keeps the model's odds of a racket contact "
                             "(default: the model file's, else off)")
    parser.add_argument("--top-p-contact", type=float, default=None,
                        help="with contact odds, the nucleus of a struck ball (default: the "
                             "model file's, else the ball's)")
    parser.add_argument("--top-p-serve", type=float, default=None,
                        help="with a serve head, its nucleus (default: the model file's, else 1)")
    parser.add_argument("--strike-in-reach", action=argparse.BooleanOptionalAction,
                        default=None,
                        help="a good ball passing within a player's reach is struck "
                             "(default: the model file's, else off)")
    parser.add_argument("--strike-in-reach-from", type=int, default=None,
                        help="with --strike-in-reach: from this contact on (1 the return, 2 the "
                             "server's first rally ball; default: the model file's, else 1)")
    parser.add_argument("--strike-in-reach-force", action=argparse.BooleanOptionalAction,
                        default=None,
                        help="with --strike-in-reach: where no draw keeps the ball in reach, "
                             "the strike head strikes it (default: the model file's, else off)")
    parser.add_argument("--strike-in-reach-m", type=float, default=None,
                        help="with --strike-in-reach: the reach (m, the ball horizontally from "
                             "the player's centre; default: the model file's, else 1.2)")
    parser.add_argument("--strike-in-reach-return-m", type=float, default=None,
                        help="with --strike-in-reach: the reach for the return (m; default: the "
                             "model file's, else --strike-in-reach-m's)")
    parser.add_argument("--keep-chasing", action=argparse.BooleanOptionalAction, default=None,
                        help="the player due to play the ball does not slow down while he is "
                             "late for it (default: the model file's, else off)")
    parser.add_argument("--chase-high-balls", action=argparse.BooleanOptionalAction,
                        default=None,
                        help="with --keep-chasing, a ball whose bounce carries it above a "
                             "racket is run to where it is at a comfortable height after the "
                             "bounce (default: the model file's, else off)")
    parser.add_argument("--contact-reach-m", type=float, default=None,
                        help="with physical limits, a racket contact needs a player within "
                             "this distance of the ball (m, horizontally; default: the model "
                             "file's, else the rules' 2.5)")
    parser.add_argument("--return-reach-m", type=float, default=None,
                        help="with physical limits, the return (the contact after the serve) "
                             "needs the receiver within this distance of the ball (m, "
                             "horizontally; default: the model file's, else the contact's)")
    for flag, what in _TABLE_SWITCHES:
        parser.add_argument(flag, action=argparse.BooleanOptionalAction, default=None,
                            help=f"{what} (default: the model file's, else off)")
    parser.add_argument("--physical-bounce", action=argparse.BooleanOptionalAction,
                        default=None,
                        help="the ball's bounces are the surface's physics, not the model's "
                             "draw (default: the model file's, else off)")
    parser.add_argument("--player-accel-mps2", type=float, default=None,
                        help="a sampled frame changes a player's velocity by at most this "
                             "acceleration (m/s²; default: the model file's, else none)")
    parser.add_argument("--player-accel-full-frac", type=float, default=None,
                        help="with --player-accel-mps2, a change of at least this fraction of "
                             "it is set to it: flat out (default: the model file's, else none)")
    parser.add_argument("--player-keep-heading-deg", type=float, default=None,
                        help="with --player-accel-mps2, a flat-out change within this angle "
                             "of a running player's heading runs along it (default: the model "
                             "file's, else none)")
    parser.add_argument("--ball-net", action=argparse.BooleanOptionalAction, default=None,
                        help="the ball's physics centre meets the net (default: the model "
                             "file's, else as it was trained)")


def sampling_kwargs(args: argparse.Namespace) -> dict:
    """The `Simulator` keyword arguments the flags of `add_sampling_options` set (those left
    out keep the model file's); `ArgumentError` names a flag out of its range."""
    kw = {}
    for name in _NUCLEI:
        value = getattr(args, name, None)
        if value is not None:
            if not 0.0 < value <= 1.0:
                raise ArgumentError(f"--{name.replace('_', '-')} must be in (0, 1], got {value}")
            kw[name] = value
    for name in _FLAGS:
        value = getattr(args, name, None)
        if value is not None:
            kw[name] = value
    check_player_rules({"accel_mps2": "--player-accel-mps2",
                        "full_from_frac": "--player-accel-full-frac",
                        "keep_heading_deg": "--player-keep-heading-deg"},
                       accel_mps2=kw.get("player_accel_mps2"),
                       full_from_frac=kw.get("player_accel_full_frac"),
                       keep_heading_deg=kw.get("player_keep_heading_deg"))
    if not kw.get("strike_in_reach_m", 1.0) > 0:
        raise ArgumentError(f"--strike-in-reach-m must be positive, got "
                            f"{kw['strike_in_reach_m']}")
    if not kw.get("contact_reach_m", 1.0) > 0:
        raise ArgumentError(f"--contact-reach-m must be positive, got {kw['contact_reach_m']}")
    if not kw.get("strike_in_reach_return_m", 1.0) > 0:
        raise ArgumentError(f"--strike-in-reach-return-m must be positive, got "
                            f"{kw['strike_in_reach_return_m']}")
    if not kw.get("return_reach_m", 1.0) > 0:
        raise ArgumentError(f"--return-reach-m must be positive, got {kw['return_reach_m']}")
    if kw.get("strike_in_reach_from", 1) < 1:
        raise ArgumentError(f"--strike-in-reach-from counts contacts after the serve (>= 1), "
                            f"got {kw['strike_in_reach_from']}")
    return kw
