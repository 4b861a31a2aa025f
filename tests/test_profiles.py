"""Player profiles: validation, the named players, the population sampler, the kinematics."""

from __future__ import annotations

import dataclasses
from collections import Counter

import numpy as np
import pytest

from sportsngen.synth.players import Mover, max_distance_m, min_time_s
from sportsngen.synth.profiles import (
    STYLES,
    PlayerProfile,
    average_profile,
    get_profile,
    named_profiles,
    sample_population,
)

NAMED = ("Roger Federer", "Rafael Nadal", "Novak Djokovic", "Andy Murray", "John Isner",
         "Serena Williams", "Maria Sharapova")


def test_named_players_present_and_plausible():
    named = named_profiles()
    assert set(NAMED) <= set(named)
    assert named["Rafael Nadal"].handedness == "left"
    assert named["Serena Williams"].gender == "women"
    for p in named.values():
        assert 0.15 <= p.reaction_s <= 0.25
        assert p.max_speed_mps <= 7.0 and p.max_accel_mps2 <= 6.0
        assert 2.5 <= p.contact_height_m <= 3.1
        assert p.second_serve_kmh < p.first_serve_kmh


def test_get_profile_unknown_lists_known():
    with pytest.raises(ValueError, match="known players: .*Roger Federer"):
        get_profile("Bjorn Borg")
    p = PlayerProfile(name="X")
    assert get_profile(p) is p


@pytest.mark.parametrize("field, value, match", [
    ("aggression", -0.1, "aggression is a probability"),
    ("serve_wide", 1.5, "serve_wide is a probability"),
    ("first_serve_kmh", -10.0, "first_serve_kmh must be >= 0"),
    ("reaction_s", float("nan"), "reaction_s must be a finite number"),
    ("contact_height_m", 4.0, "contact_height_m must lie in"),
    ("gender", "mixed", "gender must be one of"),
    ("style", "moonballer", "style must be one of"),
])
def test_profile_validation(field, value, match):
    with pytest.raises(ValueError, match=match):
        PlayerProfile(name="X", **{field: value})


def test_profile_dict_round_trip_and_unknown_fields():
    p = get_profile("Roger Federer")
    assert PlayerProfile.from_dict(p.to_dict()) == p
    with pytest.raises(ValueError, match="unknown profile fields \\['backhand_grip'\\]"):
        PlayerProfile.from_dict({**p.to_dict(), "backhand_grip": 1.0})
    mix = p.serve_mix
    assert mix.sum() == pytest.approx(1.0) and (mix >= 0).all()


def test_average_profile_is_the_mean_of_named_men():
    men = [p for p in named_profiles().values() if p.gender == "men"]
    avg = average_profile("men")
    assert avg.first_serve_kmh == pytest.approx(np.mean([p.first_serve_kmh for p in men]))
    assert avg.rally_noise_deg == pytest.approx(np.mean([p.rally_noise_deg for p in men]))
    with pytest.raises(ValueError, match="gender"):
        average_profile("juniors")
    # The population keeps the tour's composure on rushed returns, not the named players'.
    from dataclasses import replace

    calm = [replace(p, rushed_return_noise=1.5) for p in men]
    assert average_profile("men", profiles=calm).rushed_return_noise == 3.0
    assert average_profile("men", profiles=calm).rally_noise_deg == avg.rally_noise_deg


def test_population_sampler_deterministic_varied_and_plausible():
    a = sample_population(200, seed=7)
    assert a == sample_population(200, seed=7)
    assert a != sample_population(200, seed=8)
    assert len({p.name for p in a}) == 200
    lefties = sum(p.handedness == "left" for p in a) / len(a)
    assert 0.08 <= lefties <= 0.22
    styles = Counter(p.style for p in a)
    assert set(styles) == set(STYLES)
    for p in a:
        assert 0.15 <= p.reaction_s <= 0.28
        assert p.max_speed_mps <= 7.0 and p.max_accel_mps2 <= 6.0
        assert 2.5 <= p.contact_height_m <= 3.1
        assert p.second_serve_kmh <= p.first_serve_kmh - 15.0 + 1e-9
    # Styles show: serve-volleyers come in, counter-punchers stay back.
    sv = np.mean([p.net_approach for p in a if p.style == "serve_volleyer"])
    cp = np.mean([p.net_approach for p in a if p.style == "counter_puncher"])
    assert sv > cp + 0.2
    women = sample_population(5, seed=1, gender="women")
    assert all(p.gender == "women" and p.name.startswith("Pop W") for p in women)
    with pytest.raises(ValueError, match="n must be a positive integer"):
        sample_population(0)


