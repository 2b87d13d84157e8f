"""Camera paths of your own: waypoints by longitude, latitude and altitude,
smoothly interpolated in float64 (bpy-free).

A waypoint is (frame, longitude, latitude, altitude[, heading[, pitch]]):
degrees, metres, degrees from north towards east, degrees above the horizon.
The altitude is above the ground (the terrain, or the sea surface where the
sea covers it), the sea level or the sphere of the planet's radius, one
reference for the whole path.  Paths come from the command line
(parse_waypoint), CSV (the format write_csv writes and Record Path saves),
GPX tracks and routes, and KML (LineString, gx:Track, and gx:Tour FlyTo
cameras, as Google Earth exports them).

Interpolation, between waypoints at their frames:
* position: a spherical cubic through the waypoints (Bezier control points
  from each waypoint's velocity, evaluated by slerp, de Casteljau), so the
  camera moves along great circles, with a speed that varies continuously
  through each waypoint (non-uniform Catmull-Rom velocities: the frame gaps
  count); between two waypoints it is the great circle at constant speed;
* altitude: the same cubic in log space when every altitude is above zero
  (a descent from orbit slows down as it nears the ground), else linear;
* heading and pitch: unwrapped (350 -> 10 degrees turns 20 degrees, not
  340), cubic; without headings the camera looks along its track;
* terrain: a path above the ground follows a smooth spline through the
  terrain's heights sampled along it (followed_ground), and stays at least
  `min_clearance` metres over the ground itself at every frame.

A pose outside the path's frames is refused (PathError), never clamped.
"""
import csv
import io
import math
import os
import xml.etree.ElementTree as ET
from datetime import datetime

from . import PlanetLODError
from .flyby import geo_pose

REFERENCES = ("ground", "sea", "radius")
CSV_FIELDS = ("frame", "longitude", "latitude", "altitude", "heading", "pitch")
HEADER_PREFIX = "# planet_lod path:"


class PathError(PlanetLODError, ValueError):
    """A path or path file that cannot be flown (the message says where and why)."""


# ---- vectors on the unit sphere (float64) --------------------------------------

def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _norm(a):
    return math.sqrt(_dot(a, a))


def _scale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


def _add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def direction(longitude, latitude):
    lon, lat = math.radians(longitude), math.radians(latitude)
    return (math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat))


def lon_lat(d):
    return (math.degrees(math.atan2(d[1], d[0])),
            math.degrees(math.atan2(d[2], math.hypot(d[0], d[1]))))


def _log(p, q):
    """The tangent vector at p whose exponential is q (length: the angle)."""
    c = _cross(p, q)
    angle = math.atan2(_norm(c), _dot(p, q))
    along = _sub(q, _scale(p, _dot(p, q)))
    n = _norm(along)
    if n == 0.0:
        return (0.0, 0.0, 0.0)
    return _scale(along, angle / n)


def _exp(p, v):
    angle = _norm(v)
    if angle == 0.0:
        return p
    r = _add(_scale(p, math.cos(angle)), _scale(v, math.sin(angle) / angle))
    return _scale(r, 1.0 / _norm(r))


def _slerp(a, b, t):
    return _exp(a, _scale(_log(a, b), t))


def _project(p, v):
    """v's component in the tangent plane at p."""
    return _sub(v, _scale(p, _dot(p, v)))


# ---- waypoints and paths ---------------------------------------------------------

class Waypoint:
    __slots__ = ("frame", "longitude", "latitude", "altitude", "heading", "pitch")

    def __init__(self, frame, longitude, latitude, altitude, heading=None, pitch=None):
        self.frame, self.longitude, self.latitude = frame, longitude, latitude
        self.altitude, self.heading, self.pitch = altitude, heading, pitch

    def __repr__(self):
        return (f"Waypoint({self.frame}, {self.longitude!r}, {self.latitude!r}, "
                f"{self.altitude!r}, {self.heading!r}, {self.pitch!r})")

    def __eq__(self, other):
        return isinstance(other, Waypoint) and all(
            getattr(self, k) == getattr(other, k) for k in self.__slots__)


