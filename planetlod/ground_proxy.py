"""A coarse stand-in for a planet's ground, for tools that read a viewport's
depth buffer or cast rays at real meshes (a GPU-drawn preview feeds neither).

The mesh covers the whole planet around a viewer: rings of vertices around
the point below the eye, spaced geometrically (each ring a fixed fraction
farther out than the last, as many segments around), so its cells grow with
their distance from the eye and it stays a few thousand triangles from any
height.  It lies at or just below the ground, so a surface drawn at the true
ground passes the depth test over it: each vertex takes the lowest of the
heights sampled around it at twice the density, less a tenth of their
spread (relief a coarse cell can hide) and less a thousandth of its
distance from the eye (a few pixels' worth of the preview's own error).

numpy required (it runs where the GPU preview runs)."""
import math

SEGMENTS = 32        # vertices around each ring
RELIEF_SINK = 0.1    # of the heights' spread around a vertex
DISTANCE_SINK = 1e-3  # of the distance from the eye


def _basis(up):
    """Two unit vectors perpendicular to the unit `up` and to each other."""
    ax = min(range(3), key=lambda i: abs(up[i]))
    axis = [0.0, 0.0, 0.0]
    axis[ax] = 1.0
    e1 = [up[1] * axis[2] - up[2] * axis[1], up[2] * axis[0] - up[0] * axis[2],
          up[0] * axis[1] - up[1] * axis[0]]
    n = math.sqrt(sum(c * c for c in e1))
    e1 = [c / n for c in e1]
    e2 = [up[1] * e1[2] - up[2] * e1[1], up[2] * e1[0] - up[0] * e1[2],
          up[0] * e1[1] - up[1] * e1[0]]
    return e1, e2


def ring_angles(radius, altitude, segments=SEGMENTS):
    """Angles (radians from the point below the eye) of the rings: the first a
    quarter of the altitude's arc out, each next one 2 pi / segments farther
    in proportion, the last short of the antipode."""
    import numpy
    # (at most a quarter radian: from far away a few rings cover the planet)
    first = min(max(altitude, 1.0) * 0.25 / radius, 0.25)
    ratio = 1.0 + 2.0 * math.pi / segments
    count = max(int(math.ceil(math.log(math.pi / first) / math.log(ratio))), 2)
    angles = first * ratio ** numpy.arange(count, dtype=numpy.float64)
    return angles[angles < math.pi * (1.0 - 0.5 / segments)]


def proxy_mesh(surface, radius, eye, anchor=(0.0, 0.0, 0.0), sea_level=None,
               segments=SEGMENTS):
    """(positions, triangles) of the stand-in around planet-space `eye`:
    positions float32 (n, 3) relative to `anchor`, triangles int32 (m, 3)
    wound counter-clockwise seen from outside.  `surface(directions)` is a
    planet's surface() (heights in metres above `radius` for 3 n floats)."""
    import numpy
    eye = numpy.asarray(eye, dtype=numpy.float64)
    distance = float(numpy.linalg.norm(eye))
    up = eye / distance if distance > 1e-9 else numpy.array([0.0, 0.0, 1.0])
    e1, e2 = (numpy.array(v) for v in _basis(list(up)))
    nadir = numpy.frombuffer(surface(list(up))[0], dtype=numpy.float64)[0]
    altitude = max(distance - radius - nadir, 1.0)
    angles = ring_angles(radius, altitude, segments)
    # the sample grid: twice as dense in both directions, from the nadir to
    # the antipode (rows), around the ring (columns)
    half = math.sqrt(1.0 + 2.0 * math.pi / segments)
    fine_rings = numpy.concatenate(([0.0], numpy.repeat(angles, 2)
                                    * numpy.tile([1.0, half], len(angles)), [math.pi]))
    fine_rings = numpy.minimum(fine_rings, math.pi)
    phi = numpy.arange(2 * segments) * (math.pi / segments)
    theta = fine_rings[:, None]
    dirs = (numpy.cos(theta)[..., None] * up
            + numpy.sin(theta)[..., None] * (numpy.cos(phi)[None, :, None] * e1
                                             + numpy.sin(phi)[None, :, None] * e2))
    heights = numpy.frombuffer(surface(dirs.reshape(-1).tolist())[0], dtype=numpy.float64)
    heights = heights.reshape(len(fine_rings), 2 * segments)
    if sea_level is not None:
        heights = numpy.maximum(heights, sea_level)
    # lowest and highest over each sample's 3 x 3 neighbours (wrapping around the ring)
    padded = numpy.concatenate((heights[:1], heights, heights[-1:]))
    stack = [numpy.roll(padded[1 + dr:len(padded) - 1 + dr], dc, axis=1)
             for dr in (-1, 0, 1) for dc in (-1, 0, 1)]
    low, high = numpy.min(stack, axis=0), numpy.max(stack, axis=0)
    ground = low - RELIEF_SINK * (high - low)
    # the proxy's vertices: the nadir, every other fine ring and column, the antipode
    rows = [0] + list(range(1, len(fine_rings) - 1, 2)) + [len(fine_rings) - 1]
    cols = numpy.arange(0, 2 * segments, 2)
    points = []
    for k, row in enumerate(rows):
        take = [0] if k in (0, len(rows) - 1) else cols
        r = radius + ground[row, take]
        points.append(dirs[row, take] * r[:, None])
    points = numpy.concatenate(points)
    lengths = numpy.linalg.norm(points, axis=1)
    # (at most a hundredth of the radius: seen from far away the sink would
    # otherwise pass the centre of a small body)
    sink = numpy.minimum(DISTANCE_SINK * numpy.linalg.norm(points - eye, axis=1),
                         0.01 * lengths)
    points *= ((lengths - sink) / lengths)[:, None]
    positions = (points - numpy.asarray(anchor, dtype=numpy.float64)).astype(numpy.float32)
    return positions, _triangles(len(rows) - 2, segments)


def _triangles(rings, segments):
    """Triangles of the nadir (vertex 0), `rings` rings of `segments` and the
    antipode (last vertex), counter-clockwise from outside."""
    import numpy
    s = numpy.arange(segments)
    nxt = (s + 1) % segments
    tris = [numpy.stack((numpy.zeros(segments, dtype=numpy.int64), 1 + s, 1 + nxt), axis=1)]
    for k in range(rings - 1):
        a, b = 1 + k * segments, 1 + (k + 1) * segments
        tris.append(numpy.stack((a + s, b + s, b + nxt), axis=1))
        tris.append(numpy.stack((a + s, b + nxt, a + nxt), axis=1))
    last = 1 + rings * segments
    a = 1 + (rings - 1) * segments
    tris.append(numpy.stack((a + s, numpy.full(segments, last), a + nxt), axis=1))
    return numpy.concatenate(tris).astype(numpy.int32)