def test_min_time_and_max_distance_are_inverse():
    d = np.array([0.0, 0.5, 2.0, 4.0, 8.0])
    t = min_time_s(d, 7.0, 6.0)
    assert t[0] == 0.0
    assert t[1] == pytest.approx(np.sqrt(2 * 0.5 / 6.0))
    assert t[4] == pytest.approx(8.0 / 7.0 + 7.0 / 12.0)  # past v^2 / 2a = 4.08 m: cruising
    assert np.allclose(max_distance_m(t, 7.0, 6.0), d)


def test_mover_obeys_limits_and_arrives():
    m = Mover(0.0, 0.0, max_speed_mps=6.5, max_accel_mps2=5.5, dt_s=0.04)
    m.run_to(60, 5.0, -3.0)
    m.run_to(160, -4.0, 2.0)
    xy = m.as_array()
    assert len(xy) == 161
    v = np.diff(xy, axis=0) / 0.04
    a = np.diff(v, axis=0) / 0.04
    assert np.linalg.norm(v, axis=1).max() <= 6.5 + 1e-9
    assert np.linalg.norm(a, axis=1).max() <= 5.5 + 1e-9
    assert np.hypot(xy[60, 0] - 5.0, xy[60, 1] + 3.0) < 0.05
    assert np.hypot(xy[-1, 0] + 4.0, xy[-1, 1] - 2.0) < 0.05


def test_profile_is_frozen():
    p = get_profile("Rafael Nadal")
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.aggression = 0.9  # type: ignore[misc]


def test_thin_real_figures_fall_back_to_the_tour_in_calibration():
    import pandas as pd

    from sportsngen.synth.calibrate import MIN_OWN_RALLY_STRIKES, calibration_targets
    from sportsngen.synth.profiles import PlayerProfile

    rows = []
    for player, surface, n, value in [("Her", "hard", MIN_OWN_RALLY_STRIKES - 1, 0.7),
                                      ("Her", "clay", MIN_OWN_RALLY_STRIKES, 0.8),
                                      ("WTA", "hard", 9000, 0.9), ("WTA", "clay", 9000, 1.0),
                                      ("ATP", "hard", 9000, 1.1)]:
        for stat, v in (("rally_contact_z_median", value), ("rally_net_z_median", value + 1)):
            rows.append((player, surface, stat, v, n))
    t = pd.DataFrame(rows, columns=["player", "surface", "statistic", "value", "n"])
    got = calibration_targets(t, {"Her": PlayerProfile(name="Her", gender="women")})
    her = got[got["player"] == "Her"].set_index(["surface", "statistic"])["value"]
    # one match too few on hard: the WTA's figures; enough on clay: her own
    assert her[("hard", "rally_contact_z_median")] == 0.9
    assert her[("hard", "rally_net_z_median")] == 1.9
    assert her[("clay", "rally_contact_z_median")] == 0.8
    assert len(her) == 4
    # the tours' own rows are kept as they are
    assert len(got[got["player"] == "ATP"]) == 2 and len(got[got["player"] == "WTA"]) == 4


