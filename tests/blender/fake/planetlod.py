"""Pure-Python stand-in for the `planetlod` C module (tests and development only).

Implements the subset of cext/API.md the add-on uses, with simple geometry:
12 root triangles on the cube, 4-way splits by a pixel-error criterion, back-
face culling, zero heights.  It lets the add-on's Blender tests run before the
C stages land; select it with PLANET_LOD_NATIVE=<this folder>.  Never shipped.
"""
import math
import os
from array import array

PROJECTIONS = ("tsc", "csc", "qsc", "spherified", "car")
FAKE = True


class PlanetLODError(Exception):
    pass


class InvalidArgument(PlanetLODError, ValueError):
    pass


class FileError(PlanetLODError, OSError):
    pass


class ImageError(PlanetLODError, ValueError):
    pass


class Cancelled(PlanetLODError):
    pass


def _norm(v):
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return (v[0] / n, v[1] / n, v[2] / n)


def _mid(a, b):
    return _norm((a[0] + b[0], a[1] + b[1], a[2] + b[2]))


def _dist(a, b):
    return math.sqrt(sum((a[i] - b[i]) ** 2 for i in range(3)))


class Camera:
    def __init__(self, matrix_world, type="PERSP", lens=50.0, sensor_width=36.0,
                 sensor_height=24.0, sensor_fit="AUTO", ortho_scale=7.0, shift_x=0.0,
                 shift_y=0.0, clip_start=0.1, clip_end=1000.0, resolution_x=1920,
                 resolution_y=1080, pixel_aspect_x=1.0, pixel_aspect_y=1.0):
        rows = [list(r) for r in matrix_world] if not isinstance(matrix_world[0], (int, float)) \
            else [list(matrix_world[i * 4:i * 4 + 4]) for i in range(4)]
        if lens <= 0 or resolution_x <= 0 or resolution_y <= 0 or not all(
                math.isfinite(x) for r in rows for x in r):
            raise InvalidArgument("bad camera")
        self.position = (rows[0][3], rows[1][3], rows[2][3])
        self.forward = _norm((-rows[0][2], -rows[1][2], -rows[2][2]))
        self.type = type
        self.scale = resolution_x * lens / sensor_width
        self.clip_start, self.clip_end = clip_start, clip_end


