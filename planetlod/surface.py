"""What the planet's Blender mesh carries per vertex, from a planetlod.Mesh.

bpy-free (numpy, which Blender ships), so it is tested
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
from array import array

import numpy

# The core's shading normal, object space (a POINT FLOAT_VECTOR attribute).
NORMAL_ATTRIBUTE = "planet_normal"
ATTRIBUTES = ("planet_height", "planet_sea_depth", "planet_sea", "planet_slope",
              "planet_latitude", "planet_detail")


class VertexData:
    __slots__ = ("positions", "normals", "attributes")

    def __init__(self, positions, normals, attributes):
        self.positions = positions    # float32 flat buffer, 3 per vertex, relative to anchor
        self.normals = normals        # float32 flat buffer, 3 per vertex (planet_normal)
        self.attributes = attributes  # name -> float32 flat buffer, 1 per vertex


def _planet_space(rel, origin):
    """float64 planet-space positions of the core's float32 positions `rel`
    (relative to `origin`), their distance from the centre, and how far the
    float32 rounding may put each above its true height (a sea vertex far
    from the camera reads up to this much above the sea)."""
    tolerance = numpy.abs(rel).max(axis=1).astype(numpy.float64) * 2.0 ** -22 + 1e-3
    pos = rel.astype(numpy.float64) + origin
    return pos, numpy.sqrt(numpy.einsum("ij,ij->i", pos, pos)), tolerance


def _ground(mesh, radius, sea_level):
    """The positions (float64, planet space) and normals of `mesh` with the sea
    lifted, and per vertex: the unit up, the height (above sea level, or the
    radius without a sea), the water depth and the sea flag (numpy arrays)."""
    origin = numpy.array(tuple(mesh.origin), dtype=numpy.float64)
    rel = numpy.frombuffer(mesh.positions, dtype=numpy.float32).reshape(-1, 3)
    pos, distance, tolerance = _planet_space(rel, origin)
    normals = numpy.frombuffer(mesh.normals, dtype=numpy.float32).reshape(-1, 3)
    normals = normals.astype(numpy.float64)
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
    return pos, normals, up, height, depth, sea


def _relative(pos, anchor):
    """float64 planet-space positions relative to `anchor`, rounded to float32 once."""
    local = (pos - numpy.array(anchor, dtype=numpy.float64)).astype(numpy.float32)
    return numpy.ascontiguousarray(local).ravel()


def vertex_data(mesh, anchor, radius, sea_level=None):
    """VertexData of `mesh` for a planet object anchored at `anchor` (planet space)."""
    if mesh.vertex_count == 0:
        return VertexData(array("f"), array("f"), {name: array("f") for name in ATTRIBUTES})
    pos, normals, up, height, depth, sea = _ground(mesh, radius, sea_level)
    cos_slope = numpy.clip(numpy.einsum("ij,ij->i", normals, up), -1.0, 1.0)
    slope = numpy.degrees(numpy.arccos(cos_slope))
    latitude = numpy.degrees(numpy.arcsin(numpy.clip(up[:, 2], -1.0, 1.0)))
    detail = numpy.frombuffer(mesh.detail, dtype=numpy.float32).copy()
    detail[sea > 0.0] = 0.0
    f32 = numpy.float32
    return VertexData(_relative(pos, anchor),
                      numpy.ascontiguousarray(normals.astype(f32)).ravel(),
                      {"planet_height": height.astype(f32),
                       "planet_sea_depth": depth.astype(f32),
                       "planet_sea": sea.astype(f32),
                       "planet_slope": slope.astype(f32),
                       "planet_latitude": latitude.astype(f32),
                       "planet_detail": detail})


class PreviewData:
    """What the GPU preview draws of a planetlod.Mesh: the surface the planet's
    Blender mesh gets (positions relative to the anchor with the sea lifted,
    the core's normals), as one float32 array of two RGBA texels per vertex
    for a data texture `row_texels` wide (padded to whole rows):
    (x, y, z, height above sea level) and (normal x, y, z, 4 * sector level +
    2 * sea flag + 1 + crest), crest the detail field's height in units of
    its amplitude (the render material's `planet_detail` / amplitude: its
    ridges and hollows), clamped to -1..0.98, 0 on the sea and without
    detail.  Every sector is one copy of the template:
    `template_triangles` index its `vertices_per_sector` vertices.

    The sectors sit in `sector_count` slots, `slot_ids` naming each slot's
    sector (0: a free slot, all zeros: it draws nothing), so that
    preview_update can replace only what changed.  `serial` is the planet's
    mesh-cache emission count after the mesh it was made from (None: not
    from a cached mesh); preview_update needs it to be current.  `whole`: one
    slot holding a whole mesh (the LOD methods other than HRTMR), whose
    triangles change with every preview."""
    __slots__ = ("texels", "row_texels", "vertex_count", "sector_count",
                 "vertices_per_sector", "template_triangles", "slot_ids", "serial", "whole")

    def __init__(self, texels, row_texels, vertex_count, sector_count, template_triangles,
                 slot_ids=None, serial=None, whole=False):
        self.texels = texels          # (rows * row_texels, 4)
        self.row_texels = row_texels
        self.vertex_count = vertex_count
        self.sector_count = sector_count
        self.vertices_per_sector = vertex_count // max(sector_count, 1)
        self.template_triangles = template_triangles  # (t, 3) int32
        self.slot_ids = (numpy.zeros(sector_count, dtype=numpy.uint64) if slot_ids is None
                         else slot_ids)
        self.serial = serial
        self.whole = whole

    @property
    def sectors(self):
        """Sectors held (slots in use)."""
        return int(numpy.count_nonzero(self.slot_ids))

    @property
    def positions(self):
        return self.texels[0:2 * self.vertex_count:2, :3]

    @property
    def normals(self):
        return self.texels[1:2 * self.vertex_count:2, :3]

    @property
    def heights(self):
        return self.texels[0:2 * self.vertex_count:2, 3]

    @property
    def sea(self):
        return numpy.floor_divide(numpy.mod(self.texels[1:2 * self.vertex_count:2, 3], 4.0), 2.0)

    @property
    def levels(self):
        return numpy.floor_divide(self.texels[1:2 * self.vertex_count:2, 3], 4.0)

    @property
    def crest(self):
        return numpy.mod(self.texels[1:2 * self.vertex_count:2, 3], 2.0) - 1.0


PREVIEW_ROW_TEXELS = 4096  # even: a vertex's two texels share a row


def preview_data(mesh, anchor, radius, sea_level=None, row_texels=PREVIEW_ROW_TEXELS,
                 whole=False, detail_amplitude=None):
    """PreviewData of `mesh` (numpy required: the GPU preview runs in Blender).
    whole: the mesh is not copies of one template (the LOD methods other than
    HRTMR): it is drawn as a single patch, each vertex with the finest level of
    its triangles.  detail_amplitude: the planet's detail amplitude (metres),
    the unit of the crests (None or 0: no crests).
    Float32 where that is exact enough for a picture (heights for colours,
    to a few metres), float64 where vertex_data uses it for a decision: a
    vertex near or below the sea is lifted exactly as the render mesh's is."""
    f32 = numpy.float32
    n = mesh.vertex_count
    texels = _texel_rows(2 * n, row_texels)
    if n == 0:
        return PreviewData(texels, row_texels, 0, 0, numpy.zeros((0, 3), dtype=numpy.int32))
    vertex = texels[:2 * n].reshape(n, 2, 4)
    origin = numpy.array(tuple(mesh.origin), dtype=numpy.float64)
    anchor = numpy.array(anchor, dtype=numpy.float64)
    rel = numpy.frombuffer(mesh.positions, dtype=f32).reshape(-1, 3)
    numpy.add(rel, (origin - anchor).astype(f32), out=vertex[:, 0, :3])
    vertex[:, 1, :3] = numpy.frombuffer(mesh.normals, dtype=f32).reshape(-1, 3)
    planet = rel + origin.astype(f32)
    height = numpy.sqrt(numpy.einsum("ij,ij->i", planet, planet)) - f32(radius)
    sea = numpy.zeros(n, dtype=f32)
    if sea_level is not None:
        # float32 planet-space heights are off by a few float32 steps of the
        # radius; the vertices within a margin of that are redone in float64
        margin = radius * 2.0 ** -18 + 1.0
        near = numpy.flatnonzero(height <= sea_level + margin)
        if near.size:
            pos, distance, tolerance = _planet_space(rel[near], origin)
            below = (distance - radius) <= sea_level + tolerance
            lifted = near[below]
            up = pos[below] / distance[below, None]
            vertex[lifted, 0, :3] = up * (radius + sea_level) - anchor
            vertex[lifted, 1, :3] = up
            sea[lifted] = 1.0
        height -= f32(sea_level)
        height[sea > 0.0] = 0.0
    # sea flag and crest code in one float: 2 * sea + 1 + crest
    code = sea * f32(2.0) + f32(1.0)
    if detail_amplitude:
        crest = numpy.frombuffer(mesh.detail, dtype=f32) * f32(1.0 / detail_amplitude)
        code += numpy.where(sea > 0.0, f32(0.0), numpy.clip(crest, -1.0, 0.98))
    if whole:
        triangles = numpy.frombuffer(mesh.triangles, dtype=numpy.int32).reshape(-1, 3)
        levels = numpy.zeros(n, dtype=numpy.int32)
        face_levels = numpy.frombuffer(mesh.sector_level, dtype=numpy.int32)
        for corner in range(3):
            numpy.maximum.at(levels, triangles[:, corner], face_levels)
        vertex[:, 0, 3] = height
        vertex[:, 1, 3] = levels.astype(f32) * 4.0 + code
        return PreviewData(texels, row_texels, n, 1, triangles.copy(),
                           numpy.ones(1, dtype=numpy.uint64), whole=True)
    sectors = mesh.sector_count
    tris_per_sector = mesh.triangle_count // sectors
    # the first sector's triangles index vertices 0..vertices_per_sector-1
    template = numpy.frombuffer(mesh.triangles, dtype=numpy.int32)[:3 * tris_per_sector]
    levels = numpy.frombuffer(mesh.sector_level, dtype=numpy.int32)[::tris_per_sector]
    vertex[:, 0, 3] = height
    vertex[:, 1, 3] = numpy.repeat(levels.astype(f32) * 4.0, n // sectors) + code
    ids = getattr(mesh, "sector_ids", None)
    ids = (numpy.frombuffer(ids, dtype=numpy.uint64).copy() if ids is not None
           else numpy.zeros(sectors, dtype=numpy.uint64))
    return PreviewData(texels, row_texels, n, sectors, template.reshape(-1, 3).copy(), ids)


def preview_update(previous, mesh, visible_ids, anchor, radius, sea_level=None,
                   detail_amplitude=None):
    """The PreviewData of the planet's visible sectors `visible_ids` (numpy
    uint64) from `previous` and `mesh`, a planet.mesh(changed_only=True)
    emitted after the mesh `previous` was made from, with the same anchor,
    radius, sea level and template: the sectors that left the view free
    their slots, the emitted ones are written into theirs (new ones into
    free slots), the rest is kept.  `previous` is not changed (the viewport
    may be drawing it).  When fewer than half the slots would stay in use,
    the kept sectors and the emitted ones are packed into new slots."""
    fresh = preview_data(mesh, anchor, radius, sea_level, previous.row_texels,
                         detail_amplitude=detail_amplitude)
    if previous.sector_count == 0:
        return fresh
    vps = previous.vertices_per_sector
    if mesh.sector_count and fresh.vertices_per_sector != vps:
        raise ValueError("preview_update: another template than the preview's")
    per_slot = 2 * vps
    emitted = fresh.slot_ids
    fresh_slots = fresh.texels[:len(emitted) * per_slot].reshape(len(emitted), per_slot, 4)
    old_slots = previous.texels[:previous.sector_count * per_slot].reshape(-1, per_slot, 4)
    slot_ids = previous.slot_ids
    staying = (slot_ids != 0) & numpy.isin(slot_ids, visible_ids)
    if previous.sector_count > 64 and 2 * len(visible_ids) < previous.sector_count:
        kept = numpy.flatnonzero(staying & ~numpy.isin(slot_ids, emitted))
        slots = len(kept) + len(emitted)
        texels = _texel_rows(slots * per_slot, previous.row_texels)
        by_slot = texels[:slots * per_slot].reshape(slots, per_slot, 4)
        by_slot[:len(kept)] = old_slots[kept]
        by_slot[len(kept):] = fresh_slots
        slot_ids = numpy.concatenate([slot_ids[kept], emitted])
        return PreviewData(texels, previous.row_texels, slots * vps, slots,
                           previous.template_triangles, slot_ids)
    leaving = numpy.flatnonzero((slot_ids != 0) & ~staying)
    slot_ids = slot_ids.copy()
    slot_ids[leaving] = 0
    # the emitted sectors' slots: their own, else free ones, else new ones
    order = numpy.argsort(slot_ids, kind="stable")
    at = numpy.minimum(numpy.searchsorted(slot_ids, emitted, sorter=order), len(order) - 1)
    own = order[at]
    found = slot_ids[own] == emitted
    target = numpy.where(found, own, -1)
    missing = numpy.flatnonzero(~found)
    free = numpy.flatnonzero(slot_ids == 0)
    take = min(len(free), len(missing))
    target[missing[:take]] = free[:take]
    grow = len(missing) - take
    slots = len(slot_ids) + grow
    target[missing[take:]] = numpy.arange(len(slot_ids), slots)
    texels = _texel_rows(slots * per_slot, previous.row_texels, previous.texels)
    by_slot = texels[:slots * per_slot].reshape(slots, per_slot, 4)
    by_slot[leaving] = 0.0
    by_slot[target] = fresh_slots
    slot_ids = numpy.concatenate([slot_ids, numpy.zeros(grow, dtype=numpy.uint64)])
    slot_ids[target] = emitted
    return PreviewData(texels, previous.row_texels, slots * vps, slots,
                       previous.template_triangles, slot_ids)


def _texel_rows(count, row_texels, start=None):
    """Whole rows for `count` texels, zero past them: the caller fills them,
    after the copy of `start` (as much of it as fits) they begin with."""
    rows = max((count + row_texels - 1) // row_texels, 1)
    texels = numpy.empty((rows * row_texels, 4), dtype=numpy.float32)
    if start is not None:
        kept = min(len(start), count)
        texels[:kept] = start[:kept]
    texels[count:] = 0.0
    return texels
