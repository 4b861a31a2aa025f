"""Court geometry: exact expectations at corners, lines, both ends, both sides, both hands."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from sportsngen.tennis.court import (
    BALL_RADIUS_M,
    BASELINE_X_M,
    NET_HEIGHT_CENTRE_M,
    SERVICE_LINE_X_M,
    SINGLES_HALF_WIDTH_M,
    THIRD_WIDTH_M,
    court_half,
    forehand_side_sign,
    is_in_service_box,
    is_in_singles,
    net_height_m,
    serve_zone,
    service_box,
    shot_direction,
)

W = SINGLES_HALF_WIDTH_M
L = BASELINE_X_M
S = SERVICE_LINE_X_M


def test_existing_constants_unchanged():
    assert (L, S, W) == (11.885, 6.40, 4.115)
    assert net_height_m(0.0) == NET_HEIGHT_CENTRE_M
    assert net_height_m(6.40) == pytest.approx(1.07)


# --- court_half ---------------------------------------------------------------------------

def test_court_half_scalars_and_net_convention():
    assert court_half(0.0) == 1  # documented convention: the net line is the +1 half
    assert court_half(-1e-9) == -1
    assert court_half(5.0) == 1
    assert court_half(-11.885) == -1
    assert isinstance(court_half(3.0), int)


def test_court_half_array():
    np.testing.assert_array_equal(court_half(np.array([-3.0, 0.0, 2.0])), [-1, 1, 1])


# --- forehand side --------------------------------------------------------------------------

@pytest.mark.parametrize("end,hand,expected", [
    (-1, "right", -1),  # at the -x end facing +x, the right hand points to -y
    (1, "right", 1),
    (-1, "left", 1),
    (1, "left", -1),
])
def test_forehand_side_sign(end, hand, expected):
    assert forehand_side_sign(end, hand) == expected


def test_forehand_side_sign_vectorised_and_errors():
    got = forehand_side_sign(np.array([-1, 1, -1]), np.array(["right", "right", "left"]))
    np.testing.assert_array_equal(got, [-1, 1, 1])
    with pytest.raises(ValueError, match="handedness"):
        forehand_side_sign(1, "ambidextrous")
    with pytest.raises(ValueError, match="end"):
        forehand_side_sign(0, "right")


# --- singles in/out -------------------------------------------------------------------------

@pytest.mark.parametrize("side", [1, -1])
def test_is_in_singles_corners_lines_and_outside(side):
    for y in (W, -W, 0.0):
        assert is_in_singles(side * L, y, side)  # baseline corners and centre mark: in
    assert is_in_singles(side * 0.01, W, side)
    assert not is_in_singles(side * (L + 0.001), 0.0, side)  # just long
    assert not is_in_singles(side * 5.0, W + 0.001, side)  # just wide
    assert not is_in_singles(-side * 5.0, 0.0, side)  # the other half
    assert is_in_singles(0.0, 0.0, side)  # net line belongs to both halves


def test_is_in_singles_ball_radius_allowance():
    assert not is_in_singles(L + 0.03, 0.0, 1)
    assert is_in_singles(L + 0.03, 0.0, 1, ball_radius_m=BALL_RADIUS_M)
    assert is_in_singles(-3.0, -(W + 0.0335), -1, ball_radius_m=BALL_RADIUS_M)
    assert not is_in_singles(-3.0, -(W + 0.034), -1, ball_radius_m=BALL_RADIUS_M)
    with pytest.raises(ValueError, match="ball_radius_m"):
        is_in_singles(1.0, 0.0, 1, ball_radius_m=-0.1)


def test_is_in_singles_vectorised_and_bad_side():
    x = np.array([5.0, 12.0, -5.0, 11.885])
    y = np.array([0.0, 0.0, 0.0, -4.2])
    np.testing.assert_array_equal(is_in_singles(x, y, 1), [True, False, False, False])
    with pytest.raises(ValueError, match="side"):
        is_in_singles(1.0, 0.0, 2)


# --- service boxes --------------------------------------------------------------------------

@pytest.mark.parametrize("server_end,side,box", [
    # From the -x end the server's right is -y: on the deuce side he stands at y < 0 and
    # serves diagonally into x > 0, y > 0 (the receiver's right-hand box).
    (-1, "deuce", (0.0, S, 0.0, W)),
    (-1, "ad", (0.0, S, -W, 0.0)),
    (1, "deuce", (-S, 0.0, -W, 0.0)),
    (1, "ad", (-S, 0.0, 0.0, W)),
])
def test_service_box_signs(server_end, side, box):
    assert service_box(server_end, side) == pytest.approx(box)
    # The deuce box is always on the receiver's right, i.e. the receiver's forehand side for a
    # right-hander: the receiver's end is -server_end.
    y_sign = np.sign(sum(service_box(server_end, side)[2:]))
    receiver_right = forehand_side_sign(-server_end, "right")
    assert (y_sign == receiver_right) == (side == "deuce")


def test_service_box_errors():
    with pytest.raises(ValueError, match="serving_side"):
        service_box(1, "left")
    with pytest.raises(ValueError, match="server_end"):
        service_box(0, "deuce")


@pytest.mark.parametrize("server_end", [1, -1])
@pytest.mark.parametrize("side", ["deuce", "ad"])
def test_is_in_service_box_corners_lines_and_faults(server_end, side):
    x0, x1, y0, y1 = service_box(server_end, side)
    far_x = x0 if server_end == 1 else x1  # service line
    far_y = y0 if y0 < 0 else y1  # sideline
    assert is_in_service_box(far_x, far_y, server_end, side)  # far corner: both lines
    assert is_in_service_box(far_x, 0.0, server_end, side)  # service line meets centre line
    assert is_in_service_box(far_x / 2, far_y / 2, server_end, side)
    assert not is_in_service_box(far_x * 1.01, far_y / 2, server_end, side)  # long
    assert not is_in_service_box(far_x / 2, far_y * 1.01, server_end, side)  # wide
    assert not is_in_service_box(far_x / 2, -far_y / 2, server_end, side)  # other box
    assert not is_in_service_box(-far_x / 2, far_y / 2, server_end, side)  # server's half
    # The ball radius lets a ball just past the service line touch it; never past the net.
    long_x = far_x + np.sign(far_x) * 0.03
    assert not is_in_service_box(long_x, far_y / 2, server_end, side)
    assert is_in_service_box(long_x, far_y / 2, server_end, side, ball_radius_m=BALL_RADIUS_M)
    assert not is_in_service_box(-np.sign(far_x) * 0.01, far_y / 2, server_end, side,
                                 ball_radius_m=BALL_RADIUS_M)


def test_is_in_service_box_vectorised():
    x = np.array([3.0, 3.0, 7.0, -3.0])
    y = np.array([2.0, -2.0, 2.0, 2.0])
    np.testing.assert_array_equal(is_in_service_box(x, y, -1, "deuce"),
                                  [True, False, False, False])


# --- serve zones ----------------------------------------------------------------------------

def test_serve_zone_thirds():
    third = W / 3
    assert serve_zone(0.0) == "T"
    assert serve_zone(third - 1e-6) == "T"
    assert serve_zone(third) == "body"
    assert serve_zone(-(2 * third - 1e-6)) == "body"
    assert serve_zone(2 * third) == "wide"
    assert serve_zone(-W) == "wide"
    assert serve_zone(5.0) == "wide"  # a fault past the sideline
    np.testing.assert_array_equal(serve_zone(np.array([0.5, -2.0, 3.9])), ["T", "body", "wide"])


# --- shot direction -------------------------------------------------------------------------

FAR, CORNER, DEEP = 11.0, 3.0, 8.0
# (hitter end, handedness, stroke, hitter y, landing y, expected). The hitter stands at x =
# end * FAR and the ball lands at x = -end * DEEP.
DIRECTION_CASES = [
    # Right-hander at the -x end: forehand side is -y.
    (-1, "right", "forehand", -CORNER, CORNER, "cross_court"),
    (-1, "right", "forehand", -CORNER, -CORNER, "down_the_line"),
    (-1, "right", "forehand", -CORNER, 0.5, "middle"),
    (-1, "right", "backhand", CORNER, -CORNER, "cross_court"),
    (-1, "right", "backhand", CORNER, CORNER, "down_the_line"),
    (-1, "right", "forehand", CORNER, -CORNER, "inside_out"),  # ran around the backhand
    (-1, "right", "forehand", CORNER, CORNER, "inside_in"),
    (-1, "right", "forehand", 0.0, CORNER, "cross_court"),  # from the middle: stroke side -y
    (-1, "right", "forehand", 0.0, -CORNER, "down_the_line"),
    (-1, "right", "backhand", 0.0, -CORNER, "cross_court"),
    (-1, "right", "backhand", -CORNER, -CORNER, "down_the_line"),  # backhand on the fh side
    (-1, "right", "backhand", -CORNER, CORNER, "cross_court"),
    (-1, "right", "forehand_volley", CORNER, -CORNER, "cross_court"),  # no inside volleys
    # Right-hander at the +x end: forehand side is +y.
    (1, "right", "forehand", CORNER, -CORNER, "cross_court"),
    (1, "right", "forehand", CORNER, CORNER, "down_the_line"),
    (1, "right", "forehand", -CORNER, CORNER, "inside_out"),
    (1, "right", "forehand", -CORNER, -CORNER, "inside_in"),
    (1, "right", "backhand", -CORNER, CORNER, "cross_court"),
    (1, "right", "backhand", 0.0, -CORNER, "down_the_line"),  # from the middle: bh side -y
    (1, "right", "backhand", 0.0, CORNER, "cross_court"),
    (1, "right", "forehand", 0.0, -1.0, "middle"),
    # Left-hander at the -x end: forehand side is +y.
    (-1, "left", "forehand", CORNER, -CORNER, "cross_court"),
    (-1, "left", "forehand", CORNER, CORNER, "down_the_line"),
    (-1, "left", "forehand", -CORNER, CORNER, "inside_out"),
    (-1, "left", "forehand", -CORNER, -CORNER, "inside_in"),
    (-1, "left", "backhand", -CORNER, CORNER, "cross_court"),
    (-1, "left", "overhead", 0.0, -CORNER, "cross_court"),  # overhead hit from the fh side
    # Left-hander at the +x end: forehand side is -y.
    (1, "left", "forehand", -CORNER, CORNER, "cross_court"),
    (1, "left", "forehand", CORNER, -CORNER, "inside_out"),
    (1, "left", "forehand", CORNER, CORNER, "inside_in"),
    (1, "left", "backhand", CORNER, -CORNER, "cross_court"),
    (1, "left", "backhand", CORNER, CORNER, "down_the_line"),
]


@pytest.mark.parametrize("end,hand,stroke,hy,ly,expected", DIRECTION_CASES)
def test_shot_direction_cases(end, hand, stroke, hy, ly, expected):
    assert shot_direction(end * FAR, hy, -end * DEEP, ly, hand, stroke) == expected


def test_shot_direction_zone_boundaries():
    half = THIRD_WIDTH_M / 2  # 1.3717 m: edge of the middle third
    assert shot_direction(-FAR, -CORNER, DEEP, half, "right", "forehand") == "middle"
    assert shot_direction(-FAR, -CORNER, DEEP, half + 1e-6, "right", "forehand") == "cross_court"
    # A hitter exactly on the edge of the middle third counts as in the middle third: from
    # there, a forehand to his backhand side is plain cross court, never inside-out.
    assert shot_direction(-FAR, half, DEEP, -CORNER, "right", "forehand") == "down_the_line"
    assert shot_direction(-FAR, half + 1e-6, DEEP, -CORNER, "right", "forehand") == "inside_out"


def test_shot_direction_vectorised_matches_scalar():
    end, hand, stroke, hy, ly, expected = map(np.array, zip(*DIRECTION_CASES))
    got = shot_direction(end * FAR, hy, -end * DEEP, ly, hand, stroke)
    np.testing.assert_array_equal(got, expected)


def test_shot_direction_bad_stroke():
    with pytest.raises(ValueError, match="stroke"):
        shot_direction(-FAR, 0.0, DEEP, 2.0, "right", "serve")


coord = st.floats(-W, W, allow_nan=False)


@given(hy=coord, ly=coord, hand=st.sampled_from(["right", "left"]),
       stroke=st.sampled_from(["forehand", "backhand", "forehand_volley"]),
       hx=st.floats(0.5, 14.0), lx=st.floats(0.5, 12.0))
def test_shot_direction_symmetries(hy, ly, hand, stroke, hx, lx):
    """The class is invariant when the court is turned round (x, y -> -x, -y) and when it is
    mirrored (y -> -y) together with a swap of handedness."""
    base = shot_direction(-hx, hy, lx, ly, hand, stroke)
    assert shot_direction(hx, -hy, -lx, -ly, hand, stroke) == base
    other = "left" if hand == "right" else "right"
    # Skip the exact zero lateral positions where np.sign breaks the mirror symmetry.
    if hy != 0.0 and ly != 0.0:
        assert shot_direction(-hx, -hy, lx, -ly, other, stroke) == base