def _number(text, what, where, lo=None, hi=None):
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise PathError(f"{where}: {what} is {text!r}, not a number") from None
    if not math.isfinite(value):
        raise PathError(f"{where}: {what} is {text!r}, not a finite number")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise PathError(f"{where}: {what} {value:g} is outside {lo:g} .. {hi:g}")
    return value


def _frame(text, where):
    value = _number(text, "frame", where)
    if value != int(value):
        raise PathError(f"{where}: frame {text!r} is not a whole number")
    return int(value)


def make_waypoint(frame, longitude, latitude, altitude, heading=None, pitch=None,
                  where="waypoint"):
    """A checked Waypoint from numbers or strings ("" or None: not given)."""
    def optional(value, what, lo, hi):
        return None if value in (None, "") else _number(value, what, where, lo, hi)
    return Waypoint(_frame(frame, where), _number(longitude, "longitude", where, -360, 360),
                    _number(latitude, "latitude", where, -90, 90),
                    _number(altitude, "altitude", where, -1e9, 1e12),
                    optional(heading, "heading", -3600, 3600),
                    optional(pitch, "pitch", -90, 90))


def parse_waypoint(text):
    """"FRAME,LON,LAT,ALT[,HEADING[,PITCH]]" (the command line's --waypoint)."""
    parts = [p.strip() for p in text.split(",")]
    if not 4 <= len(parts) <= 6:
        raise PathError(f"waypoint {text!r}: expected FRAME,LONGITUDE,LATITUDE,ALTITUDE"
                        "[,HEADING[,PITCH]]")
    return make_waypoint(*parts, where=f"waypoint {text!r}")


