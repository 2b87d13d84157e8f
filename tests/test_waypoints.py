"""planetlod.waypoints: camera paths by longitude, latitude and altitude from
the command line, CSV, GPX and KML; smooth float64 interpolation; terrain
following; frames outside the path refused (bpy-free)."""
import math
import os

import pytest

from planetlod import presets, waypoints
from planetlod.waypoints import Path, PathError, Waypoint, make_waypoint

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EARTH_RADIUS = 6371000.0


def location(pose):
    return tuple(pose[i][3] for i in range(3))


def earth_ground():
    planetlod = pytest.importorskip("planetlod")
    if planetlod.native_error:
        pytest.skip("the C extension is not built: " + planetlod.native_error)
    s = presets.planet_settings("EARTH", lambda name: os.path.join(ROOT, "data", name))
    planet = planetlod.Planet(s["radius"], projection="qsc", heightmap=s["heightmap"],
                              height_scale=s["height_scale"], sea_level=0.0,
                              detail=presets.detail_kwargs(s))
    return lambda d: max(planet.height(*d), 0.0)


def test_two_metres_above_ground_one_centimetre_a_frame_is_smooth():
    """Over Earth's terrain (map and detail), 2 m above the ground, 1 cm a
    frame for 200 frames: each step along the ground is 1 cm within 0.1 mm,
    and the camera's acceleration per frame (the second difference of its
    position, up and down with the terrain included) stays within 0.1 mm."""
    ground = earth_ground()
    lon, lat = 7.25, 45.9  # the Alps
    metres_per_degree = EARTH_RADIUS * math.pi / 180 * math.cos(math.radians(lat))
    end_lon = lon + 2.0 / metres_per_degree
    path = Path([Waypoint(1, lon, lat, 2.0, 90.0, -5.0), Waypoint(201, end_lon, lat, 2.0, 90.0, -5.0)],
                reference="ground", min_clearance=0.5)
    points = [location(path.pose(f, EARTH_RADIUS, ground)) for f in range(1, 202)]
    under = [path.direction(f) for f in range(1, 202)]
    steps = [EARTH_RADIUS * math.dist(a, b) for a, b in zip(under, under[1:])]
    assert max(abs(s - 0.01) for s in steps) < 1e-4, (min(steps), max(steps))
    jitter = [math.dist(tuple(a[i] - 2 * b[i] + c[i] for i in range(3)), (0, 0, 0))
              for a, b, c in zip(points, points[1:], points[2:])]
    assert max(jitter) <= 1e-4, max(jitter)
    # about 2 m above the ground (the followed ground smooths it over ~4 m, so
    # the Alps' metre-scale roughness leaves up to a few decimetres)
    for f in range(1, 202, 10):
        p = location(path.pose(f, EARTH_RADIUS, ground))
        r = math.dist(p, (0, 0, 0))
        assert abs(r - EARTH_RADIUS - ground(tuple(c / r for c in p)) - 2.0) < 0.35


def test_interpolation_great_circle_log_altitude_headings():
    path = Path([Waypoint(1, 0.0, 0.0, 1000.0), Waypoint(101, 90.0, 0.0, 10.0)],
                reference="radius", min_clearance=0.0)
    # along the equator (a great circle) at constant angular speed
    for f in (1, 26, 51, 76, 101):
        lon, lat = waypoints.lon_lat(path.direction(f))
        assert abs(lat) < 1e-12 and abs(lon - 90.0 * (f - 1) / 100) < 1e-9
    # altitude in log space: the geometric mean halfway
    assert abs(path.altitude(51) - 100.0) < 1e-9
    # heading along the track: east
    assert abs(path.heading_pitch(30)[0] - 90.0) < 1e-6
    # headings turn the short way (350 -> 10 passes north, not south)
    turn = Path([Waypoint(1, 0, 0, 5, 350.0, 0), Waypoint(11, 0.001, 0, 5, 10.0, 0)])
    assert abs((turn.heading_pitch(6)[0] + 180) % 360 - 180) < 1e-9
    # velocity continuous through a waypoint (a 90 degree bend): just before
    # and just after frame 11 it is the same vector
    bend = Path([Waypoint(1, 0, 0, 100), Waypoint(11, 0.01, 0, 100), Waypoint(31, 0.01, 0.02, 100)],
                reference="radius")
    h = 1e-4
    d = [bend.direction(f) for f in (11 - h, 11, 11 + h)]
    before = [(b - a) / h for a, b in zip(d[0], d[1])]
    after = [(b - a) / h for a, b in zip(d[1], d[2])]
    assert math.dist(before, after) < 1e-3 * math.dist(before, (0, 0, 0))


def test_frames_outside_the_path_are_refused():
    path = Path([Waypoint(5, 0, 0, 10), Waypoint(9, 1, 0, 10)])
    with pytest.raises(PathError, match=r"frame 10 is outside the path \(frames 5-9\)"):
        path.pose(10, EARTH_RADIUS)
    with pytest.raises(PathError, match="outside the path"):
        path.direction(4)


def test_minimum_clearance():
    path = Path([Waypoint(1, 0, 0, -50.0), Waypoint(3, 0.001, 0, -50.0)], reference="sea",
                min_clearance=3.0)
    r = path.radius_at(2, EARTH_RADIUS, ground_height=lambda d: 120.0)
    assert r == EARTH_RADIUS + 123.0


