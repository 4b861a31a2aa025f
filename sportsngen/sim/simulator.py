"""`Simulator`: the learned engine's Python API (rallies, service points, matches).

    from sportsngen.sim import Simulator
    sim = Simulator.from_pretrained()                     # the bundled model
    data = sim.simulate_points("Roger Federer", "Rafael Nadal", "hard", n_points=100, seed=0)
    match = sim.simulate_match("Roger Federer", "Rafael Nadal", "hard", seed=0)
    print(match.score_line); print(match.summary())

Everything goes through `simulate_rallies`: a plan (one row a rally: who serves, which serve,
side, end, surface, score) becomes initial frames drawn from the model's pool of historical
serve starts (`sportsngen.data.serve_starts`), one batched rollout (`sportsngen.sim.rollout`) under
the rally-end rules (`sportsngen.tennis.rally`), event labels from the classifier
(`sportsngen.sim.events`) and a `RallyData` (`sportsngen.sim.assemble`).
"""

from __future__ import annotations

import inspect
import math
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from sportsngen.data.serve_starts import InitialConditions
from sportsngen.data.tokens import Vocab
from sportsngen.data.tracking import SURFACES, RallyData
from sportsngen.errors import (
    ArgumentError,
    check_choice,
    check_int,
    check_name,
    check_players,
)
from sportsngen.eval.calibration import IsotonicCalibrator, LogisticCalibrator, calibrator_from_dict
from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.event_classifier import EventClassifier
from sportsngen.model.export import load_model, read_extra, update_extra
from sportsngen.model.inputs import SCORE_FIELDS, score_vector
from sportsngen.sim import whatif
from sportsngen.sim.assemble import PLAN_COLUMNS, assemble
from sportsngen.sim.constraints import (
    HIGH_BALL_BAND_M,
    STRIKE_REACH_M,
    AllOf,
    KeepChasing,
    PhysicalLimits,
    StrikeInReach,
)
from sportsngen.sim.events import frame_labels
from sportsngen.sim.frame_draws import Constraint
from sportsngen.sim.kinematics import PlayerLimits
from sportsngen.sim.match import MatchResult, simulate_matches
from sportsngen.sim.reach_table import ReachTable
from sportsngen.sim.rollout import RolloutInputs, rollout
from sportsngen.sim.top_speed import TopSpeeds
from sportsngen.tennis.rally import CONTACT_REACH_M, MAX_RALLY_S, RallyTracker

RETURN_REACH_STREAM = 0x5E7E        # the return reaches' own random stream (`_return_reaches`)
RALLY_REACH_STREAM = 0x5E7F         # the rally balls' (`_rally_reaches`)
RALLY_REACH_DRAWS = 64              # a rally's reaches drawn per row: contact k reads k mod this
BUNDLED_DIR = Path(__file__).resolve().parents[1] / "model" / "bundled"
BUNDLED_NAMES = {"sportsngen-small": BUNDLED_DIR / "sportsngen-small.pt"}
DEFAULT_MODEL = "sportsngen-small"
TOURNAMENT = "synthetic"
# The Simulator's sampling keywords and their types: what a config (`simulate.py`) or a command
# line (`eval.sampling_options`) may set, each left out (None) for the model file's default.
SAMPLING_OPTIONS: dict[str, type] = {
    "top_p_player": float, "top_p_ball": float, "top_p_contact": float, "top_p_serve": float,
    "contact_odds": bool, "strike_in_reach": bool, "strike_in_reach_from": int,
    "strike_in_reach_force": bool, "strike_in_reach_m": float, "strike_in_reach_return_m": float,
    "contact_reach_m": float, "return_reach_m": float, "ball_net": bool,
    "physical_bounce": bool, "keep_chasing": bool, "chase_high_balls": bool,
    "return_reach_draw": bool, "rally_reach_draw": bool, "player_top_speed": bool,
    "player_bin_quantiles": bool, "player_accel_mps2": float, "player_accel_full_frac": float,
    "player_keep_heading_deg": float, "refresh_frames": int}
# The player rules' keywords, by which a bad value is named (`PlayerLimits.from_options`).
PLAYER_LIMIT_NAMES = {"accel_mps2": "player_accel_mps2",
                      "full_from_frac": "player_accel_full_frac",
                      "keep_heading_deg": "player_keep_heading_deg"}
