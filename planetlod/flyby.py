"""Camera and object poses, pure functions of their arguments.

The flyby path is a function of (frame, path_frames, radius, heights):
rendering any sub-range of a path gives exactly the cameras of the full run
(farm splits).  geo_pose places an object by longitude, latitude and
altitude.  Matrices are row-major 4x4 tuples in planet space (float64)."""
import math

ORBIT_END = 0.4
DESCENT_END = 0.75
# share of the descent over which the gaze turns from the planet's centre to
# the horizon: the rest of the descent keeps the horizon and the sky in view
GAZE_TURN = 0.3
# The flyby's sun (a sun lamp's XYZ Euler rotation and strength): afternoon
# light from the south-west, about 40 degrees up over the orbit and the
# descent and 25-30 over the skim, low enough for the relief to show
FLYBY_SUN_ROTATION = (1.914, 0.0, 2.314)
FLYBY_SUN_STRENGTH = 4.0


def _normalise(v):
    n = math.sqrt(sum(c * c for c in v))
    return tuple(c / n for c in v)


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _smooth(t):
    t = min(max(t, 0.0), 1.0)
    return t * t * (3 - 2 * t)


def look_matrix(location, forward, up_hint):
    """Row-major 4x4 camera matrix (Blender camera looks down -Z, +Y up)."""
    f = _normalise(forward)
    right = _cross(f, up_hint)
    if sum(c * c for c in right) < 1e-20:
        right = _cross(f, (1.0, 0.0, 0.0) if abs(f[0]) < 0.9 else (0.0, 1.0, 0.0))
    right = _normalise(right)
    up = _cross(right, f)
    z = tuple(-c for c in f)
    return ((right[0], up[0], z[0], location[0]),
            (right[1], up[1], z[1], location[1]),
            (right[2], up[2], z[2], location[2]),
            (0.0, 0.0, 0.0, 1.0))


def flyby_pose(frame, path_frames, radius, skim_height=5.0, ground_height=None,
               orbit_distance=3.0):
    """Camera matrix (planet space, row-major 4x4) at `frame` of a `path_frames` path.

    orbit (camera at orbit_distance*radius circling over 60 degrees of longitude,
    looking at the centre) -> descent (altitude falls exponentially to
    skim_height; the gaze turns to just below the horizon early on, so the
    ground comes down to meet a sky) -> skim (skim_height metres above
    the ground, flying east).  ground_height(dir) -> metres gives the terrain
    under the camera (None: the bare sphere)."""
    t = 0.0 if path_frames <= 1 else (frame - 1) / float(path_frames - 1)
    t = min(max(t, 0.0), 1.0)
    lon0, lat = math.radians(10.0), math.radians(20.0)
    lon = lon0 + math.radians(60.0) * (t / ORBIT_END if t < ORBIT_END else 1.0)
    if t > ORBIT_END:  # keep moving east along the descent and the skim
        lon += math.radians(25.0) * _smooth((t - ORBIT_END) / (1.0 - ORBIT_END))
        lon += (t - DESCENT_END) / (1 - DESCENT_END) * 2000.0 / radius if t > DESCENT_END else 0.0
    direction = (math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat))
    east = (-math.sin(lon), math.cos(lon), 0.0)
    north = _cross(direction, east)
    top = (orbit_distance - 1.0) * radius
    ground = ground_height(direction) if ground_height else 0.0
    if t <= ORBIT_END:
        altitude = top
        tilt = 0.0
    elif t <= DESCENT_END:
        s = _smooth((t - ORBIT_END) / (DESCENT_END - ORBIT_END))
        altitude = math.exp(math.log(top) * (1 - s) + math.log(skim_height) * s)
        tilt = _smooth(s / GAZE_TURN)
    else:
        altitude = skim_height
        tilt = 1.0
    r = radius + ground + altitude
    location = tuple(c * r for c in direction)
    # gaze: centre (tilt 0) -> a little below the horizon, heading east (tilt 1)
    down = tuple(-c for c in direction)
    horizon_dip = math.acos(min(1.0, radius / r)) + math.radians(8.0)
    ahead = tuple(math.cos(horizon_dip) * e + math.sin(horizon_dip) * d
                  for e, d in zip(east, down))
    forward = _normalise(tuple((1 - tilt) * d + tilt * a for d, a in zip(down, ahead)))
    return look_matrix(location, forward, north if tilt < 0.5 else direction)


def geo_pose(radius, longitude, latitude, east=0.0, north=0.0, altitude=0.0, heading=0.0,
             pitch=0.0, roll=0.0, base_height=None):
    """Row-major 4x4 matrix (planet space, float64) of an object placed on a planet.

    longitude/latitude (degrees) pick a point; east/north (metres, along the
    surface) move from it, so a float32 property animated in metres keeps
    millimetre steps where degrees would not (1e-7 degrees is 1 cm).  The
    object is `altitude` metres above base_height(direction) (None: the
    sphere of `radius`).  heading (degrees from north towards east), pitch
    (degrees above the horizon) and roll (degrees about the view direction)
    turn its -Z axis (a camera's view) and +Y (its up)."""
    lon, lat = math.radians(longitude), math.radians(latitude)
    p0 = (math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat))
    east0 = (-math.sin(lon), math.cos(lon), 0.0)
    north0 = _cross(p0, east0)
    distance = math.hypot(east, north)
    if distance > 0.0:
        tangent = tuple((east * e + north * n) / distance for e, n in zip(east0, north0))
        angle = distance / radius
        up = _normalise(tuple(math.cos(angle) * p + math.sin(angle) * t
                              for p, t in zip(p0, tangent)))
    else:
        up = p0
    east_axis = _cross((0.0, 0.0, 1.0), up)
    if sum(c * c for c in east_axis) < 1e-24:  # at a pole: keep the start's east
        east_axis = east0
    east_axis = _normalise(east_axis)
    north_axis = _cross(up, east_axis)
    r = radius + (base_height(up) if base_height else 0.0) + altitude
    location = tuple(c * r for c in up)
    h, p, q = math.radians(heading), math.radians(pitch), math.radians(roll)
    level = tuple(math.cos(h) * n + math.sin(h) * e for n, e in zip(north_axis, east_axis))
    right = tuple(math.cos(h) * e - math.sin(h) * n for n, e in zip(north_axis, east_axis))
    forward = tuple(math.cos(p) * l + math.sin(p) * u for l, u in zip(level, up))
    cam_up = _cross(right, forward)
    right, cam_up = (tuple(math.cos(q) * r_ + math.sin(q) * u_ for r_, u_ in zip(right, cam_up)),
                     tuple(-math.sin(q) * r_ + math.cos(q) * u_ for r_, u_ in zip(right, cam_up)))
    z = tuple(-c for c in forward)
    return ((right[0], cam_up[0], z[0], location[0]),
            (right[1], cam_up[1], z[1], location[1]),
            (right[2], cam_up[2], z[2], location[2]),
            (0.0, 0.0, 0.0, 1.0))