class Path:
    """Waypoints at increasing frames, their altitude reference and the
    minimum clearance over the ground (metres)."""

    def __init__(self, waypoints, reference="ground", min_clearance=0.5):
        waypoints = sorted(waypoints, key=lambda w: w.frame)
        if len(waypoints) < 2:
            raise PathError(f"a path needs at least 2 waypoints, got {len(waypoints)}")
        for a, b in zip(waypoints, waypoints[1:]):
            if a.frame == b.frame:
                raise PathError(f"two waypoints at frame {a.frame}")
        if reference not in REFERENCES:
            raise PathError(f"altitude reference {reference!r}: expected one of "
                            + ", ".join(REFERENCES))
        headings = [w.heading is not None for w in waypoints]
        if any(headings) and not all(headings):
            raise PathError("give a heading at every waypoint or at none "
                            "(none: the camera looks along its track)")
        pitches = [w.pitch is not None for w in waypoints]
        if any(pitches) and not all(pitches):
            raise PathError("give a pitch at every waypoint or at none (none: level)")
        if not (math.isfinite(min_clearance) and min_clearance >= 0):
            raise PathError(f"minimum clearance {min_clearance!r}: expected metres >= 0")
        self.waypoints = waypoints
        self.reference = reference
        self.min_clearance = float(min_clearance)
        self.frames = [w.frame for w in waypoints]
        self._points = [direction(w.longitude, w.latitude) for w in waypoints]
        self._log_altitude = all(w.altitude > 0 for w in waypoints)
        alt = [math.log(w.altitude) if self._log_altitude else w.altitude for w in waypoints]
        self._altitude = alt
        self._heading = _unwrap([w.heading for w in waypoints]) if all(headings) else None
        self._pitch = [w.pitch for w in waypoints] if all(pitches) else None
        self._velocities = self._sphere_velocities()

    @property
    def first(self):
        return self.frames[0]

    @property
    def last(self):
        return self.frames[-1]

    def __eq__(self, other):
        return (isinstance(other, Path) and self.waypoints == other.waypoints
                and self.reference == other.reference
                and self.min_clearance == other.min_clearance)

    def _sphere_velocities(self):
        """Tangent velocity (radians per frame) at each waypoint."""
        p, f = self._points, self.frames
        n = len(p)
        velocities = []
        for i in range(n):
            after = _scale(_log(p[i], p[i + 1]), 1.0 / (f[i + 1] - f[i])) if i + 1 < n else None
            before = _scale(_log(p[i], p[i - 1]), -1.0 / (f[i] - f[i - 1])) if i > 0 else None
            if before is None:
                velocities.append(after)
            elif after is None:
                velocities.append(before)
            else:
                dt0, dt1 = f[i] - f[i - 1], f[i + 1] - f[i]
                velocities.append(_scale(_add(_scale(before, dt1), _scale(after, dt0)),
                                         1.0 / (dt0 + dt1)))
        return velocities

    def _segment(self, frame):
        if not self.first <= frame <= self.last:
            raise PathError(f"frame {frame:g} is outside the path (frames {self.first}-"
                            f"{self.last})")
        i = 0
        while i + 2 < len(self.frames) and frame > self.frames[i + 1]:
            i += 1
        return i, (frame - self.frames[i]) / float(self.frames[i + 1] - self.frames[i])

    def direction(self, frame):
        """Unit vector under the camera at `frame` (float64)."""
        i, t = self._segment(frame)
        dt = self.frames[i + 1] - self.frames[i]
        p0, p3 = self._points[i], self._points[i + 1]
        p1 = _exp(p0, _scale(self._velocities[i], dt / 3.0))
        p2 = _exp(p3, _scale(self._velocities[i + 1], -dt / 3.0))
        a, b, c = _slerp(p0, p1, t), _slerp(p1, p2, t), _slerp(p2, p3, t)
        return _slerp(_slerp(a, b, t), _slerp(b, c, t), t)

    def _cubic(self, values, frame):
        i, t = self._segment(frame)
        return _hermite(values, self.frames, i, t)

    def altitude(self, frame):
        """Altitude above the path's reference at `frame` (before the clearance)."""
        value = self._cubic(self._altitude, frame)
        return math.exp(value) if self._log_altitude else value

    def heading_pitch(self, frame):
        """(heading, pitch) in degrees: interpolated, or along the track."""
        pitch = self._cubic(self._pitch, frame) if self._pitch is not None else 0.0
        if self._heading is not None:
            return self._cubic(self._heading, frame) % 360.0, pitch
        return self.track_heading(frame), pitch

    def track_heading(self, frame):
        """Heading of the path's motion at `frame` (degrees from north to east)."""
        d = self.direction(frame)
        step = 0.25
        ahead = self.direction(min(frame + step, self.last))
        behind = self.direction(max(frame - step, self.first))
        motion = _project(d, _sub(ahead, behind))
        if _norm(motion) < 1e-15:  # not moving: the direction of the next waypoint
            i, _t = self._segment(frame)
            motion = _log(d, self._points[i + 1]) if self._points[i + 1] != d else (0, 0, 0)
        east = _cross((0.0, 0.0, 1.0), d)
        if _norm(east) < 1e-12:
            east = (0.0, 1.0, 0.0)
        east = _scale(east, 1.0 / _norm(east))
        north = _cross(d, east)
        if _norm(motion) == 0.0:
            return 0.0
        return math.degrees(math.atan2(_dot(motion, east), _dot(motion, north))) % 360.0

    def ground_knot_frames(self, radius):
        """Frames between the knots of the followed ground: about twice the
        lowest waypoint's height above the ground (1 m at least) along the
        path, at its mean speed."""
        metres = sum(math.acos(max(-1.0, min(1.0, _dot(a, b))))
                     for a, b in zip(self._points, self._points[1:])) * radius
        per_frame = metres / (self.last - self.first)
        smoothing = max(1.0, 2.0 * min(w.altitude for w in self.waypoints))
        return max(1.0, smoothing / per_frame) if per_frame > 0 else float(self.last - self.first)

    def followed_ground(self, frame, radius, ground_height):
        """The ground the path follows: a uniform cubic B-spline over the
        terrain's heights sampled at knots along the path (ground_knot_frames
        apart, fixed by the path, not by the frames rendered).  The terrain
        itself has creases (map texels, detail) that a camera a few metres up
        would copy as jolts; the spline keeps slopes and drops the creases."""
        k = self.ground_knot_frames(radius)
        u = (frame - self.first) / k
        j = math.floor(u)
        t = u - j

        def sample(i):
            at = min(max(self.first + i * k, self.first), self.last)
            return ground_height(self.direction(at))
        c = [sample(j + m) for m in (-1, 0, 1, 2)]
        t2, t3 = t * t, t * t * t
        return ((1 - t) ** 3 * c[0] + (3 * t3 - 6 * t2 + 4) * c[1]
                + (-3 * t3 + 3 * t2 + 3 * t + 1) * c[2] + t3 * c[3]) / 6.0

    def radius_at(self, frame, radius, ground_height=None, sea_level=0.0):
        """Distance from the planet's centre at `frame` (metres, float64).
        ground_height(direction) -> metres is the terrain (None: the sphere)."""
        d = self.direction(frame)
        ground = ground_height(d) if ground_height is not None else 0.0
        if self.reference == "ground":
            base = self.followed_ground(frame, radius, ground_height) if ground_height else 0.0
        else:
            base = sea_level if self.reference == "sea" else 0.0
        return max(radius + base + self.altitude(frame), radius + ground + self.min_clearance)

    def pose(self, frame, radius, ground_height=None, sea_level=0.0):
        """Row-major 4x4 camera matrix in planet space at `frame` (float64)."""
        d = self.direction(frame)
        longitude, latitude = lon_lat(d)
        heading, pitch = self.heading_pitch(frame)
        r = self.radius_at(frame, radius, ground_height, sea_level)
        return geo_pose(radius, longitude, latitude, altitude=r - radius, heading=heading,
                        pitch=pitch)