MAX_POINTS = 100_000   # a call's rallies are held in memory (~75 KB each): more, in several calls


def check_plan(plan: pd.DataFrame) -> None:
    """A rally plan's columns, players and surfaces, before any rollout."""
    if not isinstance(plan, pd.DataFrame):
        raise ArgumentError(f"plan must be a pandas DataFrame, got {type(plan).__name__}")
    missing = [c for c in PLAN_COLUMNS if c not in plan.columns]
    if missing:
        raise ArgumentError(f"rally plan lacks columns {missing}")
    for col in ("server", "receiver"):
        ok = plan[col].map(lambda v: isinstance(v, str) and bool(v.strip())).to_numpy(bool)
        if not ok.all():
            i = int(np.flatnonzero(~ok)[0])
            check_name(f"plan row {i} {col}", plan[col].iat[i])
    same = np.flatnonzero((plan["server"] == plan["receiver"]).to_numpy(bool))
    if len(same):
        raise ArgumentError(f"plan row {int(same[0])}: server and receiver are the same player "
                            f"{plan['server'].iat[int(same[0])]!r}")
    for surface in sorted(set(plan["surface"]), key=str):
        check_choice("surface", surface, SURFACES)


def check_top_p(top_p) -> float | None:
    """A call's `top_p` (None, or a number in (0, 1]) -> float or None."""
    if top_p is not None and not (isinstance(top_p, (int, float)) and 0 < top_p <= 1):
        raise ArgumentError(f"top_p must be None or a number in (0, 1], got {top_p!r}")
    return None if top_p is None else float(top_p)


def points_plan(server: str, receiver: str, surface: str, n_points: int, seed: int,
                serve_number: int = 1) -> pd.DataFrame:
    """A plan of `n_points` service points of `server` against `receiver` on serve
    `serve_number`: scores within a game drawn at random (seeded by `seed`; the side from the
    score), ends alternating (`Simulator.simulate_points`)."""
    rng = np.random.default_rng([seed, 1])
    sp, rp = rng.integers(0, 4, n_points), rng.integers(0, 4, n_points)
    return pd.DataFrame({
        "rally_id": np.arange(n_points), "match_id": "points",
        "point": np.arange(1, n_points + 1),
        "server": server, "receiver": receiver, "serve_number": serve_number,
        "side": np.where((sp + rp) % 2 == 0, "deuce", "ad"),
        "server_end": np.where(np.arange(n_points) % 2 == 0, 1, -1),
        "surface": surface, "tournament": TOURNAMENT, "set_no": 1,
        "server_sets": 0, "receiver_sets": 0, "server_games": 0, "receiver_games": 0,
        "server_points": sp, "receiver_points": rp, "in_tiebreak": False,
        "score": [f"{a}-{b}" for a, b in zip(sp, rp)]})


def model_path(path_or_name: str | Path | None = None) -> Path:
    """The file of a bundled model name (None: the default bundled model), or the path given."""
    name = DEFAULT_MODEL if path_or_name is None else str(path_or_name)
    return BUNDLED_NAMES.get(name, Path(name))