def test_hawkeye_step_moves_each_knob_by_its_rule():
    import math

    import pandas as pd

    from sportsngen.synth.calibrate import MIN_HAWKEYE_N, step_hawkeye
    from sportsngen.synth.profiles import PlayerProfile

    p = PlayerProfile(name="Him", gender="men", return_pace=1.0, contact_height_m=2.8)

    def table(rows):
        return pd.DataFrame([("Him",) + r for r in rows],
                            columns=["player", "surface", "statistic", "value", "n"])

    # generated returns cross 0.3 and 0.1 m above the real ones: the mean error -0.2 m
    sim = table([("hard", "return_net_z_median", 2.0, 500),
                 ("clay", "return_net_z_median", 1.9, 500),
                 ("hard", "serve_contact_z_median", 2.7, 500),
                 ("grass", "serve_contact_z_median", 2.0, MIN_HAWKEYE_N - 1)])  # too few
    real = table([("hard", "return_net_z_median", 1.7, 400),
                  ("clay", "return_net_z_median", 1.8, 400),
                  ("hard", "serve_contact_z_median", 2.85, 400),
                  ("grass", "serve_contact_z_median", 3.3, 400)])
    # and 90 % of them below 3.0 m where the real ones stay below 2.6 m: more composure
    sim = pd.concat([sim, table([("hard", "return_net_z_p90", 3.0, 500)])])
    real = pd.concat([real, table([("hard", "return_net_z_p90", 2.6, 400)])])
    q = step_hawkeye(p, sim, real, damping=0.5)
    assert q.return_pace == pytest.approx(math.exp(0.5 * -0.45 * -0.2))  # faster, flatter
    assert q.rushed_return_noise == pytest.approx(3.0 * math.exp(0.5 * 1.7 * -0.4))
    assert q.contact_height_m == pytest.approx(2.8 + 0.5 * 0.15)
    assert q.rally_speed_mps == p.rally_speed_mps and q.serve_wide == p.serve_wide
    # no real figures: unchanged
    assert step_hawkeye(p, sim, real.assign(player="Other"), damping=0.5) == p


def test_aces_move_the_serve_margin_only_where_the_disguise_is_at_its_floor():
    from dataclasses import replace

    import pandas as pd

    from sportsngen.synth.calibrate import DISGUISE_RANGE_S, RALLY_BINS, STAT_KEYS, step_2011
    from sportsngen.synth.profiles import PlayerProfile

    keys = STAT_KEYS + RALLY_BINS
    tgt = pd.Series({k: 0.1 for k in keys} | {"first_serve_kmh_median": 185.0,
                                               "second_serve_kmh_median": 150.0,
                                               "rally_mean": 4.0, "ace": 0.07})
    sim = dict(tgt) | {"ace": 0.10}   # three points too many aces
    floor = PlayerProfile(name="Him", serve_disguise_s=DISGUISE_RANGE_S[0], serve_margin_m=0.5)
    q = step_2011(floor, sim, tgt, damping=0.5)
    assert q.serve_margin_m == pytest.approx(0.5 + 4.0 * 0.5 * 0.03)
    assert q.serve_disguise_s == DISGUISE_RANGE_S[0]
    free = replace(floor, serve_disguise_s=0.0)
    q = step_2011(free, sim, tgt, damping=0.5)
    assert q.serve_margin_m == 0.5 and q.serve_disguise_s == pytest.approx(-0.8 * 0.5 * 0.03)
    # too few aces at the floor: the margin comes back down, never below every player's 0.45 m
    q = step_2011(replace(floor, serve_margin_m=0.46), dict(sim, ace=0.0), tgt, damping=0.5)
    assert q.serve_margin_m == 0.45


def test_surface_overrides_replace_fields_on_their_surface_only():
    p = PlayerProfile.from_dict({"name": "X", "rushed_return_noise": 2.4,
                                 "surface_overrides": {"clay": {"rushed_return_noise": 1.5,
                                                                "second_return_depth_m": 2.1}}})
    clay = p.on_surface("clay")
    assert clay.rushed_return_noise == 1.5 and clay.second_return_depth_m == 2.1
    assert clay.on_surface("clay") == clay          # idempotent
    assert p.on_surface("hard") is p and p.on_surface("grass").rushed_return_noise == 2.4
    # the JSON form survives a round trip, and a profile without overrides writes none
    assert PlayerProfile.from_dict(p.to_dict()) == p
    assert p.to_dict()["surface_overrides"] == {"clay": {"rushed_return_noise": 1.5,
                                                         "second_return_depth_m": 2.1}}
    assert "surface_overrides" not in PlayerProfile(name="Y").to_dict()
    hash(p)                                          # still usable as a key
    with pytest.raises(ValueError, match="unknown surface 'carpet'"):
        p.on_surface("carpet")