def pose_to_waypoint(matrix, radius, frame, base=0.0):
    """The Waypoint of a camera matrix (row-major, planet space, float64):
    its longitude, latitude, altitude above radius + base, heading and pitch
    (roll is not kept).  Path.pose gives the matrix back (Record Path)."""
    location = (matrix[0][3], matrix[1][3], matrix[2][3])
    r = _norm(location)
    if r == 0.0:
        raise PathError("a camera at the planet's centre has no longitude or latitude")
    d = _scale(location, 1.0 / r)
    longitude, latitude = lon_lat(d)
    forward = (-matrix[0][2], -matrix[1][2], -matrix[2][2])
    forward = _scale(forward, 1.0 / _norm(forward))
    east = _cross((0.0, 0.0, 1.0), d)
    if _norm(east) < 1e-12:  # at a pole: geo_pose's east of longitude 0
        east = (0.0, 1.0, 0.0)
    east = _scale(east, 1.0 / _norm(east))
    north = _cross(d, east)
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, _dot(forward, d)))))
    heading = math.degrees(math.atan2(_dot(forward, east), _dot(forward, north))) % 360.0
    return Waypoint(int(frame), longitude, latitude, r - radius - base, heading, pitch)


_saved = {}


def saved_path(text):
    """The Path of CSV text kept on a camera (parsed once per text)."""
    path = _saved.get(text)
    if path is None:
        path = parse_csv(text, "the camera's path")
        if len(_saved) > 16:
            _saved.clear()
        _saved[text] = path
    return path


def _unwrap(angles):
    out = [angles[0]]
    for a in angles[1:]:
        delta = (a - out[-1] + 180.0) % 360.0 - 180.0
        out.append(out[-1] + delta)
    return out