class Simulator:
    """A decoder f, its event classifier g, vocabularies and serve starts, ready to roll."""

    def __init__(self, model: SportsNGEN, event_model: EventClassifier | None, vocab: Vocab,
                 initial: InitialConditions, top_p_player: float = 1.0,
                 top_p_ball: float = 1.0, max_duration_s: float = MAX_RALLY_S,
                 batch_size: int = 256, max_retries: int = 10, unknown: str | None = None,
                 physical_limits: bool = True, device: str | torch.device = "cpu",
                 contact_odds: bool = False, top_p_contact: float | None = None,
                 refresh_frames: int | None = None, strike_in_reach: bool = False,
                 strike_in_reach_from: int = 1, strike_in_reach_force: bool = False,
                 top_p_serve: float = 1.0, strike_in_reach_m: float = STRIKE_REACH_M,
                 ball_net: bool | None = None, keep_chasing: bool = False,
                 contact_reach_m: float = CONTACT_REACH_M,
                 return_reach_m: float | None = None,
                 strike_in_reach_return_m: float | None = None,
                 physical_bounce: bool = False, player_accel_mps2: float | None = None,
                 chase_high_balls: bool = False, return_reach_draw: bool = False,
                 rally_reach_draw: bool = False, player_top_speed: bool = False,
                 player_bin_quantiles: bool = False,
                 player_accel_full_frac: float | None = None,
                 player_keep_heading_deg: float | None = None):
        if abs(initial.fps - model.cfg.fps) > 1e-6:
            raise ValueError(f"initial conditions at {initial.fps} Hz, model at {model.cfg.fps}")
        for name, p in (("top_p_player", top_p_player), ("top_p_ball", top_p_ball),
                        ("top_p_contact", 1.0 if top_p_contact is None else top_p_contact),
                        ("top_p_serve", top_p_serve)):
            if not 0.0 < p <= 1.0:
                raise ArgumentError(f"{name} must be in (0, 1], got {p}")
        self.model = model.to(device).eval()
        self.event_model = None if event_model is None else event_model.to(device).eval()
        self.vocab = vocab
        self.initial = initial
        self.top_p_player = float(top_p_player)
        self.top_p_ball = float(top_p_ball)
        self.max_duration_s = float(max_duration_s)
        self.batch_size = int(batch_size)
        self.max_retries = int(max_retries)
        self.unknown = unknown or model.cfg.unknown
        self.physical_limits = bool(physical_limits)
        # The ball's nucleus keeps the model's odds of a racket contact (`rollout`).
        self.contact_odds = bool(contact_odds)
        # With contact_odds: the nucleus of a struck ball (None: top_p_ball).
        self.top_p_contact = None if top_p_contact is None else float(top_p_contact)
        # The serve head's nucleus, where the model has one.
        self.top_p_serve = float(top_p_serve)
        # Past the model's window, re-fill the cache from the last window every this many
        # frames (`rollout`): None keeps the band; 1 gives training's view on every frame.
        if refresh_frames is not None and int(refresh_frames) < 1:
            raise ArgumentError(f"refresh_frames must be a positive int or None, got "
                                f"{refresh_frames!r}")
        self.refresh_frames = None if refresh_frames is None else int(refresh_frames)
        # A good ball is struck by the player it passes within reach of (`StrikeInReach`).
        self.strike_in_reach = bool(strike_in_reach)
        # ... from this contact on (1: the return; 2: the server's first rally ball).
        if int(strike_in_reach_from) < 1:
            raise ArgumentError(f"strike_in_reach_from counts contacts after the serve (>= 1), "
                                f"got {strike_in_reach_from!r}")
        self.strike_in_reach_from = int(strike_in_reach_from)
        # ... and where no draw strikes it or keeps it in reach, the strike head strikes it.
        self.strike_in_reach_force = bool(strike_in_reach_force)
        # ... within this distance of the player's centre (horizontally).
        if not float(strike_in_reach_m) > 0:
            raise ArgumentError(f"strike_in_reach_m must be positive, got {strike_in_reach_m!r}")
        self.strike_in_reach_m = float(strike_in_reach_m)
        # ... and the return's (None: the same).
        if strike_in_reach_return_m is not None and not float(strike_in_reach_return_m) > 0:
            raise ArgumentError(f"strike_in_reach_return_m must be positive, got "
                                f"{strike_in_reach_return_m!r}")
        self.strike_in_reach_return_m = None if strike_in_reach_return_m is None \
            else float(strike_in_reach_return_m)
        # With physical limits: a racket contact needs a player within this distance of the
        # ball (horizontally; `PhysicalLimits`). The rules' 2.5 m by default; the generator's
        # players return within 1.82 m and strike 99.3 % of rally balls within 1.8 m
        # (docs/evaluation.md, thirty-third part).
        if not float(contact_reach_m) > 0:
            raise ArgumentError(f"contact_reach_m must be positive, got {contact_reach_m!r}")
        self.contact_reach_m = float(contact_reach_m)
        # ... and the return (the contact after the serve) one within this (None: the same).
        if return_reach_m is not None and not float(return_reach_m) > 0:
            raise ArgumentError(f"return_reach_m must be positive, got {return_reach_m!r}")
        self.return_reach_m = None if return_reach_m is None else float(return_reach_m)
        # The player due to play the ball does not slow down while he is late for it
        # (`KeepChasing`).
        self.keep_chasing = bool(keep_chasing)
        # ... and, with it, for a ball whose bounce carries it above a racket his ball is where
        # it is at a comfortable height after the bounce (`KeepChasing.band_m`,
        # `HIGH_BALL_BAND_M`); read only with keep_chasing.
        self.chase_high_balls = bool(chase_high_balls)
        # The ball's physics centre meets the net (`ModelConfig.ball_net`; None: as the model
        # was trained, unless the file's sampling defaults say). Set on a file trained without
        # it, the rollouts' flight stops at the net where its training targets flew through (the
        # bundled file does: its first serves in had been 3.6 points above the truth's,
        # docs/evaluation.md, thirty-fourth part). It is the model's own config that changes:
        # Simulators sharing one model object share it.
        if ball_net is not None:
            if ball_net and self.model.cfg.ball_centre != "physics":
                raise ArgumentError(f"ball_net needs a model whose ball centre is the physics "
                                    f"step, this one's is {self.model.cfg.ball_centre!r}")
            self.model.cfg.ball_net = bool(ball_net)
        # The ball's bounces are the surface's physics, not the model's draw (`sim.bounce`).
        if physical_bounce and self.model.strike_head is None and self.model.serve_head is None:
            raise ArgumentError("physical_bounce puts down the frame after a bounce as a "
                                "strike's launch frames are: it needs a model with a strike "
                                "or serve head")
        self.physical_bounce = bool(physical_bounce)
        # A sampled frame changes a player's velocity by at most this acceleration, a change
        # of at least this fraction of it is flat out (the generator's players run at the limit
        # or well short of it), and a flat-out change within this angle of a running player's
        # heading runs along it (the model's x and y draws turn him); `sim.kinematics`, None:
        # as drawn. Checked here, once, under the keywords' names.
        self.player_limits = PlayerLimits.from_options(
            player_accel_mps2, player_accel_full_frac, player_keep_heading_deg,
            names=PLAYER_LIMIT_NAMES)
        # Each serve's return reach (the contact limit's and the strike rule's) drawn from its
        # receiver's row of `return_reach` (`sim.reach_table`), and each rally ball's from the
        # row of the player due in `rally_reach`, where the file has the tables
        # (`from_pretrained`); without one the fixed reaches stand.
        self.return_reach_draw = bool(return_reach_draw)
        self.rally_reach_draw = bool(rally_reach_draw)
        self.return_reach: ReachTable | None = None
        self.rally_reach: ReachTable | None = None
        # Each player runs no faster than his record's top speed (`sim.top_speed`), where the
        # file has the table (`from_pretrained`): every frame and the chase rule's cap.
        self.player_top_speed = bool(player_top_speed)
        self.top_speeds: TopSpeeds | None = None
        # A player's draw lands inside its bin with the record's spread there, where the file
        # has the table (`model.bin_quantiles`, `from_pretrained`); without one, uniformly.
        self.player_bin_quantiles = bool(player_bin_quantiles)
        self.player_quantiles: torch.Tensor | None = None
        self._warned: set[str] = set()    # unknown players already warned about
        # Raw rollout win probabilities -> observed frequencies, when the model file has one
        # (`scripts/rally_outcome_study.py --save-calibrator`).
        self.outcome_calibrator: LogisticCalibrator | IsotonicCalibrator | None = None

    @property
    def player_accel_mps2(self) -> float | None:
        """The players' acceleration limit (m/s², `player_limits`; None: none)."""
        return None if self.player_limits is None else self.player_limits.accel_mps2

    @property
    def player_accel_full_frac(self) -> float | None:
        """The share of the limit from which a change is flat out (None: none, or no limit)."""
        return None if self.player_limits is None else self.player_limits.full_from_frac

    @property
    def player_keep_heading_deg(self) -> float | None:
        """The angle within which a flat-out change runs along the heading (None: none, or no
        limit)."""
        return None if self.player_limits is None else self.player_limits.keep_heading_deg

    @classmethod
    def from_pretrained(cls, path_or_name: str | Path | None = None, **kwargs) -> Simulator:
        """Load a model file (or a bundled model by name; None: the default bundled model).
        Keyword arguments go to `Simulator` (top_p_player, top_p_ball, contact_odds,
        top_p_contact, refresh_frames, max_duration_s, ...); those stored with the model
        (`sim_defaults`: its top-p and contact odds) are the defaults."""
        path = model_path(path_or_name)
        model, ec, vocab, _ = load_model(path)
        extra = read_extra(path)
        if "initial_conditions" not in extra:
            raise ValueError(f"{path} carries no initial conditions for simulation; add them "
                             "with scripts/add_initial_conditions.py --model ... --data ...")
        for key, value in (extra.get("sim_defaults") or {}).items():
            kwargs.setdefault(key, value if isinstance(value, bool) else float(value))
        sim = cls(model, ec, vocab, InitialConditions.from_dict(extra["initial_conditions"]),
                  **kwargs)
        if extra.get("outcome_calibrator") is not None:
            sim.outcome_calibrator = calibrator_from_dict(extra["outcome_calibrator"])
        if extra.get("return_reach") is not None:
            sim.return_reach = ReachTable.from_dict(extra["return_reach"])
        if extra.get("rally_reach") is not None:
            sim.rally_reach = ReachTable.from_dict(extra["rally_reach"])
        if extra.get("top_speed") is not None:
            sim.top_speeds = TopSpeeds.from_dict(extra["top_speed"])
        if extra.get("player_bin_quantiles") is not None:
            sim.set_player_quantiles(extra["player_bin_quantiles"])
        return sim

    def set_player_quantiles(self, table) -> None:
        """The players' within-bin quantiles (`model.bin_quantiles.fit_bin_quantiles`'s table,
        (2, n_bins, Q + 1), any nested sequence) that `player_bin_quantiles` draws from."""
        t = torch.as_tensor(np.asarray(table, dtype=np.float32),
                            device=next(self.model.parameters()).device)
        n_bins = self.model.player_bins.edges.shape[1] - 1
        if t.ndim != 3 or t.shape[:2] != (2, n_bins) or t.shape[2] < 2:
            raise ArgumentError(f"player bin quantiles must be (2, {n_bins}, Q + 1), got "
                                f"{tuple(t.shape)}")
        self.player_quantiles = t

    def player_quantiles_used(self) -> torch.Tensor | None:
        """The within-bin table the rollouts place player draws by (None: uniformly)."""
        return self.player_quantiles if self.player_bin_quantiles else None

    @staticmethod
    def set_defaults(path: str | Path, **values) -> dict:
        """Store sampling defaults in a model file (`sim_defaults`, which `from_pretrained`
        applies), keeping those not named -> the file's defaults after. Only `Simulator`'s
        own sampling arguments are accepted."""
        allowed = set(inspect.signature(Simulator.__init__).parameters) - {
            "self", "model", "event_model", "vocab", "initial", "device"}
        unknown = sorted(set(values) - allowed)
        if unknown:
            raise ArgumentError(f"not a Simulator sampling argument: {', '.join(unknown)} "
                                f"(known: {', '.join(sorted(allowed))})")
        kept = read_extra(path).get("sim_defaults") or {}
        update_extra(path, sim_defaults={**kept, **values})
        return read_extra(path)["sim_defaults"]

    @property
    def fps(self) -> float:
        return self.model.cfg.fps

    # --- rallies -------------------------------------------------------------------------------
    def _inputs(self, plan: pd.DataFrame, rng: np.random.Generator,
                init_pos_m: np.ndarray | None = None,
                init_frames: np.ndarray | None = None) -> RolloutInputs:
        init = init_pos_m if init_pos_m is not None else np.stack(
            [self.initial.draw(s, int(n), side, int(e), rng, surface=surf, receiver=rcv)
             for s, n, side, e, surf, rcv in zip(plan["server"], plan["serve_number"],
                                                 plan["side"], plan["server_end"],
                                                 plan["surface"], plan["receiver"])])
        v = self.vocab
        ids = {p: self._player_index(p) for p in set(plan["server"]) | set(plan["receiver"])}
        ident = np.stack([plan["server"].map(ids), plan["receiver"].map(ids),
                          np.zeros(len(plan), dtype=np.int64)], axis=1).astype(np.int64)
        surf = plan["surface"].map(lambda s: v.surface_index(s, "error")).to_numpy(np.int64)
        tour = plan["tournament"].map(v.tournament_index).to_numpy(np.int64)
        score = score_vector(*(plan[c].to_numpy() for c in SCORE_FIELDS))
        return RolloutInputs(init, ident, surf, tour,
                             plan["serve_number"].to_numpy(np.int64) - 1, score,
                             None if init_frames is None else np.asarray(init_frames, np.int64))

    def _player_index(self, name: str) -> int:
        """The model's identity of `name`; an unknown player (the model's generic identity,
        the average player) is warned about once per simulator, not once per rally."""
        if self.unknown != "warn" or name in self.vocab.players or not self.vocab.players:
            return self.vocab.player_index(name, self.unknown)
        if name in self._warned:
            return self.vocab.player_index(name, "generic")
        self._warned.add(name)
        warnings.warn(f"unknown player {name!r}: the model plays him as its average (generic) "
                      f"player; known players: {list(self.vocab.players)}", stacklevel=4)
        return self.vocab.player_index(name, "generic")

    def _return_reaches(self, part: pd.DataFrame, seed: int, lo: int) -> np.ndarray | None:
        """(len(part),) each serve's return reach drawn from its receiver's row (`return_reach_draw`
        with a table), from a stream of its own (seed, batch start): the rollout's other draws
        stay those without it. None: the fixed reaches."""
        if not self.return_reach_draw or self.return_reach is None:
            return None
        rng = np.random.default_rng((int(seed), int(lo), RETURN_REACH_STREAM))
        return self.return_reach.draw(part["receiver"].to_numpy(), rng)

    def _top_speeds(self, part: pd.DataFrame) -> np.ndarray | None:
        """(len(part), 2) the server's and the receiver's top speed (m/s) where the simulator
        bounds them (`player_top_speed` with a table); None: unbounded."""
        if not self.player_top_speed or self.top_speeds is None:
            return None
        return self.top_speeds.speeds_mps(part[["server", "receiver"]].to_numpy(str))

    def _rally_reaches(self, part: pd.DataFrame, seed: int, lo: int) -> np.ndarray | None:
        """(len(part), RALLY_REACH_DRAWS) each rally ball's reach, contact k (1 the return) in
        column k, drawn from the row of the player due (the receiver at odd k, the server at
        even) in `rally_reach` (`rally_reach_draw` with a table), from a stream of its own.
        None: the fixed reach."""
        if not self.rally_reach_draw or self.rally_reach is None:
            return None
        rng = np.random.default_rng((int(seed), int(lo), RALLY_REACH_STREAM))
        odd = np.arange(RALLY_REACH_DRAWS) % 2 == 1
        due = np.where(odd[None, :], part["receiver"].to_numpy(str)[:, None],
                       part["server"].to_numpy(str)[:, None])
        return self.rally_reach.draw(due, rng)

    def simulate_rallies(self, plan: pd.DataFrame, seed: int = 0, progress: bool = False,
                         init_pos_m: np.ndarray | None = None,
                         constraint: Constraint | None = None,
                         max_duration_s: float | np.ndarray | None = None,
                         forced_pos_m: np.ndarray | None = None,
                         init_frames: np.ndarray | None = None,
                         label_events: bool = True, top_p: float | None = None) -> RallyData:
        """One rally for each row of `plan` (columns `PLAN_COLUMNS`), in batches of
        `batch_size` -> RallyData with the simulator's columns (see `sportsngen.sim.assemble`).

        Rallies start from serve starts drawn from the model's pool, or from `init_pos_m`
        (len(plan), T0, 3, 3) (branching from a real rally); `constraint` restricts sampling
        (`sportsngen.sim.frame_draws.Constraint`; row indices are plan positions).
        `max_duration_s` (default the simulator's) cuts rallies that last longer: they end
        undecided (diagnostics that only need a rally's first shots); (len(plan),): each
        rally its own. `forced_pos_m` (len(plan), T, 3, 3), NaN where free: players' positions
        that replace the sampled ones frame by frame (`rollout`'s; frames counted as
        `init_pos_m`'s). `init_frames` (len(plan),): each rally's own count of `init_pos_m`'s
        frames (the rest of its row unread), so rallies branched at different frames share
        batches (`RolloutInputs.init_frames`). `label_events` False: no event classifier
        labels (the rules' shots only), for callers that read positions alone. `top_p`: both
        kinds' nucleus for this call (None: `top_p_player` and `top_p_ball`)."""
        check_plan(plan)
        top_p = check_top_p(top_p)
        top_p_player, top_p_ball = (self.top_p_player, self.top_p_ball) if top_p is None \
            else (top_p, top_p)
        for name, given in (("forced_pos_m", forced_pos_m), ("init_frames", init_frames)):
            if given is not None and len(given) != len(plan):
                raise ArgumentError(f"{name} has {len(given)} rows, the plan {len(plan)}")
        if init_frames is not None and init_pos_m is None:
            raise ArgumentError("init_frames counts init_pos_m's frames: give init_pos_m")
        rng = np.random.default_rng(check_int("seed", seed, 0))
        parts = []
        duration_s = np.broadcast_to(np.asarray(
            self.max_duration_s if max_duration_s is None else max_duration_s, dtype=float),
            (len(plan),))
        if not (duration_s > 0).all():
            raise ArgumentError(f"max_duration_s must be positive, got {max_duration_s!r}")

        def rows(x, lo):
            return None if x is None else x[lo:lo + self.batch_size]

        for lo in range(0, len(plan), self.batch_size):
            part = plan.iloc[lo:lo + self.batch_size].reset_index(drop=True)
            inputs = self._inputs(part, rng, rows(init_pos_m, lo), rows(init_frames, lo))
            cap_s = rows(duration_s, lo)
            tracker = RallyTracker(part["server_end"].to_numpy(), part["side"].to_numpy(),
                                   part["serve_number"].to_numpy(), self.fps, cap_s)
            max_frames = int(math.ceil(cap_s.max() * self.fps)) + 2
            drawn = self._return_reaches(part, seed, lo)
            rally_drawn = self._rally_reaches(part, seed, lo)
            limits = PhysicalLimits(fps=self.fps, reach_m=self.contact_reach_m,
                                    tracker=tracker, return_reach_m=self.return_reach_m) \
                if self.physical_limits else None
            strike = StrikeInReach(tracker, reach_m=self.strike_in_reach_m, fps=self.fps,
                                   from_shot=self.strike_in_reach_from,
                                   force=self.strike_in_reach_force,
                                   return_reach_m=self.strike_in_reach_return_m) \
                if self.strike_in_reach else None
            for rule in (limits, strike):
                if rule is not None:
                    rule.return_reach_rows_m = drawn
                    rule.rally_reach_rows_m = rally_drawn
            top = self._top_speeds(part)
            chase = KeepChasing(tracker, fps=self.fps,
                                band_m=HIGH_BALL_BAND_M if self.chase_high_balls else None) \
                if self.keep_chasing else None
            if chase is not None:
                chase.max_speed_rows_mps = top
            con = AllOf(limits, strike, chase, constraint) \
                if (limits or strike or chase or constraint) else None
            if con is not None:
                con.offset = lo
            gen = torch.Generator(device=next(self.model.parameters()).device)
            gen.manual_seed(int(rng.integers(2 ** 62)))
            t0 = inputs.init_pos_m.shape[1]
            roll = rollout(self.model, inputs, max(max_frames, t0 + 2), tracker,
                           top_p_player, top_p_ball, generator=gen,
                           progress=progress, constraint=con, contact_odds=self.contact_odds,
                           top_p_contact=self.top_p_contact,
                           refresh_frames=self.refresh_frames, top_p_serve=self.top_p_serve,
                           bounce_surfaces=part["surface"].astype(str).to_numpy()
                           if self.physical_bounce else None,
                           player_limits=self.player_limits,
                           player_top_speed_mps=top,
                           forced_pos_m=rows(forced_pos_m, lo),
                           player_quantiles=self.player_quantiles_used())
            labels = None if self.event_model is None or not label_events else frame_labels(
                self.event_model, roll.pos_m, roll.length, self.fps, self.model.cfg.window_frames)
            data = assemble(part, roll.pos_m, roll.length, tracker.results(), labels, self.fps)
            data.rallies["resampled_frames"] = roll.resampled
            data.rallies["forced_strikes"] = roll.forced_strikes
            parts.append(data)
        return RallyData.concat(parts)

    # --- service points ------------------------------------------------------------------------
    def simulate_points(self, server: str, receiver: str, surface: str, n_points: int,
                        seed: int = 0, serve_number: int | None = None,
                        top_p: float | None = None, progress: bool = False) -> RallyData:
        """`n_points` service points of `server` against `receiver`: first serves, then a second
        serve for each fault (or only serve `serve_number`). Scores within a game are drawn at
        random (side from the score), ends alternate. `top_p` sets both kinds' nucleus for this
        call. The rallies table carries `realistic`; `sportsngen.sim.assemble.realistic_points`
        keeps the points fit for statistics. At most `MAX_POINTS` a call (held in memory)."""
        check_players(server, receiver)
        check_choice("surface", surface, SURFACES)
        n_points = check_int("n_points", n_points, 1, MAX_POINTS)
        seed = check_int("seed", seed, 0)
        if serve_number is not None:
            serve_number = check_int("serve_number", serve_number, 1, 2)
        top_p = check_top_p(top_p)
        plan = points_plan(server, receiver, surface, n_points, seed, serve_number or 1)
        first = self.simulate_rallies(plan, seed=seed, progress=progress, top_p=top_p)
        if serve_number is not None:
            return first
        faulted = first.rallies["end_reason"].to_numpy() == "fault"
        second_plan = plan[faulted].assign(serve_number=2,
                                           rally_id=np.arange(faulted.sum()) + n_points)
        if not len(second_plan):
            return first
        second = self.simulate_rallies(second_plan, seed=seed + 1, progress=progress,
                                       top_p=top_p)
        return RallyData.concat([first, second])

    def simulate_both_serving(self, player1: str, player2: str, surface: str, n_points: int,
                              seed: int = 0, **kwargs) -> RallyData:
        """`simulate_points` of each player serving `n_points` to the other (seeds `seed` and
        `seed + 1`), in one RallyData (ids renumbered; match ids "0-..." and "1-...")."""
        return RallyData.concat(
            [self.simulate_points(a, b, surface, n_points, seed=seed + k, **kwargs)
             for k, (a, b) in enumerate(((player1, player2), (player2, player1)))],
            renumber=True)

    # --- matches -------------------------------------------------------------------------------
    def simulate_match(self, player1: str, player2: str, surface: str, fmt=None, seed: int = 0,
                       first_server: int | None = None, progress: bool = True,
                       lookahead: int = 0, lookahead_depth: int = 2) -> MatchResult:
        """One match -> `MatchResult` (points table, RallyData, score line, summary).
        `lookahead`: worker processes that play its likely next `lookahead_depth` rallies
        ahead, the same match faster on more cores (`sim.lookahead`)."""
        return simulate_matches(self, [(player1, player2)], surface, fmt=fmt, seed=seed,
                                first_server=first_server, progress=progress,
                                lookahead=lookahead, lookahead_depth=lookahead_depth)[0]

    def simulate_matches(self, matchups, surface: str, fmt=None, seed: int = 0,
                         first_server: int | None = None, progress: bool = True,
                         lookahead: int = 0, lookahead_depth: int = 2) -> list[MatchResult]:
        """Many matches, their points batched together -> list of `MatchResult`
        (`lookahead` with one match only, as `simulate_match`)."""
        return simulate_matches(self, matchups, surface, fmt=fmt, seed=seed,
                                first_server=first_server, progress=progress,
                                lookahead=lookahead, lookahead_depth=lookahead_depth)

    # --- what if -------------------------------------------------------------------------------
    def rally_win_probability(self, rally_data: RallyData, rally_id: int, frame: int,
                              n: int = 100, seed: int = 0, calibrated: bool = False) -> float:
        """P(the rally's server wins the point) from `n` rollouts after frame `frame` of the
        rally (see `sportsngen.sim.whatif.rally_win_probability`). `calibrated`: mapped
        through the model file's outcome calibrator (fitted on held-out rallies; an error when
        the file has none)."""
        if calibrated and self.outcome_calibrator is None:
            raise ValueError("this model has no outcome calibrator: fit one with "
                             "scripts/rally_outcome_study.py --save-calibrator")
        p = whatif.rally_win_probability(self, rally_data, rally_id, frame, n, seed)
        if not calibrated or math.isnan(p):   # NaN: no realistic decided rollout
            return p
        return float(self.outcome_calibrator(p))

    def counterfactual(self, rally_data: RallyData, rally_id: int, shot_index: int,
                       options=("cross_court", "down_the_line"), n: int = 100,
                       seed: int = 0) -> pd.DataFrame:
        """The hitter's win probability for each way shot `shot_index` could have gone (see
        `sportsngen.sim.whatif.counterfactual`)."""
        return whatif.counterfactual(self, rally_data, rally_id, shot_index, options, n, seed)

    def match_win_probability(self, player1: str, player2: str, surface: str, state=None,
                              fmt=None, n_points: int = 200, seed: int = 0) -> dict:
        """P(player1 wins the match) from any score (see
        `sportsngen.sim.whatif.match_win_probability`)."""
        return whatif.match_win_probability(self, player1, player2, surface, state, fmt,
                                            n_points, seed)
