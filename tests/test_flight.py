"""Flying over a planet at the altitude's pace (planetlod/flight.py): the
speed follows the height above the ground, the eye never ends a step below
the clearance, mouse look keeps the horizon defined."""
import math

import pytest

from planetlod import flight

RADIUS = 1000000.0


def flat(point):
    return math.sqrt(sum(c * c for c in point)) - RADIUS


def ridged(point):
    """A ground with sharp 400 m ridges every 2 km along x (metres above it)."""
    r = math.sqrt(sum(c * c for c in point))
    along = RADIUS * math.atan2(point[0], point[2])
    ridge = 400.0 * max(0.0, 1.0 - abs((along % 2000.0) - 1000.0) / 100.0)
    return r - RADIUS - ridge


def test_speed_follows_the_height_above_the_ground():
    assert flight.speed(2000.0) == pytest.approx(1000.0 * flight.speed(2.0))
    assert flight.speed(2000.0, factor=2.0) == pytest.approx(2.0 * flight.speed(2000.0))
    # on the ground, still the clearance's pace
    assert flight.speed(0.0, clearance=2.0) == flight.speed(2.0, clearance=2.0) > 0.0
    assert flight.scaled_factor(1.0, 1) == pytest.approx(flight.FACTOR_STEP)
    assert flight.scaled_factor(1.0, -1000) == flight.FACTOR_RANGE[0]
    assert flight.scaled_factor(1.0, 1000) == flight.FACTOR_RANGE[1]


def test_a_level_flight_covers_the_distance_asked():
    for height in (2.0, 2000.0):
        eye = (0.0, 0.0, RADIUS + height)
        end, end_height = flight.fly(eye, (1.0, 0.0, 0.0), flight.speed(height), flat, 2.0)
        assert math.dist(eye, end) == pytest.approx(flight.SPEED_PER_METRE * height, rel=1e-3)
        assert end_height >= height


def test_a_dive_never_ends_below_the_clearance():
    eye = (0.0, 0.0, RADIUS + 2000.0)
    down = (0.0, 0.0, -1.0)
    height = 2000.0
    for _ in range(300):  # ten seconds of 1/30 s steps straight down
        eye, height = flight.fly(eye, down, flight.speed(height) / 30.0, flat, 2.0)
        assert height >= 2.0 - 1e-9
    # the height falls by half a height per second: 2 km * e^-5 after 10 s
    assert height == pytest.approx(2000.0 * math.exp(-10.0 * flight.SPEED_PER_METRE), rel=0.1)
    for _ in range(900):  # 30 s more: down to the clearance, never under it
        eye, height = flight.fly(eye, down, flight.speed(height) / 30.0, flat, 2.0)
        assert height >= 2.0 - 1e-9
    assert height == pytest.approx(2.0, abs=1e-6)
    # one step far longer than the height: it ends on the clearance, not under
    end, end_height = flight.fly((0.0, 0.0, RADIUS + 50.0), down, 5000.0, flat, 2.0)
    assert end_height == pytest.approx(2.0) and flat(end) == pytest.approx(2.0)


def test_a_low_flight_climbs_over_ridges():
    eye = (0.0, 0.0, RADIUS + 5.0)
    height = 5.0
    lowest = height
    for _ in range(2000):
        eye, height = flight.fly(eye, flight.motion((1.0, 0.0, 0.0), flight.local_up(eye), 1, 0, 0),
                                 20.0, ridged, 2.0)
        lowest = min(lowest, ridged(eye))
    assert lowest >= 2.0 - 1e-9
    assert RADIUS * math.atan2(eye[0], eye[2]) > 20000.0  # it went over ten ridges


def test_look_keeps_the_horizon_defined():
    up = (0.0, 0.0, 1.0)
    forward = flight.look((1.0, 0.0, 0.0), up, math.radians(90.0), 0.0)
    assert forward == pytest.approx((0.0, 1.0, 0.0), abs=1e-12)
    steep = flight.look((1.0, 0.0, 0.0), up, 0.0, math.radians(120.0))
    assert math.degrees(math.asin(steep[2])) == pytest.approx(math.degrees(flight.STEEPEST))
    # straight down: the view's own up gives the heading
    down = flight.look((0.0, 0.0, -1.0), up, 0.0, 0.0, fallback_up=(0.0, 1.0, 0.0))
    assert down[1] > 0.0 and down[2] < -0.99
    right, view_up, back = flight.view_basis(forward, up)
    assert right == pytest.approx((1.0, 0.0, 0.0), abs=1e-12)
    assert view_up == pytest.approx(up, abs=1e-12)
    assert back == pytest.approx((0.0, -1.0, 0.0), abs=1e-12)


def test_motion_combines_the_keys():
    up = (0.0, 0.0, 1.0)
    assert flight.motion((1.0, 0.0, 0.0), up, 0, 0, 0) is None
    assert flight.motion((1.0, 0.0, 0.0), up, 1, 0, 0) == pytest.approx((1.0, 0.0, 0.0))
    way = flight.motion((1.0, 0.0, 0.0), up, 1, 1, 0)
    assert way == pytest.approx((math.sqrt(0.5), -math.sqrt(0.5), 0.0))
    assert flight.motion((1.0, 0.0, 0.0), up, 0, 0, -1) == pytest.approx((0.0, 0.0, -1.0))


def test_bad_input_is_refused():
    with pytest.raises(ValueError):
        flight.fly((0.0, 0.0, RADIUS + 5.0), (1.0, 0.0, 0.0), float("nan"), flat, 2.0)
    with pytest.raises(ValueError):
        flight.fly((0.0, 0.0, RADIUS + 5.0), (1.0, 0.0, 0.0), 1.0, flat, 0.0)