@pytest.mark.parametrize("overrides, match", [
    ({"carpet": {"reach_m": 1.0}}, "unknown surface 'carpet'"),
    ({"clay": {"handedness": 1.0}}, "names fields \\['handedness'\\] that no surface"),
    ({"clay": {"backhand_grip": 1.0}}, "names fields \\['backhand_grip'\\]"),
    ({"clay": {"aggression": 1.5}}, "aggression is a probability"),
    ({"clay": 2.0}, "surface_overrides must map a surface"),
])
def test_surface_overrides_are_validated(overrides, match):
    with pytest.raises(ValueError, match=match):
        PlayerProfile.from_dict({"name": "X", "surface_overrides": overrides})


def test_the_population_and_the_average_ignore_surface_overrides():
    men = [dataclasses.replace(p, surface_overrides=(("clay", (("reach_m", 0.5),)),))
           for p in named_profiles().values() if p.gender == "men"]
    avg = average_profile("men", profiles=men)
    assert avg.surface_overrides == () and avg.reach_m == pytest.approx(
        np.mean([p.reach_m for p in men]))
    assert all(q.surface_overrides == () for q in sample_population(5, base=avg))


def test_named_nadal_returns_by_surface():
    # His real returns run the other way between surfaces from everyone else's (Hawk-Eye:
    # against second serves 3.29 m behind the baseline on hard, 2.93 on clay; 90 % cross the
    # net below 3.53 m on hard, 3.14 on clay): deeper and more often rushed long on hard, a
    # flatter return on clay.
    nadal = get_profile("Rafael Nadal")
    hard, clay = nadal.on_surface("hard"), nadal.on_surface("clay")
    assert hard.second_return_depth_m > nadal.second_return_depth_m > \
        clay.second_return_depth_m
    assert hard.rushed_return_noise > nadal.rushed_return_noise > clay.rushed_return_noise
    assert clay.return_pace > nadal.return_pace == hard.return_pace
    assert nadal.on_surface("grass") == nadal        # grass plays the base profile


def test_the_rally_policy_plays_the_surface_profile():
    from sportsngen.synth.behaviour import return_depth_m
    from sportsngen.synth.rally import ProfilePolicy

    p = PlayerProfile.from_dict({"name": "X", "second_return_depth_m": 0.5,
                                 "surface_overrides": {"clay": {"second_return_depth_m": 2.0}}})
    on_clay = ProfilePolicy(PlayerProfile(name="S"), p, 1, "deuce", 2, "clay")
    on_hard = ProfilePolicy(PlayerProfile(name="S"), p, 1, "deuce", 2, "hard")
    assert on_clay.profiles[1].second_return_depth_m == 2.0
    assert on_hard.profiles[1].second_return_depth_m == 0.5
    # where the receiver waits for a second serve follows
    assert on_clay.serve(np.random.default_rng(0))[1][0] != \
        on_hard.serve(np.random.default_rng(0))[1][0]
    assert return_depth_m(on_clay.profiles[1], 2, "clay") == pytest.approx(2.0 + 0.3)


def test_hawkeye_step_moves_a_surface_override_on_that_surface_alone():
    import math

    import pandas as pd

    from sportsngen.synth.calibrate import step_hawkeye

    p = PlayerProfile.from_dict({"name": "Him", "rushed_return_noise": 3.0,
                                 "surface_overrides": {"clay": {"rushed_return_noise": 2.0}}})

    def table(rows):
        return pd.DataFrame([("Him",) + r for r in rows],
                            columns=["player", "surface", "statistic", "value", "n"])

    sim = table([("hard", "return_net_z_p90", 3.0, 500), ("clay", "return_net_z_p90", 3.3, 500),
                 ("hard", "return_net_z_median", 2.0, 500),
                 ("clay", "return_net_z_median", 1.8, 500)])
    real = table([("hard", "return_net_z_p90", 3.5, 400), ("clay", "return_net_z_p90", 3.1, 400),
                  ("hard", "return_net_z_median", 1.9, 400),
                  ("clay", "return_net_z_median", 1.9, 400)])
    q = step_hawkeye(p, sim, real, damping=0.5)
    assert q.rushed_return_noise == pytest.approx(3.0 * math.exp(0.5 * 1.7 * 0.5))   # hard
    assert q.on_surface("clay").rushed_return_noise == pytest.approx(
        2.0 * math.exp(0.5 * 1.7 * -0.2))                                            # clay
    # a field no surface overrides follows the mean over the surfaces, as before
    assert q.return_pace == pytest.approx(0.85 * math.exp(0.5 * -0.45 * 0.0))


