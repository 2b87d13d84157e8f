"""The recorded camera path of the camera-path benchmark (chapter 6 of
K. Gasiński's master's thesis, Gdańsk University of Technology, 2010: an 80 s
animation replayed frame by frame).

The path lives in bench/camera_path.csv as keyframes
    t_s, dir_x, dir_y, dir_z, altitude_m, fwd_x, fwd_y, fwd_z, segment
(camera position = unit direction * (R + altitude), planet space, z = north
pole, x = lon 0; forward = world-space gaze).  Replay interpolates linearly
between keyframes: direction and gaze are lerped then normalised, the altitude
is lerped in log space (linear in log-altitude, so a descent over five decades
needs few keys).  Up = the local vertical.  Blender camera conventions
(looks down -Z, +Y up).

    /usr/bin/python3 -m bench.camera_path --write   # re-record the CSV

Segments: approach from space (60,000 km -> 800 km), orbit over both poles
(a full great circle along lon 0 / 180 at 800 km, gaze 30 deg below the
horizon), descent (800 km -> 300 m above the terrain, towards Kilimanjaro),
skim (300 m above the terrain, heading east).  The skim altitude was recorded
from the Earth topology map (QSC, 8848 m scale) + 300 m.
"""
import csv
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))
PATH_CSV = os.path.join(HERE, "camera_path.csv")
R_EARTH = 6371000.0
DURATION_S = 80.0


def _norm(v):
    n = math.sqrt(sum(c * c for c in v))
    return tuple(c / n for c in v)


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dir(lat_deg, lon_deg):
    la, lo = math.radians(lat_deg), math.radians(lon_deg)
    return (math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la))


def load(path=PATH_CSV):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    keys = []
    for r in rows:
        keys.append((float(r["t_s"]), (float(r["dir_x"]), float(r["dir_y"]), float(r["dir_z"])),
                     float(r["altitude_m"]), (float(r["fwd_x"]), float(r["fwd_y"]),
                                              float(r["fwd_z"])), r["segment"]))
    return keys


def look_matrix(location, forward, up_hint):
    """Row-major 4x4 (Blender camera: looks down -Z, +Y up)."""
    f = _norm(forward)
    right = _cross(f, up_hint)
    if sum(c * c for c in right) < 1e-20:
        right = _cross(f, (1.0, 0.0, 0.0) if abs(f[0]) < 0.9 else (0.0, 1.0, 0.0))
    right = _norm(right)
    up = _cross(right, f)
    return [[right[0], up[0], -f[0], location[0]], [right[1], up[1], -f[1], location[1]],
            [right[2], up[2], -f[2], location[2]], [0.0, 0.0, 0.0, 1.0]]


def pose(keys, t, radius=R_EARTH):
    """(matrix 4x4 row-major, altitude_m, segment) at time t (seconds)."""
    t = min(max(t, keys[0][0]), keys[-1][0])
    i = 0
    while i + 2 < len(keys) and keys[i + 1][0] <= t:
        i += 1
    t0, d0, a0, f0, seg0 = keys[i]
    t1, d1, a1, f1, seg1 = keys[i + 1]
    s = 0.0 if t1 == t0 else (t - t0) / (t1 - t0)
    d = _norm(tuple(x + s * (y - x) for x, y in zip(d0, d1)))
    fw = _norm(tuple(x + s * (y - x) for x, y in zip(f0, f1)))
    alt = math.exp(math.log(a0) + s * (math.log(a1) - math.log(a0)))
    loc = tuple(c * (radius + alt) for c in d)
    # an interval belongs to the segment of the key it leads to (the turn from
    # the approach into the orbit is orbit, the first leg down is descent)
    return look_matrix(loc, fw, d), alt, (seg0 if t1 == t0 else seg1)


def frames(count, keys=None, radius=R_EARTH):
    """count poses evenly spread over the path: [(t, matrix, altitude, segment)]."""
    keys = keys or load()
    t_end = keys[-1][0]
    out = []
    for k in range(count):
        t = t_end * k / max(1, count - 1)
        m, alt, seg = pose(keys, t, radius)
        out.append((t, m, alt, seg))
    return out