class Planet:
    def __init__(self, radius, projection="qsc", heightmap=None, height_scale=1.0,
                 sea_level=None, heightmap_size=None):
        if not (1.0 <= radius <= 1e8):
            raise InvalidArgument("radius out of range [1, 1e8]")
        if projection not in PROJECTIONS:
            raise InvalidArgument("unknown projection %r" % (projection,))
        if isinstance(heightmap, str):
            if not os.path.isfile(heightmap):
                raise FileError("cannot open height map %r" % heightmap)
            if os.path.getsize(heightmap) == 0:
                raise ImageError("empty image %r" % heightmap)
        self.radius = float(radius)
        self.projection = projection
        self.height_scale = height_scale
        self.reset()

    def reset(self):
        c = [(-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1),
             (-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1)]
        c = [_norm(p) for p in c]
        quads = [(0, 1, 2, 3), (4, 7, 6, 5), (0, 4, 5, 1), (1, 5, 6, 2), (2, 6, 7, 3), (3, 7, 4, 0)]
        self._roots = []
        for q in quads:
            self._roots.append((c[q[0]], c[q[1]], c[q[2]]))
            self._roots.append((c[q[0]], c[q[2]], c[q[3]]))
        self._visible = []
        self._total = 12

    @property
    def sector_count(self):
        return self._total

    @property
    def visible_count(self):
        return len(self._visible)

    def refine(self, camera, criterion="pixel", max_pixel_error=1.0, split_border=0.5,
               merge_border=0.25, hysteresis=False, template_level=4, max_level=48,
               budget=0, backface=True, frustum=True, skip_sea=False):
        import heapq
        r = self.radius
        cam = camera.position
        cam_len = math.sqrt(sum(c * c for c in cam))
        cam_dir = _norm(cam) if cam_len > 0 else (0.0, 0.0, 1.0)
        horizon = math.acos(min(1.0, r / cam_len)) if cam_len > r else math.pi

        def angle(a, b):
            return math.acos(max(-1.0, min(1.0, sum(a[i] * b[i] for i in range(3)))))

        def facing(tri):
            centre = _norm(tuple(sum(t[i] for t in tri) for i in range(3)))
            radius = max(angle(centre, t) for t in tri)
            return angle(centre, cam_dir) - radius < horizon + 0.01

        def error(tri):
            centre = _norm(tuple(sum(t[i] for t in tri) for i in range(3)))
            edge = _dist(tri[0], tri[1]) * r
            d = max(_dist(tuple(x * r for x in centre), cam) - edge, 1e-3)
            if criterion == "pixel":
                return edge / (2 ** template_level) * camera.scale / d / max_pixel_error
            return edge / d / split_border

        heap = [(-error(t), i, t, 0, i) for i, t in enumerate(self._roots)]
        heapq.heapify(heap)
        leaves = []
        splits = 0
        counter = len(heap)
        while heap:
            neg_err, _, tri, level, sid = heapq.heappop(heap)
            room = not budget or len(leaves) + len(heap) + 3 <= budget
            if -neg_err > 1.0 and level < min(max_level, 24) and room and (
                    not backface or facing(tri)):
                a, b, c = tri
                ab, bc, ca = _mid(a, b), _mid(b, c), _mid(c, a)
                splits += 1
                for k, child in enumerate(((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))):
                    counter += 1
                    heapq.heappush(heap, (-error(child), counter, child, level + 1, sid * 4 + k))
            else:
                leaves.append((tri, level, sid))
        total = len(leaves)
        if backface:
            leaves = [l for l in leaves if facing(l[0])]
        after_back = len(leaves)
        self._visible = sorted(leaves, key=lambda l: (l[1], l[2]))
        self._total = total
        self._cam = cam
        return {"sectors_total": total, "sectors_after_backface": after_back,
                "sectors_after_frustum": after_back, "sectors_after_budget": after_back,
                "sectors_sea_skipped": 0, "splits": splits, "merges": 0, "refine_us": 0,
                "cull_us": 0, "max_level": max((l[1] for l in leaves), default=0)}

    def sector_levels(self, visible_only=True):
        return array("i", [l[1] for l in self._visible])

    def sector_ids(self, visible_only=True):
        return array("Q", [l[2] for l in self._visible])

    def recommended_clip(self, camera):
        h = max(_dist(camera.position, (0, 0, 0)) - self.radius, 1.0)
        far = math.sqrt(h * (2 * self.radius + h)) * 1.1 + self.radius * 0.01
        return (max(h * 0.01, 0.01), far)

    def height(self, x, y, z):
        return 0.0

    def height_range(self):
        return (0.0, 0.0)

    def _template(self, level):
        n = 2 ** level
        idx = {}
        bary = array("f")
        for i in range(n + 1):
            for j in range(n + 1 - i):
                idx[(i, j)] = len(bary) // 3
                bary.extend(((n - i - j) / n, i / n, j / n))
        tris = array("i")
        for i in range(n):
            for j in range(n - i):
                tris.extend((idx[(i, j)], idx[(i + 1, j)], idx[(i, j + 1)]))
                if i + j < n - 1:
                    tris.extend((idx[(i + 1, j)], idx[(i + 1, j + 1)], idx[(i, j + 1)]))
        return bary, tris

    def mesh(self, template_level=None, morph=False, threads=2, visible_only=True):
        level = 2 if template_level is None else template_level
        bary, tris = self._template(level)
        vt = len(bary) // 3
        r = self.radius
        cam = getattr(self, "_cam", (0, 0, r * 3))
        o = _norm(cam)
        origin = (o[0] * r, o[1] * r, o[2] * r)
        m = _Mesh()
        m.origin = origin
        for s, (tri, lvl, sid) in enumerate(self._visible):
            base = s * vt
            u0 = None
            for k in range(vt):
                w = bary[3 * k:3 * k + 3]
                d = _norm(tuple(w[0] * tri[0][i] + w[1] * tri[1][i] + w[2] * tri[2][i] for i in range(3)))
                m.positions.extend((d[0] * r - origin[0], d[1] * r - origin[1], d[2] * r - origin[2]))
                m.normals.extend(d)
                u = math.atan2(d[1], d[0]) / (2 * math.pi) + 0.5
                if u0 is None:
                    u0 = u
                u += round(u0 - u)
                m.uv.extend((u, math.asin(max(-1.0, min(1.0, d[2]))) / math.pi + 0.5))
                m.morph.append(0.0)
            for t in tris:
                m.triangles.append(base + t)
            m.sector_level.extend([lvl] * (len(tris) // 3))
            m.face.extend([sid % 6] * (len(tris) // 3))
        m.vertex_count = len(m.positions) // 3
        m.triangle_count = len(m.triangles) // 3
        return m

    def instances(self, template_level=None):
        level = 2 if template_level is None else template_level
        bary, tris = self._template(level)
        corners = array("f")
        for tri, lvl, sid in self._visible:
            for c in tri:
                corners.extend(c)
        return {"template_barycentrics": bary, "template_triangles": tris, "corners": corners,
                "levels": array("f", [l[1] for l in self._visible]),
                "morph": array("f", [0.0] * len(self._visible)), "origin": (0.0, 0.0, 0.0)}


class _Mesh:
    def __init__(self):
        self.positions, self.normals, self.uv = array("f"), array("f"), array("f")
        self.triangles, self.sector_level, self.face = array("i"), array("i"), array("i")
        self.morph = array("f")


class CubeMap:
    def __init__(self, *a, **k):
        raise ImageError("the fake planetlod has no cube maps")

    @staticmethod
    def from_image(path, **kwargs):
        if not os.path.isfile(path):
            raise FileError("cannot open %r" % path)
        raise ImageError("the fake planetlod has no cube maps")
