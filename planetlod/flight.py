"""Flying over a planet at a pace that follows the altitude.

The speed is a fixed share of the height above the ground per second, so the
ground below slides across the view at the same angular rate from 2 m as
from 2 km, and a dive slows down as the ground comes near.  The eye never
ends a step below a clearance above the ground: where the way would go under
it, the eye is lifted along the local up (flying into a hillside climbs over
it).

Points and directions are planet-space float64 3-tuples (the planet's
centre at the origin); the ground is given as a callable returning a
point's height above the ground in metres, negative underground, that
depends on the point's distance from the centre only through that distance
(moving a point out along its own direction by d raises it by d)."""
import math

# Metres per second for each metre above the ground (from 2 km: 1 km/s;
# from 2 m: a metre a second, a walk).
SPEED_PER_METRE = 0.5
# Speed factors of the wheel (a step each notch), Shift (fast) and Alt (slow).
FACTOR_STEP = 1.25
FACTOR_RANGE = (1.0 / 64.0, 64.0)
FAST = 4.0
SLOW = 0.25
# A tick moves at most this long: a redraw stalled for seconds does not
# throw the eye far at once.
LONGEST_TICK_S = 0.1
# Mouse look: radians per pixel, and how close to straight up or down the
# view may turn (the horizon stays defined).
TURN_PER_PIXEL = 0.004
STEEPEST = math.radians(89.0)


def speed(height, factor=1.0, clearance=2.0):
    """Metres per second at `height` metres above the ground (at least the
    speed at the clearance, so the eye still moves on the ground)."""
    return SPEED_PER_METRE * factor * max(height, clearance)


def scaled_factor(factor, notches):
    """The speed factor after `notches` wheel steps (positive: faster), within FACTOR_RANGE."""
    low, high = FACTOR_RANGE
    return min(max(factor * FACTOR_STEP ** notches, low), high)


def _add(a, b, s=1.0):
    return (a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2])


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _unit(a):
    length = math.sqrt(_dot(a, a))
    if not length > 0.0:
        raise ValueError("a direction of zero length")
    return (a[0] / length, a[1] / length, a[2] / length)


def local_up(point):
    """The planet's local up at a planet-space point."""
    return _unit(point)


def lift(point, height, clearance):
    """`point` (`height` m above the ground) moved out along its local up to
    `clearance` above the ground when it is lower; else unchanged."""
    if height >= clearance:
        return point, height
    return _add(point, local_up(point), clearance - height), clearance


def fly(eye, direction, distance, height_above, clearance):
    """(new eye, its height above the ground): `eye` moved `distance` metres
    along the unit `direction`, in pieces no longer than a quarter of the
    height above the ground where each begins (so the way cannot skip
    through a slope gentler than about 76 degrees), each piece's end lifted
    to `clearance` above the ground where it would be lower."""
    if distance < 0.0 or not math.isfinite(distance):
        raise ValueError(f"distance must be finite and not negative, not {distance}")
    if clearance <= 0.0:
        raise ValueError(f"clearance must be above 0 m, not {clearance}")
    point, height = lift(eye, height_above(eye), clearance)
    left = distance
    for _ in range(10000):
        if left <= 0.0:
            break
        piece = min(left, 0.25 * max(height, clearance))
        point = _add(point, direction, piece)
        point, height = lift(point, height_above(point), clearance)
        left -= piece
    return point, height


def look(forward, up, yaw, pitch, fallback_up=None):
    """The unit view direction `forward` turned by `yaw` radians about the
    planet's local `up` (positive: to the left) and by `pitch` radians
    towards it, never closer to straight up or down than STEEPEST.  A view
    looking straight along `up` turns from `fallback_up` (the view's own up)."""
    f, u = _unit(forward), _unit(up)
    along = _dot(f, u)
    flat = _add(f, u, -along)
    if _dot(flat, flat) < 1e-12:
        source = fallback_up if fallback_up is not None else (1.0, 0.0, 0.0)
        flat = _add(source, u, -_dot(source, u))
        if along > 0.0:
            flat = (-flat[0], -flat[1], -flat[2])
        if _dot(flat, flat) < 1e-12:
            flat = _cross(u, (1.0, 0.0, 0.0) if abs(u[0]) < 0.9 else (0.0, 1.0, 0.0))
    flat = _unit(flat)
    elevation = math.asin(max(-1.0, min(1.0, along)))
    elevation = max(-STEEPEST, min(STEEPEST, elevation + pitch))
    # Rodrigues about up (flat is perpendicular to it)
    side = _cross(u, flat)
    c, s = math.cos(yaw), math.sin(yaw)
    flat = _add((flat[0] * c, flat[1] * c, flat[2] * c), side, s)
    return _unit(_add((flat[0] * math.cos(elevation), flat[1] * math.cos(elevation),
                       flat[2] * math.cos(elevation)), u, math.sin(elevation)))


def view_basis(forward, up):
    """(right, view up, backward): the columns of a view's rotation that looks
    along `forward` with its horizon level (its up in the plane of `up`)."""
    f = _unit(forward)
    right = _unit(_cross(f, up))
    return right, _cross(right, f), (-f[0], -f[1], -f[2])


def motion(forward, up, ahead, aside, rise):
    """The unit direction of a move `ahead` along the view (-1, 0, 1), `aside`
    to the right of it and `rise` along the local up; None when they cancel."""
    right = _unit(_cross(_unit(forward), up))
    way = _add(_add((forward[0] * ahead, forward[1] * ahead, forward[2] * ahead), right, aside),
               up, rise)
    if _dot(way, way) < 1e-12:
        return None
    return _unit(way)