def record(ground=None):
    """Builds the keyframes. ground(dir) -> terrain height in metres (skim)."""
    rows = []

    def add(t, d, alt, fwd, seg):
        rows.append((t, d, alt, _norm(fwd), seg))

    # approach from space over (0N, 0E), looking at the centre
    d0 = _dir(0.0, 0.0)
    for t, alt in ((0.0, 6.0e7), (4.0, 1.5e7), (8.0, 4.0e6), (12.0, 8.0e5)):
        add(t, d0, alt, tuple(-c for c in d0), "approach")
    # orbit over both poles: great circle through lon 0 and lon 180, 800 km,
    # gaze along the track pitched 30 deg below the local horizontal
    pitch = math.radians(30.0)
    steps = 24
    for k in range(steps + 1):
        a = 2.0 * math.pi * k / steps
        d = (math.cos(a), 0.0, math.sin(a))
        tangent = (-math.sin(a), 0.0, math.cos(a))
        fwd = tuple(math.cos(pitch) * tv - math.sin(pitch) * dv for tv, dv in zip(tangent, d))
        if k == 0:
            # turn from the approach gaze to the orbit gaze at 800 km
            add(14.0, d, 8.0e5, fwd, "orbit")
            continue
        add(14.0 + 36.0 * k / steps, d, 8.0e5, fwd, "orbit")
    # descent: from (0N, 0E) eastwards/south to (-3.0N, 33.0E), 800 km -> ground + 300 m
    lat_end, lon_end = -3.0, 33.0
    descent_keys = 8
    g_end = ground(_dir(lat_end, lon_end)) if ground else 1200.0
    for k in range(1, descent_keys + 1):
        s = k / descent_keys
        lat, lon = lat_end * s, lon_end * s
        d = _dir(lat, lon)
        alt = math.exp(math.log(8.0e5) * (1 - s) + math.log(g_end + 300.0) * s)
        east = _norm(_cross((0.0, 0.0, 1.0), d))
        p = math.radians(30.0 - 22.0 * s)
        fwd = tuple(math.cos(p) * e - math.sin(p) * dv for e, dv in zip(east, d))
        add(50.0 + 15.0 * s, d, alt, fwd, "descent")
    # skim: 300 m above the terrain, east along 3S towards Kilimanjaro (37.35E)
    skim_keys = 15
    for k in range(1, skim_keys + 1):
        lon = lon_end + 3.5 * k / skim_keys
        d = _dir(lat_end, lon)
        # the highest ground around this key (also between keys) + 300 m
        g = max(ground(_dir(lat_end, lon + dl)) for dl in (-0.15, -0.08, 0.0, 0.08, 0.15)) \
            if ground else 1200.0
        east = _norm(_cross((0.0, 0.0, 1.0), d))
        p = math.radians(8.0)
        fwd = tuple(math.cos(p) * e - math.sin(p) * dv for e, dv in zip(east, d))
        add(65.0 + 15.0 * k / skim_keys, d, g + 300.0, fwd, "skim")
    return rows


def write(rows, path=PATH_CSV):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s", "dir_x", "dir_y", "dir_z", "altitude_m", "fwd_x", "fwd_y", "fwd_z",
                    "segment"])
        for t, d, alt, fwd, seg in rows:
            w.writerow([f"{t:.3f}"] + [f"{c:.9f}" for c in d] + [f"{alt:.1f}"]
                       + [f"{c:.9f}" for c in fwd] + [seg])


if __name__ == "__main__":
    import planetlod
    earth = planetlod.Planet(R_EARTH, projection="qsc",
                             heightmap=os.path.join(os.path.dirname(HERE), "data",
                                                    "earth-topology.png"),
                             height_scale=8848.0, sea_level=0.0)
    write(record(lambda d: earth.height(*d)))
    print("wrote", PATH_CSV, len(load()), "keyframes")