def _hermite(values, frames, i, t):
    """Cubic Hermite between values[i] and values[i+1] with non-uniform
    Catmull-Rom slopes (per frame), at 0 <= t <= 1."""
    def slope(k):
        if k == 0:
            return (values[1] - values[0]) / (frames[1] - frames[0])
        if k == len(values) - 1:
            return (values[k] - values[k - 1]) / (frames[k] - frames[k - 1])
        dt0, dt1 = frames[k] - frames[k - 1], frames[k + 1] - frames[k]
        s0, s1 = (values[k] - values[k - 1]) / dt0, (values[k + 1] - values[k]) / dt1
        return (s0 * dt1 + s1 * dt0) / (dt0 + dt1)
    dt = frames[i + 1] - frames[i]
    m0, m1 = slope(i) * dt, slope(i + 1) * dt
    t2, t3 = t * t, t * t * t
    return ((2 * t3 - 3 * t2 + 1) * values[i] + (t3 - 2 * t2 + t) * m0
            + (-2 * t3 + 3 * t2) * values[i + 1] + (t3 - t2) * m1)


# ---- files -------------------------------------------------------------------------

def write_csv(path_obj, out=None):
    """The path as CSV text (written to the file `out` when given): a comment
    line with the reference and clearance, a header, one row per waypoint."""
    buf = io.StringIO()
    buf.write(f"{HEADER_PREFIX} altitude_reference={path_obj.reference} "
              f"min_clearance={path_obj.min_clearance!r}\n")
    buf.write(",".join(CSV_FIELDS) + "\n")
    for w in path_obj.waypoints:
        cells = [str(w.frame), repr(w.longitude), repr(w.latitude), repr(w.altitude),
                 "" if w.heading is None else repr(w.heading),
                 "" if w.pitch is None else repr(w.pitch)]
        buf.write(",".join(cells) + "\n")
    text = buf.getvalue()
    if out is not None:
        with open(out, "w", encoding="utf-8", newline="") as f:
            f.write(text)
    return text


def parse_csv(text, name="path.csv", reference=None, min_clearance=None):
    """A Path from CSV text (columns frame, longitude, latitude, altitude and
    optionally heading, pitch; '#' lines are comments, the first may carry
    altitude_reference= and min_clearance=).  Arguments given override the
    file's."""
    settings = {}
    rows = []
    for number, line in enumerate(text.splitlines(), 1):
        if line.startswith(HEADER_PREFIX):
            for item in line[len(HEADER_PREFIX):].split():
                key, _, value = item.partition("=")
                settings[key] = value
        if line.strip() and not line.lstrip().startswith("#"):
            rows.append((number, line))
    if not rows:
        raise PathError(f"{name}: no header line and no waypoints")
    reader = csv.reader([line for _n, line in rows])
    header = [h.strip().lower() for h in next(reader)]
    missing = [c for c in CSV_FIELDS[:4] if c not in header]
    if missing:
        raise PathError(f"{name}: line {rows[0][0]}: the header has no column "
                        + ", ".join(missing) + f" (expected {','.join(CSV_FIELDS)})")
    unknown = [c for c in header if c not in CSV_FIELDS]
    if unknown:
        raise PathError(f"{name}: line {rows[0][0]}: unknown column " + ", ".join(unknown))
    waypoints = []
    for (number, _line), cells in zip(rows[1:], reader):
        where = f"{name}: line {number}"
        if len(cells) != len(header):
            raise PathError(f"{where}: {len(cells)} values for {len(header)} columns")
        row = dict(zip(header, (c.strip() for c in cells)))
        waypoints.append(make_waypoint(row["frame"], row["longitude"], row["latitude"],
                                       row["altitude"], row.get("heading"), row.get("pitch"),
                                       where=where))
    if reference is None:
        reference = settings.get("altitude_reference", "ground")
    if min_clearance is None:
        min_clearance = _number(settings.get("min_clearance", "0.5"), "min_clearance", name)
    try:
        return Path(waypoints, reference, min_clearance)
    except PathError as exc:
        raise PathError(f"{name}: {exc}") from None


