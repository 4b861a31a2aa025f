"""Model hyper-parameters as one plain dataclass (what Hydra's `model` group fills in)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

HEAD_KINDS = ("joint", "factorised")
BIN_SPACINGS = ("uniform", "nonuniform")
BIN_CENTRES = ("current", "cv")
BALL_CENTRES = ("physics", "velocity", "current")
FRAMES = ("world", "server")
# Model files saved before `ball_centre` existed centred the ball like the players.
LEGACY_BALL_CENTRE = {"current": "current", "cv": "velocity"}
# The object-feature groups as `sportsngen.model.inputs.object_features` lays them out: name ->
# (first, end) column of the N_FEATURES = 8 features. Ablations switch groups off by name.
FEATURE_GROUPS = {"position": (0, 3), "velocity": (3, 6), "distance": (6, 7), "time": (7, 8)}


@dataclass
class ModelConfig:
    """Decoder f (and event classifier g) sizes, output bins and data conventions.

    The vocabulary sizes (`n_ids`, `n_tournaments`) come from the data's `Vocab` at build time.
    """

    d_model: int = 128
    n_layers: int = 4
    n_heads: int = 4
    ff_mult: int = 4
    dropout: float = 0.1
    # Dropout on the attention probabilities. Above 0 it rules out PyTorch's fused attention
    # kernels on the CPU (the unfused path was ~4.8x slower a layer, forward and backward, for
    # the small config: bench/bench_model.py), so residual and feed-forward dropout (`dropout`)
    # regularise instead; GPUs' fused kernels support it (the paper config keeps 0.2).
    attn_dropout: float = 0.0
    id_dim: int = 22                     # identity size (22 + 8 features = the paper's 30)
    embed_hidden: tuple[int, ...] = (256, 512)
    score_hidden: int = 64
    n_bins: int = 61                     # per dimension
    head: str = "factorised"             # "joint" (paper) or "factorised" (x, y|x, z|x,y)
    head_hidden: int = 128               # width of the factorised heads' conditional MLPs
    bin_spacing: str = "uniform"         # "uniform" (paper) or "nonuniform" (finer near 0)
    bin_centre: str = "current"          # players: "current" (paper) or "cv" (constant velocity)
    # The ball: "velocity" (constant velocity), "physics" (one flight step: gravity, drag,
    # Magnus read from the track) or "current" (the paper); `sportsngen.model.centre`. Chosen by
    # the model's own serves and simulated points (docs/evaluation.md): physics makes a flight
    # exact but carries the bin error of every decision frame through it.
    ball_centre: str = "velocity"
    # With the physics centre: the step meets the net as the generator's ball does (drops dead
    # on the hitter's side, `centre.net_step_m`). Without it a ball flown low at the net went
    # through in the centre bin, and only a large offset drawn on that one frame stopped it:
    # without the physical limits 19 % of a check's rallies sent a ball through the net. Off
    # in files trained before it (their heads were fitted beside the limits' looser net;
    # docs/evaluation.md, twenty-third part).
    ball_net: bool = False
    # The court frame the decoder sees its inputs and offsets in: "world" as recorded, or
    # "server" (turned 180 degrees about the net's centre where the server stands at -x, so
    # he is always at +x). In the server frame, whose ball it is (coming to the server or to
    # the receiver) is the sign of its own x velocity, a feature of the ball's token, not a
    # relation the attention has to find between the ball's and the server's tokens
    # (docs/evaluation.md, eleventh part). Physics and the court are the same either way.
    frame: str = "world"
    # The ball's flight forecast (`sportsngen.model.forecast`: where it will be 0.4 and 0.8 s
    # on and where it will bounce, by gravity, drag and the spin read from the track) as extra
    # input columns of each player's token, from where he stands, computed by the model from
    # the ball's own features: the reading of a flight that a player runs on, given rather
    # than learned.
    ball_forecast: bool = False
    # With the forecast, three more columns in each player's token: the point of the ball's
    # flight (flown on 1.6 s) nearest him at a height he can strike, from where he stands, and
    # the time to it (`forecast.nearest_playable`). Fed the ball the record played, the model's
    # players ran the first 0.8-1 s of a long chase as the record's did and then slowed early:
    # 30 % of 4-6 m chases passed beyond 1.5 m of them, 2 % of the record's (issue 17).
    ball_intercept: bool = False
    # With > 0, one more input column in every token, last: the rally's elapsed time (s),
    # clipped at `clock_s`. The features' own time is scaled by 10 s (0.004 a frame), and the
    # decoder times its server's run after the serve by the ball's flight instead: a serve
    # re-flown 10 % faster on its path slows him as a later frame would, while shifting the
    # time feature by 10 s does not move him (docs/evaluation.md, sixty-seventh part). A serve is
    # struck about 1.1 s into a rally, so the clock covers its phase (an experiment; the general
    # clock would be the time since the last racket contact). Added in a 700-step fine-tune it
    # is learned (held-out player NLL 0.013 below a paired control's) but the brake still
    # follows the ball, also with the players' turns weighted (sixty-eighth part): off.
    clock_s: float = 0.0
    # Each ball bin split again into this many equal parts by a head of its own
    # (`heads.SubBinHead`, p(part | bins)), 0: none, uniform inside the bin. A strike's offset
    # lies where the bins are 10-17 cm wide, and a track drawn uniformly inside them puts
    # its speed +-1-2 m/s off: recorded rally balls re-drawn so land in play 0.54-0.64 of the
    # time instead of 0.86-0.88 (docs/evaluation.md, twelfth part).
    ball_sub_bins: int = 0
    # A head that gives a rally strike (`model.strike.is_strike`) as where its ball will land,
    # its height over the net and its spin (`model.strike`), the launch then solved by the
    # physics centre's own flight: the court's lines are edges of its bins, so a strike no
    # longer has to invert the flight to land in. False: strikes are drawn in the ball's bins.
    strike_head: bool = False
    # The strike head's input also carries whose strike it is (the server's or the receiver's:
    # whose end the ball is struck on) and the point's serve (first or second), as a learned
    # shift of the ball token's state (`SportsNGEN.strike_role`, started at zero). The
    # generator's server keeps a first serve's initiative all rally (the receiver's balls err a
    # quarter of the time, the server's a tenth); the head read from the state alone drew
    # the same share for both from the fourth shot on (docs/evaluation.md, twentieth part).
    strike_roles: bool = False
    # The strike head's input also carries the strike's number in the rally (1 the return, 2
    # the server's first rally ball, ..., `strike_heads.shot_bucket`), as a learned shift
    # (`SportsNGEN.strike_shot`, started at zero, fitted on the decoder's states by
    # `train.strike_inputs`): the rollout's tracker counts the contacts. Read from the ball's
    # state alone the head placed the receiver's second rally ball short and his third deep
    # against the record, and its spin was 0.085 nats a strike worse than with the number
    # (docs/evaluation.md, forty-fourth part). Without a count (no tracker) the head reads as
    # without the shift.
    strike_shots: bool = False
    # With the role shift, two more learned shifts of the strike head's input: one per hitter
    # and his role in the point, one per opponent (who struck the ball being answered) and the
    # hitter's role (`SportsNGEN.strike_player` / `strike_opponent`, (n_ids, 2, d), zero until
    # fitted by `train.strike_inputs`): the head reads the players only through the ball's
    # state, and held out its likelihood rose 0.26 nats a strike with them (docs/evaluation.md,
    # forty-fourth part). A player added for fine-tuning gets zero rows.
    strike_players: bool = False
    # A head of its own for the serve (`model.strike.is_serve`: struck from the toss) as where
    # it lands, its speed and its spin, the launch solved as a strike's: its fault, its box and
    # its speed come from a distribution over those, not from the ball's bins under a nucleus.
    # False: serves are drawn in the ball's bins.
    serve_head: bool = False
    # A table of per-server shifts of the serve head's odds of a long and a wide serve and of
    # its speed (`model.serve_bias`, fitted by `train.serve_bias` after the head; zero until
    # then): the head reads the server only through the ball's state and draws every named
    # player's faults near the average player's (docs/evaluation.md, twenty-fourth part).
    serve_bias: bool = False
    # With it, a per-server tilt of the serve head's lateral bins inside the box by their
    # distance toward its sideline (`model.serve_bias.aim_tilt`, fitted on the model's own
    # serves by `train.serve_bias.fit_serve_aim`; zero until then). Built to test whether the
    # model's own serves went wide less often than the record's: measured, its head already aims
    # as the record from its own tosses (docs/evaluation.md, thirty-seventh part), so off.
    serve_aim: bool = False
    # With it, a per-server shift of the serve head's depth bins short of `SHORT_DEPTH_M`
    # (`model.serve_bias.short_bins`, fitted by `train.serve_bias.fit_serve_short`; zero until
    # then): a serve that short is in the net at a second serve's pace, and the head drew
    # Williams' second serves short three times as often as her record (docs/evaluation.md,
    # forty-second part).
    serve_short: bool = False
    # With it, a per-server shift of the serve head's lateral bins inside the box, by band of
    # their distance toward its sideline (`model.serve_bias.lateral_bands`, fitted by
    # `train.serve_bias.fit_serve_lateral`; zero until then): the head, fitted on everyone's
    # serves, spreads a server's first serves over the box where the big servers' go to the T
    # or wide (Federer's 1.0-3.0 m from the centre line 0.20 of his first serves in the
    # bundled file's checks against his truth's 0.08; docs/evaluation.md, fifty-third part).
    serve_lateral: bool = False
    # A table of per-hitter shifts of the strike head's odds of a rally ball long, wide or into
    # the net, by his role in the point (`model.strike_bias`, fitted by `train.strike_bias`
    # after the head; zero until then): the head draws every named player's errors near the
    # average player's (docs/evaluation.md, thirty-second part).
    strike_bias: bool = False
    # With it, a per-hitter tilt of the strike head's lateral bins in play by their distance
    # from the centre line (`model.strike_bias.width_tilt`, fitted by
    # `train.strike_bias.fit_strike_width`; zero until then): the head places every player's
    # balls about as wide as the average player's (docs/evaluation.md, thirty-third part).
    strike_width: bool = False
    # With it, a second per-hitter table of the same three shifts added on his returns alone
    # (`model.strike_bias`, fitted by `train.strike_bias.fit_strike_bias` with the returns
    # named; zero until then): teacher-forced, the head drew 0.03-0.12 more errors on returns
    # of first serves than the record's in six of seven matchups, while one shift for all of a
    # receiver's strikes matched his errors overall (docs/evaluation.md, thirty-fifth part).
    strike_return: bool = False
    # With the returns' table, one more per surface and serve (first, second) of the same three
    # shifts, added on the returns (`model.strike_bias`, fitted in turn with the receivers'
    # returns table by `train.return_surface.fit_return_surface`; zero until then): the
    # generator's return faces the serve's heaviness, which clay and a second serve pass on
    # less, and the head drew first serves' returns on clay erring 0.05 more than the round
    # robins' record and second serves' on hard 0.04 less (docs/evaluation.md, fifty-fifth
    # part).
    strike_return_surface: bool = False
    # With the hitters' table, one more per hitter and surface of the same three shifts, a row
    # for his rally balls and one for his returns, added on top of every other table
    # (`model.strike_bias`, fitted by `train.strike_surface.fit_strike_surface`; zero until
    # then): from generator version 6.3 a named player may play a surface his own way
    # (`synth.profiles.PlayerProfile.surface_overrides`), and one row per player pools his
    # surfaces: on version 6.4's hard court Nadal's returns err 0.318 of the time in the truth
    # and 0.146 in the bundled file's rollouts (docs/evaluation.md, seventy-second part).
    strike_surface: bool = False
    # With it and the returns' table, a per-opponent table of the same three shifts by the
    # hitter's role, added on every strike but the return (`model.strike_bias`, fitted by
    # `train.strike_bias.fit_strike_pressure`; zero until then): a hitter's errors depend on
    # whom he plays, which one row per hitter cannot say (docs/evaluation.md, thirty-eighth
    # part).
    strike_pressure: bool = False
    # With the opponents' table, two more tables, per hitter and per opponent by the hitter's
    # role, of a tilt of the depth bins in play and of the net-height bins above the net
    # (`model.strike_bias.depth_tilt` / `height_tilt`, fitted by
    # `train.strike_bias.fit_strike_shape`; zero until then), added on every strike but the
    # return: teacher-forced, the head's mean depth of the receivers' rally balls is about the
    # same whoever sent the ball, while the record's runs 6.78 m against Isner to 7.52 against
    # Djokovic (docs/evaluation.md, forty-third part).
    strike_shape: bool = False
    # With the opponents' table, one more per hitter and role of the same three shifts, added on
    # his strikes from the rally's fifth on (`model.strike_bias.LATE_SHOT`; fitted on the record
    # with the hitters' and opponents' tables by `train.strike_bias.fit_strike_pressure`, or
    # moved by the model's own rollouts, `train.rollout_tables`; zero until then): in rollouts
    # some men's late balls err more than the truth's (docs/evaluation.md, forty-seventh and
    # forty-eighth parts). An option, off in the bundled file.
    strike_late: bool = False
    # With the player's table, one more per hitter and role of the same three shifts, added on
    # his strikes after the return in points of a second serve (moved by the model's own
    # rollouts, `train.rollout_tables.add_rollout_second_shift`; zero until then): the
    # generator's server carries a weaker initiative through a second serve's rally, and in the
    # bundled file's rollouts the receivers' rally balls erred 0.04-0.05 too often after second
    # serves only (docs/evaluation.md, seventy-fourth part). An option, off in the bundled file.
    strike_second: bool = False
    # With the opponents' table, one more by where the ball is struck: per band of the
    # contact's distance behind the baseline (`model.strike_bias.DEPTH_EDGES_M`) and the
    # hitter's role, the same three shifts on every strike but the return (fitted on the
    # record, centred, on top of the other tables by `train.strike_bias.fit_strike_pressure`
    # with `depth_only`; zero until then): the head's errors vary less with the hitter's depth
    # than the record's (docs/evaluation.md, forty-ninth part). An option, off in the bundled
    # file.
    strike_depth: bool = False
    # A table of per-server shifts of the receiver's odds of starting his run while the serve
    # flies at him (`model.receiver_start`, fitted by `train.receiver_start`; zero until
    # then): the truth's receivers wait longer against a server who disguises his serve, the
    # model's start alike against all (docs/evaluation.md, twenty-fifth part).
    receiver_start: bool = False
    # A table of shifts of the ball's odds of a racket contact by where the ball is from the
    # player due to strike it (`model.contact_reach`, fitted by `train.contact_reach`; zero
    # until then): the decoder's odds hardly read the hitter's reach (docs/evaluation.md,
    # twenty-sixth part).
    contact_reach: bool = False
    player_max_speed_mps: float = 10.0   # bin range: offsets up to this speed over one frame
    ball_max_speed_mps: tuple[float, float, float] = (80.0, 40.0, 40.0)
    window_s: float = 6.0
    fps: float = 25.0
    generic_identity: bool = False       # every player shares one learned generic identity
    unknown: str = "warn"                # unknown player/surface at inference: generic|warn|error
    n_ids: int = 2                       # ball + generic + named players (set from the Vocab)
    n_tournaments: int = 1               # unknown + named tournaments (set from the Vocab)
    n_surfaces: int = 3
    # Event classifier g (smaller, bidirectional).
    event_d_model: int = 64
    event_layers: int = 2
    event_heads: int = 4
    # Ablations (conf/experiment/ablation_*.yaml). The defaults are the full model, so a config
    # saved before these fields existed loads unchanged. Disabled feature groups are dropped
    # from the object embedding's input (of f and g alike); without context the four context
    # tokens are learned constants (same shape, so the mask and the cache are unchanged).
    features: tuple[str, ...] = tuple(FEATURE_GROUPS)
    use_context: bool = True

    def __post_init__(self) -> None:
        self.embed_hidden = tuple(int(v) for v in self.embed_hidden)
        unknown = sorted(set(self.features) - set(FEATURE_GROUPS))
        if unknown or not self.features:
            raise ValueError(f"model.features must be a non-empty subset of "
                             f"{list(FEATURE_GROUPS)}, got {list(self.features)}")
        # Canonical order, so equal sets give equal configs (the input order is fixed anyway).
        self.features = tuple(g for g in FEATURE_GROUPS if g in set(self.features))
        if self.id_dim < 0:
            raise ValueError(f"model.id_dim must be >= 0 (0: no identity), got {self.id_dim}")
        self.ball_max_speed_mps = tuple(float(v) for v in self.ball_max_speed_mps)
        if self.head not in HEAD_KINDS:
            raise ValueError(f"model.head must be one of {HEAD_KINDS}, got {self.head!r}")
        if self.bin_spacing not in BIN_SPACINGS:
            raise ValueError(f"model.bin_spacing must be one of {BIN_SPACINGS}, "
                             f"got {self.bin_spacing!r}")
        if self.bin_centre not in BIN_CENTRES:
            raise ValueError(f"model.bin_centre must be one of {BIN_CENTRES}, "
                             f"got {self.bin_centre!r}")
        if self.ball_centre not in BALL_CENTRES:
            raise ValueError(f"model.ball_centre must be one of {BALL_CENTRES}, "
                             f"got {self.ball_centre!r}")
        if self.ball_net and self.ball_centre != "physics":
            raise ValueError(f"model.ball_net needs ball_centre physics (the net is in its "
                             f"step), got ball_centre {self.ball_centre!r}")
        if self.frame not in FRAMES:
            raise ValueError(f"model.frame must be one of {FRAMES}, got {self.frame!r}")
        for name in ("dropout", "attn_dropout"):
            if not 0.0 <= getattr(self, name) < 1.0:
                raise ValueError(f"model.{name} must be in [0, 1), got {getattr(self, name)}")
        if self.d_model % self.n_heads or self.event_d_model % self.event_heads:
            raise ValueError("model.d_model (event_d_model) must be divisible by n_heads "
                             f"(event_heads): {self.d_model}/{self.n_heads}, "
                             f"{self.event_d_model}/{self.event_heads}")
        if self.serve_bias and not self.serve_head:
            raise ValueError("model.serve_bias shifts the serve head's odds: it needs "
                             "serve_head=True")
        if self.serve_short and not self.serve_bias:
            raise ValueError("model.serve_short is read with the serve head's table: it needs "
                             "serve_bias=True")
        if self.serve_lateral and not self.serve_bias:
            raise ValueError("model.serve_lateral is read with the serve head's table: it "
                             "needs serve_bias=True")
        if self.serve_aim and not self.serve_bias:
            raise ValueError("model.serve_aim is read with the serve head's table: it needs "
                             "serve_bias=True")
        if self.strike_bias and not self.strike_head:
            raise ValueError("model.strike_bias shifts the strike head's odds: it needs "
                             "strike_head=True")
        if self.strike_width and not self.strike_bias:
            raise ValueError("model.strike_width is read with the strike head's error table: "
                             "it needs strike_bias=True")
        if self.strike_pressure and not self.strike_return:
            raise ValueError("model.strike_pressure is read beside the returns' table (it "
                             "leaves the returns alone): it needs strike_return=True")
        if self.strike_players and not self.strike_roles:
            raise ValueError("model.strike_players reads the hitter's role from the role "
                             "shift's index: it needs model.strike_roles")
        if self.strike_shape and not self.strike_pressure:
            raise ValueError("model.strike_shape is read with the opponents' table: it needs "
                             "strike_pressure=True")
        if self.strike_depth and not self.strike_pressure:
            raise ValueError("model.strike_depth is fitted with the opponents' table: it needs "
                             "strike_pressure=True")
        if self.strike_second and not self.strike_bias:
            raise ValueError("model.strike_second adds to the player's table: it needs "
                             "model.strike_bias")
        if self.strike_late and not self.strike_pressure:
            raise ValueError("model.strike_late is fitted with the opponents' table: it needs "
                             "strike_pressure=True")
        if self.strike_return_surface and not self.strike_return:
            raise ValueError("model.strike_return_surface is fitted with the receivers' returns "
                             "table: it needs strike_return=True")
        if self.strike_surface and not self.strike_bias:
            raise ValueError("model.strike_surface is added on the strike head's error table: "
                             "it needs strike_bias=True")
        if self.strike_return and not self.strike_bias:
            raise ValueError("model.strike_return is read with the strike head's error table: "
                             "it needs strike_bias=True")
        if self.receiver_start and self.head != "factorised":
            raise ValueError("model.receiver_start shifts the players' factorised head: it "
                             "needs head='factorised'")
        if self.clock_s < 0:
            raise ValueError(f"model.clock_s must be >= 0 (0: no clock), got {self.clock_s}")
        if self.ball_intercept and not self.ball_forecast:
            raise ValueError("model.ball_intercept adds columns to the ball's forecast: it needs "
                             "ball_forecast=True")
        if self.contact_reach and self.head != "factorised":
            raise ValueError("model.contact_reach shifts the ball's factorised head: it needs "
                             "head='factorised'")
        if self.n_bins < 3 or self.n_bins % 2 == 0:
            raise ValueError(f"model.n_bins must be odd and >= 3 (a bin centred on 0), "
                             f"got {self.n_bins}")
        if self.ball_sub_bins != 0 and self.ball_sub_bins < 2:
            raise ValueError(f"model.ball_sub_bins must be 0 (none) or >= 2, "
                             f"got {self.ball_sub_bins}")
        if len(self.ball_max_speed_mps) != 3:
            raise ValueError("model.ball_max_speed_mps needs 3 values (x, y, z)")

    @property
    def ball_bin_half_ranges_m(self) -> tuple[float, float, float]:
        """Half ranges of the ball's bins (m a frame), x, y and z (the decoder's, the
        diagnostics' and the bin studies' one source)."""
        return tuple(v / self.fps for v in self.ball_max_speed_mps)

    @property
    def window_frames(self) -> int:
        return max(2, int(round(self.window_s * self.fps)))

    def to_dict(self) -> dict:
        d = asdict(self)
        d["embed_hidden"] = list(self.embed_hidden)
        d["ball_max_speed_mps"] = list(self.ball_max_speed_mps)
        d["features"] = list(self.features)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> ModelConfig:
        """Build from a dict (or Hydra DictConfig); unknown keys are an error, missing keys
        take their defaults (so older model files load)."""
        d = dict(d)
        known = {f.name for f in fields(cls)}
        extra = sorted(set(d) - known)
        if extra:
            raise ValueError(f"unknown model config keys {extra}; known: {sorted(known)}")
        if "ball_centre" not in d:
            d["ball_centre"] = LEGACY_BALL_CENTRE.get(d.get("bin_centre", "current"), "current")
        return cls(**d)