def test_2011_step_moves_a_surface_override_with_its_base():
    import pandas as pd

    from sportsngen.synth.calibrate import RALLY_BINS, STAT_KEYS, step_2011

    keys = STAT_KEYS + RALLY_BINS
    tgt = pd.Series({k: 0.1 for k in keys} | {"first_serve_kmh_median": 185.0,
                                               "second_serve_kmh_median": 150.0,
                                               "rally_mean": 4.0, "second_serve_won": 0.55})
    # five points too many second serves won, four km/h too slow a first serve
    sim = dict(tgt) | {"second_serve_won": 0.60, "first_serve_kmh_median": 181.0}
    p = PlayerProfile.from_dict({"name": "Him", "second_serve_initiative": 1.4,
                                 "first_serve_kmh": 190.0,
                                 "surface_overrides": {"hard": {"second_serve_initiative": 0.8,
                                                                "first_serve_kmh": 180.0,
                                                                "reach_m": 1.7}}})
    q = step_2011(p, sim, tgt, damping=0.5)
    ratio = np.exp(4.0 * 0.5 * -0.05)
    assert q.second_serve_initiative == pytest.approx(1.4 * ratio)
    hard = q.on_surface("hard")
    assert hard.second_serve_initiative == pytest.approx(0.8 * ratio)   # the same ratio
    assert q.first_serve_kmh == pytest.approx(192.0)
    assert hard.first_serve_kmh == pytest.approx(182.0)                 # the same difference
    assert hard.reach_m == 1.7                                          # not a 2011 knob
    # a profile without overrides steps exactly as before
    plain = step_2011(dataclasses.replace(p, surface_overrides=()), sim, tgt, damping=0.5)
    assert plain == dataclasses.replace(q, surface_overrides=())


def test_hawkeye_step_moves_a_surface_serve_mix_on_that_surface_alone():
    import pandas as pd

    from sportsngen.synth.calibrate import step_hawkeye

    p = PlayerProfile.from_dict({"name": "Him", "serve_wide": 0.5, "serve_body": 0.1,
                                 "serve_t": 0.4,
                                 "surface_overrides": {"clay": {"serve_wide": 0.6}}})

    def table(rows):
        return pd.DataFrame([("Him",) + r for r in rows],
                            columns=["player", "surface", "statistic", "value", "n"])

    zones = ("serve1_wide_share", "serve1_body_share", "serve1_t_share")
    sim = table([("hard", z, v, 300) for z, v in zip(zones, (0.5, 0.1, 0.4))] +
                [("clay", z, v, 300) for z, v in zip(zones, (0.6, 0.1, 0.3))])
    real = table([("hard", z, v, 300) for z, v in zip(zones, (0.5, 0.1, 0.4))] +
                 [("clay", z, v, 300) for z, v in zip(zones, (0.3, 0.1, 0.6))])
    q = step_hawkeye(p, sim, real, damping=1.0)
    # hard was right: the base mix stays; clay had too many wide serves: its mix moves
    assert (q.serve_wide, q.serve_body, q.serve_t) == pytest.approx((0.5, 0.1, 0.4))
    clay = q.on_surface("clay")
    m = np.array([0.6 * 0.3 / 0.6, 0.1, 0.4 * 0.6 / 0.3])     # (fields on clay) x real / sim
    assert (clay.serve_wide, clay.serve_body, clay.serve_t) == pytest.approx(tuple(m / m.sum()))