def _local(tag):
    return tag.rsplit("}", 1)[-1]


def _children(element, name):
    return [e for e in element.iter() if _local(e.tag) == name]


def _time(text, where):
    try:
        return datetime.fromisoformat(text.strip().replace("Z", "+00:00")).timestamp()
    except ValueError:
        raise PathError(f"{where}: time {text!r} is not an ISO 8601 time") from None


def _spread(points, times, first_frame, path_frames, name):
    """Frames for track points: by their times when every point has one, else
    by distance along the track, over first_frame .. first_frame+path_frames-1."""
    if len(points) < 2:
        raise PathError(f"{name}: a track needs at least 2 points, found {len(points)}")
    if all(t is not None for t in times):
        span = [t - times[0] for t in times]
    else:
        span = [0.0]
        for a, b in zip(points, points[1:]):
            span.append(span[-1] + math.acos(max(-1.0, min(1.0, _dot(
                direction(a[0], a[1]), direction(b[0], b[1]))))) + 1e-12)
    if span[-1] <= 0 or any(b < a for a, b in zip(span, span[1:])):
        raise PathError(f"{name}: the track's times do not increase")
    frames = [first_frame + round((path_frames - 1) * s / span[-1]) for s in span]
    keep = [0] + [i for i in range(1, len(frames)) if frames[i] > frames[i - 1]]
    return [(frames[i],) + tuple(points[i]) for i in keep]