def test_command_line_and_csv_round_trip(tmp_path):
    w = waypoints.parse_waypoint("12, 7.5, 45.25, 300, 80, -10")
    assert w == Waypoint(12, 7.5, 45.25, 300.0, 80.0, -10.0)
    path = Path([w, waypoints.parse_waypoint("1,7.4,45.2,1e4,60,-30")], "sea", 2.5)
    out = tmp_path / "path.csv"
    waypoints.write_csv(path, str(out))
    again = waypoints.read_path(str(out))
    assert again == path
    assert again.pose(7, EARTH_RADIUS) == path.pose(7, EARTH_RADIUS)


def test_bad_input_errors(tmp_path):
    cases = {
        "no header": ("1,2,3,4\n", "the header has no column frame"),
        "bad number": ("frame,longitude,latitude,altitude\n1,0,0,10\n2,zero,0,10\n",
                       r"line 3: longitude is 'zero', not a number"),
        "latitude": ("frame,longitude,latitude,altitude\n1,0,95,10\n2,0,0,10\n",
                     "latitude 95 is outside"),
        "one point": ("frame,longitude,latitude,altitude\n1,0,0,10\n", "at least 2 waypoints"),
        "same frame": ("frame,longitude,latitude,altitude\n1,0,0,10\n1,1,0,10\n",
                       "two waypoints at frame 1"),
        "columns": ("frame,longitude,latitude,altitude\n1,0,0\n", "3 values for 4 columns"),
        "heading": ("frame,longitude,latitude,altitude,heading\n1,0,0,10,5\n2,1,0,10,\n",
                    "a heading at every waypoint or at none"),
    }
    for label, (text, message) in cases.items():
        with pytest.raises(PathError, match=message):
            waypoints.parse_csv(text, "bad.csv")
    with pytest.raises(PathError, match="waypoint '1,2,3'"):
        waypoints.parse_waypoint("1,2,3")
    with pytest.raises(PathError, match="unknown path file type .txt"):
        (tmp_path / "p.txt").write_text("x")
        waypoints.read_path(str(tmp_path / "p.txt"))
    with pytest.raises(PathError, match="cannot read path file"):
        waypoints.read_path(str(tmp_path / "none.csv"))
    with pytest.raises(PathError, match="not a GPX file"):
        waypoints.parse_gpx("<gpx><trk>", "broken.gpx")
    with pytest.raises(PathError, match=r"point 2: lat is 'north'"):
        waypoints.parse_gpx('<gpx><trk><trkseg><trkpt lat="1" lon="2"/><trkpt lat="north" lon="2"/>'
                            '</trkseg></trk></gpx>', "bad.gpx")
    with pytest.raises(PathError, match="no gx:Tour, gx:Track or LineString"):
        waypoints.parse_kml('<kml xmlns="http://www.opengis.net/kml/2.2"><Document/></kml>')
    with pytest.raises(PathError, match="not a KML file"):
        waypoints.parse_kml("<gpx/>")


GPX = """<?xml version="1.0" encoding="UTF-8"?>
<gpx version="1.1" creator="a phone" xmlns="http://www.topografix.com/GPX/1/1">
 <trk><name>walk</name><trkseg>
  <trkpt lat="46.0000" lon="7.0000"><ele>1500.0</ele><time>2024-06-01T10:00:00Z</time></trkpt>
  <trkpt lat="46.0010" lon="7.0010"><ele>1510.0</ele><time>2024-06-01T10:00:30Z</time></trkpt>
  <trkpt lat="46.0020" lon="7.0030"><ele>1530.0</ele><time>2024-06-01T10:01:30Z</time></trkpt>
 </trkseg></trk>
</gpx>"""

KML_TOUR = """<?xml version="1.0" encoding="UTF-8"?>
<kml xmlns="http://www.opengis.net/kml/2.2" xmlns:gx="http://www.google.com/kml/ext/2.2">
<gx:Tour><name>tour</name><gx:Playlist>
 <gx:FlyTo><gx:duration>0</gx:duration><Camera><longitude>7.0</longitude><latitude>46.0</latitude>
  <altitude>3000</altitude><heading>90</heading><tilt>70</tilt><altitudeMode>absolute</altitudeMode></Camera></gx:FlyTo>
 <gx:FlyTo><gx:duration>4</gx:duration><Camera><longitude>7.1</longitude><latitude>46.0</latitude>
  <altitude>2500</altitude><heading>100</heading><tilt>80</tilt><altitudeMode>absolute</altitudeMode></Camera></gx:FlyTo>
</gx:Playlist></gx:Tour></kml>"""

KML_LINE = """<kml xmlns="http://www.opengis.net/kml/2.2"><Placemark><LineString>
 <altitudeMode>relativeToGround</altitudeMode>
 <coordinates>7.0,46.0,50 7.01,46.0,50 7.02,46.01,80</coordinates></LineString></Placemark></kml>"""


def test_gpx_and_kml_parse():
    gpx = waypoints.parse_gpx(GPX, "walk.gpx", path_frames=91)
    assert gpx.reference == "sea"
    assert [w.frame for w in gpx.waypoints] == [1, 31, 91]  # by the points' times
    assert gpx.waypoints[1].altitude == 1510.0 and gpx.waypoints[1].latitude == 46.001
    tour = waypoints.parse_kml(KML_TOUR, "tour.kml", path_frames=97)
    assert tour.reference == "sea"
    assert [(w.frame, w.heading, w.pitch) for w in tour.waypoints] == [(1, 90.0, -20.0),
                                                                       (97, 100.0, -10.0)]
    line = waypoints.parse_kml(KML_LINE, "line.kml")
    assert line.reference == "ground" and [w.frame for w in line.waypoints] == [1, 2, 3]
    assert line.waypoints[2].altitude == 80.0
