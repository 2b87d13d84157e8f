"""What the planet's Blender mesh carries per vertex, from a planetlod.Mesh.

bpy-free (numpy when present, plain Python otherwise), so it is tested
without Blender.  From the core's float64 origin, its float32 positions
relative to that origin and its normals:

* positions relative to the planet object's anchor (the floating origin),
  offset in float64 and rounded to float32 once;
* the sea: ground below sea level (within the float32 rounding of the
  core's positions) is lifted onto the sphere of radius
  radius + sea_level, so the sea comes from the same refined sectors as the
  land, meets the coast in shared triangles and never sags below sea level;
  its normal is the sphere's;
* the shading normal `planet_normal`: the core's normal in planet space
  (the same on both sides of a sector border; the sphere's on the sea),
  which the planet material shades with instead of Blender's face-averaged
  normals;
* attributes the materials shade with: `planet_height` (metres above sea
  level, or above the radius without a sea), `planet_sea_depth` (metres of
  water above the ground, 0 on land), `planet_sea` (1 where the ground was
  lifted to the sea surface, else 0), `planet_slope` (degrees between the
  surface normal and the local vertical), `planet_latitude` (degrees),
  `planet_detail` (metres of the core's detail field in the vertex's height:
  ridges and hollows below the height map's resolution; 0 on the sea).
"""
import math
from array import array

try:
    import numpy
except ImportError:  # pragma: no cover - Blender ships numpy
    numpy = None

ATTRIBUTES = ("planet_height", "planet_sea_depth", "planet_sea", "planet_slope",
              "planet_latitude", "planet_detail")


def _detail_of(mesh):
    """The mesh's per-vertex detail buffer (an older native module has none)."""
    detail = getattr(mesh, "detail", None)
    return detail if detail is not None else array("f", bytes(4 * mesh.vertex_count))


class VertexData:
    __slots__ = ("positions", "normals", "attributes")

    def __init__(self, positions, normals, attributes):
        self.positions = positions    # float32 flat buffer, 3 per vertex, relative to anchor
        self.normals = normals        # float32 flat buffer, 3 per vertex (planet_normal)
        self.attributes = attributes  # name -> float32 flat buffer, 1 per vertex


def vertex_data(mesh, anchor, radius, sea_level=None):
    """VertexData of `mesh` for a planet object anchored at `anchor` (planet space)."""
    if mesh.vertex_count == 0:
        return VertexData(array("f"), array("f"), {name: array("f") for name in ATTRIBUTES})
    if numpy is None:
        return _vertex_data_python(mesh, anchor, radius, sea_level)
    origin = numpy.array(tuple(mesh.origin), dtype=numpy.float64)
    pos = numpy.frombuffer(mesh.positions, dtype=numpy.float32).reshape(-1, 3)
    # float32 rounding of the core's positions, relative to its origin: a sea
    # vertex far from the camera reads up to this much above the sea
    tolerance = numpy.abs(pos).max(axis=1).astype(numpy.float64) * 2.0 ** -22 + 1e-3
    pos = pos.astype(numpy.float64) + origin
    normals = numpy.frombuffer(mesh.normals, dtype=numpy.float32).reshape(-1, 3)
    normals = normals.astype(numpy.float64)
    distance = numpy.sqrt(numpy.einsum("ij,ij->i", pos, pos))
    up = pos / distance[:, None]
    height = distance - radius
    depth = numpy.zeros_like(height)
    sea = numpy.zeros_like(height)
    if sea_level is not None:
        below = height <= sea_level + tolerance
        sea[below] = 1.0
        depth[below] = numpy.maximum(sea_level - height[below], 0.0)
        pos[below] = up[below] * (radius + sea_level)
        normals[below] = up[below]
        height = height - sea_level
        height[below] = 0.0
    cos_slope = numpy.clip(numpy.einsum("ij,ij->i", normals, up), -1.0, 1.0)
    slope = numpy.degrees(numpy.arccos(cos_slope))
    latitude = numpy.degrees(numpy.arcsin(numpy.clip(up[:, 2], -1.0, 1.0)))
    detail = numpy.frombuffer(_detail_of(mesh), dtype=numpy.float32).copy()
    detail[sea > 0.0] = 0.0
    local = (pos - numpy.array(anchor, dtype=numpy.float64)).astype(numpy.float32)
    f32 = numpy.float32
    return VertexData(numpy.ascontiguousarray(local).ravel(),
                      numpy.ascontiguousarray(normals.astype(f32)).ravel(),
                      {"planet_height": height.astype(f32),
                       "planet_sea_depth": depth.astype(f32),
                       "planet_sea": sea.astype(f32),
                       "planet_slope": slope.astype(f32),
                       "planet_latitude": latitude.astype(f32),
                       "planet_detail": detail})


def _vertex_data_python(mesh, anchor, radius, sea_level):
    ox, oy, oz = (float(v) for v in mesh.origin)
    ax, ay, az = (float(v) for v in anchor)
    p, n, detail = mesh.positions, mesh.normals, _detail_of(mesh)
    positions, normals = array("f"), array("f")
    columns = {name: array("f") for name in ATTRIBUTES}
    for i in range(mesh.vertex_count):
        tolerance = max(abs(p[3 * i]), abs(p[3 * i + 1]), abs(p[3 * i + 2])) * 2.0 ** -22 + 1e-3
        x, y, z = p[3 * i] + ox, p[3 * i + 1] + oy, p[3 * i + 2] + oz
        nx, ny, nz = n[3 * i], n[3 * i + 1], n[3 * i + 2]
        distance = math.sqrt(x * x + y * y + z * z)
        ux, uy, uz = x / distance, y / distance, z / distance
        height, depth, sea = distance - radius, 0.0, 0.0
        columns["planet_detail"].append(detail[i])
        if sea_level is not None:
            if height <= sea_level + tolerance:
                depth, sea = max(sea_level - height, 0.0), 1.0
                columns["planet_detail"][-1] = 0.0
                x, y, z = (c * (radius + sea_level) for c in (ux, uy, uz))
                nx, ny, nz = ux, uy, uz
                height = sea_level
            height -= sea_level
        positions.extend((x - ax, y - ay, z - az))
        normals.extend((nx, ny, nz))
        cos_slope = max(-1.0, min(1.0, nx * ux + ny * uy + nz * uz))
        columns["planet_height"].append(height)
        columns["planet_sea_depth"].append(depth)
        columns["planet_sea"].append(sea)
        columns["planet_slope"].append(math.degrees(math.acos(cos_slope)))
        columns["planet_latitude"].append(math.degrees(math.asin(max(-1.0, min(1.0, uz)))))
    return VertexData(positions, normals, columns)