def parse_gpx(text, name="track.gpx", path_frames=None, reference="sea", min_clearance=0.5,
              first_frame=1):
    """A Path from a GPX track (trkpt) or route (rtept): <ele> is metres above
    the sea (GPS), altitude 0 without one.  Frames follow the points' <time>
    when all have one, else the distance, over path_frames frames (default:
    one frame per point)."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise PathError(f"{name}: not a GPX file ({exc})") from None
    if _local(root.tag) != "gpx":
        raise PathError(f"{name}: not a GPX file (the root is <{_local(root.tag)}>)")
    points, times = [], []
    elements = _children(root, "trkpt") or _children(root, "rtept")
    for index, pt in enumerate(elements, 1):
        where = f"{name}: point {index}"
        lon = _number(pt.get("lon"), "lon", where, -180, 180)
        lat = _number(pt.get("lat"), "lat", where, -90, 90)
        ele = next((e.text for e in pt if _local(e.tag) == "ele"), None)
        when = next((e.text for e in pt if _local(e.tag) == "time"), None)
        points.append((lon, lat, _number(ele, "ele", where) if ele else 0.0, None, None))
        times.append(_time(when, where) if when else None)
    if not points:
        raise PathError(f"{name}: no track or route points (trkpt, rtept)")
    rows = _spread(points, times, first_frame, path_frames or len(points), name)
    return Path([Waypoint(*row) for row in rows], reference, min_clearance)


_KML_REFERENCE = {"absolute": "sea", "relativetoground": "ground", "clamptoground": "ground",
                  "relativetoseafloor": "ground", "clamptoseafloor": "ground"}


def parse_kml(text, name="path.kml", path_frames=None, min_clearance=0.5, first_frame=1):
    """A Path from KML: a gx:Tour's FlyTo cameras (longitude, latitude,
    altitude, heading, tilt; frames from gx:duration), else the first
    gx:Track or LineString.  altitudeMode absolute: above the sea; the others
    (clampToGround is KML's default): above the ground."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise PathError(f"{name}: not a KML file ({exc})") from None
    if _local(root.tag) != "kml":
        raise PathError(f"{name}: not a KML file (the root is <{_local(root.tag)}>)")

    def mode_of(element):
        found = [e.text.strip().lower() for e in element.iter()
                 if _local(e.tag) == "altitudeMode" and e.text]
        return _KML_REFERENCE.get(found[0] if found else "clamptoground", "ground")

    flytos = _children(root, "FlyTo")
    if flytos:
        points, times, elapsed, modes = [], [], 0.0, set()
        for index, fly in enumerate(flytos, 1):
            where = f"{name}: FlyTo {index}"
            view = next((e for e in fly.iter() if _local(e.tag) in ("Camera", "LookAt")), None)
            if view is None:
                raise PathError(f"{where}: no Camera")
            values = {_local(e.tag): e.text for e in view}
            duration = next((e.text for e in fly if _local(e.tag) == "duration"), "0")
            elapsed += _number(duration, "duration", where, 0, 1e9)
            tilt = _number(values.get("tilt", "0"), "tilt", where, 0, 180)
            points.append((_number(values.get("longitude"), "longitude", where, -180, 180),
                           _number(values.get("latitude"), "latitude", where, -90, 90),
                           _number(values.get("altitude", "0"), "altitude", where),
                           _number(values.get("heading", "0"), "heading", where),
                           max(-90.0, min(90.0, tilt - 90.0))))
            times.append(elapsed)
            modes.add(mode_of(view))
        if len(modes) > 1:
            raise PathError(f"{name}: the tour mixes altitude modes")
        reference = modes.pop()
    else:
        points, times = [], []
        tracks = _children(root, "Track")
        if tracks:
            track = tracks[0]
            coords = [e.text for e in track if _local(e.tag) == "coord"]
            whens = [e.text for e in track if _local(e.tag) == "when"]
            for index, coord in enumerate(coords, 1):
                parts = (coord or "").split()
                if len(parts) < 2:
                    raise PathError(f"{name}: gx:coord {index} is {coord!r}, not 'lon lat alt'")
                where = f"{name}: gx:coord {index}"
                points.append((_number(parts[0], "longitude", where, -180, 180),
                               _number(parts[1], "latitude", where, -90, 90),
                               _number(parts[2], "altitude", where) if len(parts) > 2 else 0.0,
                               None, None))
            times = ([_time(w, f"{name}: when {i}") for i, w in enumerate(whens, 1)]
                     if len(whens) == len(coords) else [None] * len(coords))
            reference = mode_of(track)
        else:
            lines = _children(root, "LineString")
            if not lines:
                raise PathError(f"{name}: no gx:Tour, gx:Track or LineString")
            text_coords = next((e.text for e in lines[0] if _local(e.tag) == "coordinates"), "")
            for index, item in enumerate((text_coords or "").split(), 1):
                parts = item.split(",")
                where = f"{name}: coordinate {index}"
                if len(parts) < 2:
                    raise PathError(f"{where} is {item!r}, not 'lon,lat[,alt]'")
                points.append((_number(parts[0], "longitude", where, -180, 180),
                               _number(parts[1], "latitude", where, -90, 90),
                               _number(parts[2], "altitude", where) if len(parts) > 2 else 0.0,
                               None, None))
            times = [None] * len(points)
            reference = mode_of(lines[0])
    rows = _spread(points, times, first_frame, path_frames or len(points), name)
    return Path([Waypoint(*row) for row in rows], reference, min_clearance)


def read_path(filename, path_frames=None, reference=None, min_clearance=None):
    """A Path from a .csv, .gpx or .kml file (by its extension)."""
    try:
        with open(filename, encoding="utf-8") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise PathError(f"cannot read path file {filename}: {exc}") from None
    name = os.path.basename(filename)
    kind = os.path.splitext(filename)[1].lower()
    clearance = 0.5 if min_clearance is None else min_clearance
    if kind == ".csv":
        return parse_csv(text, name, reference, min_clearance)
    if kind == ".gpx":
        return parse_gpx(text, name, path_frames, reference or "sea", clearance)
    if kind == ".kml":
        path = parse_kml(text, name, path_frames, clearance)
        if reference is not None:
            path = Path(path.waypoints, reference, clearance)
        return path
    raise PathError(f"{name}: unknown path file type {kind or '(none)'}: use .csv, .gpx or .kml")
