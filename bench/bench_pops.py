"""Pops along camera paths: how far the surface jumps on screen from one frame
to the next.

    /usr/bin/python3 -m bench.bench_pops [--paths descent,walk,dive,flyby]
        [--frames N] [--range FIRST:LAST] [--every N | --at F1,F2] [--morph on,off]
        [--template-level 4] [--plot bench/results/pops.png]

For each frame f of a path, frame f's camera looks at two surfaces: the mesh
refined and emitted for frame f-1's camera and the one for frame f's.  Every
vertex of either mesh in frame f's view is matched with the point of the
other mesh on the same ray from the planet's centre (the other mesh's
triangle there, interpolated); the pair's screen distance in frame f's
pixels is the geometric change, and the interpolated normal, slope (angle of
the normal from the local vertical) and planet_detail are compared with the
vertex's own.  A vertex kept unchanged scores 0; a split's new vertex scores
how far it stands from the parent's triangle; a detail band switching with
the eye scores its height change.  Vertices in front of the camera and inside
the image count (occlusion is ignored, so hidden jumps count too); those at
the image's border and the horizon (the silhouette) are included.

Paths (Earth preset with its detail field, refined as renders refine):
  descent  bench_refine.py's 240-frame descent (20,000 km to 2 m over
           Everest, 1920x1080, 50 mm)
  walk     2 m above the ground near Everest, moving 1 cm a frame east,
           looking 10 degrees down (960x540, 35 mm)
  dive     from 20 km above the ground near Everest, losing 1 % of the
           altitude a frame, looking 20 degrees down (1920x1080, 50 mm)
  flyby    the README flyby's 48 frames (orbit, descent, skim; 640x360,
           50 mm): much faster per frame than the others
"""
import argparse
import math
import os
import sys
import time

import numpy as np

import planetlod
from bench.bench_refine import descent
from planetlod import presets
from planetlod.flyby import flyby_pose, geo_pose

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

EVEREST_LON, EVEREST_LAT = 86.925, 27.988
PATHS = ("descent", "walk", "dive", "flyby")


def data_path(name):
    for folder in (os.path.join(ROOT, "data"), os.path.join(os.path.dirname(ROOT), "shared", "data")):
        path = os.path.join(folder, name)
        if os.path.exists(path):
            return path
    raise FileNotFoundError(name)


def earth(detail=True):
    """The Earth preset as renders build it (height map, sea, detail field)."""
    s = presets.planet_settings("EARTH", data_path)
    kwargs = dict(projection=s["projection"].lower(), height_scale=float(s["height_scale"]))
    if s["heightmap"]:
        kwargs["heightmap"] = s["heightmap"]
    if s.get("use_sea_level"):
        kwargs["sea_level"] = float(s["sea_level"])
    if detail:
        kwargs["detail"] = presets.detail_kwargs(s)
    return planetlod.Planet(float(s["radius"]), **kwargs)


def camera(planet, matrix, width, height, lens):
    cam = planetlod.Camera(matrix, lens=lens, sensor_width=36.0, resolution_x=width,
                           resolution_y=height, clip_start=0.01, clip_end=1e12)
    near, far = planet.recommended_clip(cam)
    return planetlod.Camera(matrix, lens=lens, sensor_width=36.0, resolution_x=width,
                            resolution_y=height, clip_start=near, clip_end=far)


def path_cameras(planet, name, frames=None):
    """(label, [(matrix, width, height, lens), ...]) of path `name`."""
    radius = planet.radius
    if name == "descent":
        top = planet.height_range()[1]
        n = frames or 240
        return [(m, 1920, 1080, 50.0) for _alt, m in descent(n, terrain_top=top, radius=radius)]
    if name == "walk":
        n = frames or 48
        base = surface_height(planet)
        return [(geo_pose(radius, EVEREST_LON, EVEREST_LAT, east=0.01 * k - 1500.0, altitude=2.0,
                          heading=90.0, pitch=-10.0, base_height=base), 960, 540, 35.0)
                for k in range(n)]
    if name == "dive":
        n = frames or 240
        base = surface_height(planet)
        return [(geo_pose(radius, EVEREST_LON, EVEREST_LAT, east=-20000.0 + 40.0 * k,
                          altitude=20000.0 * 0.99 ** k, heading=90.0, pitch=-20.0,
                          base_height=base), 1920, 1080, 50.0) for k in range(n)]
    if name == "flyby":
        n = frames or 48
        base = surface_height(planet)
        return [(flyby_pose(k + 1, n, radius, ground_height=base), 640, 360, 50.0)
                for k in range(n)]
    raise ValueError(f"unknown path {name!r}: one of {', '.join(PATHS)}")


def surface_height(planet):
    """base_height(direction) -> metres of the planet's surface (every detail
    octave; the sea where it is higher), as the add-on's geo placement uses."""
    sea = planet.sea_level
    if sea is None:
        return lambda d: planet.height(*d)
    return lambda d: max(planet.height(*d), sea)


# ---- meshes and matching ------------------------------------------------------

class Surface:
    """One emitted mesh in planet space (float64) with its attributes."""

    def __init__(self, mesh):
        origin = np.asarray(mesh.origin, dtype=np.float64)
        self.positions = np.frombuffer(mesh.positions, dtype=np.float32).reshape(-1, 3) \
            .astype(np.float64) + origin
        self.normals = np.frombuffer(mesh.normals, dtype=np.float32).reshape(-1, 3) \
            .astype(np.float64)
        self.detail = np.frombuffer(mesh.detail, dtype=np.float32).astype(np.float64)
        self.triangles = np.frombuffer(mesh.triangles, dtype=np.int32).reshape(-1, 3)
        up = self.positions / np.linalg.norm(self.positions, axis=1)[:, None]
        self.slope = angle_deg(self.normals, up)
        self.ids = np.frombuffer(mesh.sector_ids, dtype=np.uint64)
        self.per_sector = len(self.positions) // max(len(self.ids), 1)
        self.triangles_per_sector = len(self.triangles) // max(len(self.ids), 1)
        self._tree = None
        self._tree_of = None

    def vertex_rows(self, sectors):
        """Vertex indices of the sectors at positions `sectors` (in order)."""
        return (sectors[:, None] * self.per_sector + np.arange(self.per_sector)).ravel()

    def triangle_rows(self, sectors):
        return (sectors[:, None] * self.triangles_per_sector
                + np.arange(self.triangles_per_sector)).ravel()

    def hit(self, directions, sectors, candidates=16):
        """Per unit direction: the point of this mesh's sectors `sectors` (their
        positions in the emission) on the ray from the centre, its
        interpolated normal, detail and slope, and whether one was found."""
        from scipy.spatial import cKDTree
        q = directions
        candidate_triangles = self.triangles[self.triangle_rows(sectors)]
        if not len(q) or not len(candidate_triangles):
            z = np.zeros((len(q), 3))
            return z, z, np.zeros(len(q)), np.zeros(len(q)), np.zeros(len(q), dtype=bool)
        c = self.positions[candidate_triangles].mean(axis=1)
        tree = cKDTree(c / np.linalg.norm(c, axis=1)[:, None])
        k = min(candidates, len(candidate_triangles))
        _, idx = tree.query(q, k=k)
        idx = idx.reshape(len(q), k)
        tri = candidate_triangles[idx]                            # (Q, k, 3)
        p0, p1, p2 = (self.positions[tri[..., c]] for c in range(3))
        e1, e2 = p1 - p0, p2 - p0
        d = q[:, None, :]
        pv = np.cross(d, e2)
        det = np.sum(e1 * pv, axis=-1)
        ok = np.abs(det) > 0
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tv = -p0  # the ray starts at the centre
        u = np.sum(tv * pv, axis=-1) * inv
        qv = np.cross(tv, e1)
        v = np.sum(d * qv, axis=-1) * inv
        t = np.sum(e2 * qv, axis=-1) * inv
        eps = 1e-7
        inside = ok & (u >= -eps) & (v >= -eps) & (u + v <= 1 + eps) & (t > 0)
        found = inside.any(axis=1)
        first = np.argmax(inside, axis=1)
        rows = np.arange(len(q))
        u, v, t = u[rows, first], v[rows, first], t[rows, first]
        tri = tri[rows, first]
        w = np.stack([1 - u - v, u, v], axis=1)
        point = q * t[:, None]
        normal = np.einsum("qc,qcx->qx", w, self.normals[tri])
        normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-30)[:, None]
        detail = np.einsum("qc,qc->q", w, self.detail[tri])
        slope = angle_deg(normal, q)
        return point, normal, detail, slope, found

    def sector_centres(self):
        c = self.positions.reshape(len(self.ids), self.per_sector, 3).mean(axis=1)
        return c / np.linalg.norm(c, axis=1)[:, None]

    def near_sectors(self, directions, count=8):
        """Positions of the sectors whose centres are nearest the directions."""
        from scipy.spatial import cKDTree
        _, idx = cKDTree(self.sector_centres()).query(directions, k=min(count, len(self.ids)))
        return np.unique(idx)


class View:
    """Frame f's camera: planet space -> pixels."""

    def __init__(self, matrix, width, height, lens, sensor=36.0):
        m = np.asarray(matrix, dtype=np.float64)
        self.rotation = m[:3, :3]
        self.location = m[:3, 3]
        self.width, self.height = width, height
        self.focal_px = lens / sensor * width

    def project(self, points):
        local = (points - self.location) @ self.rotation  # camera axes: x right, y up, -z ahead
        depth = -local[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = self.width / 2 + self.focal_px * local[:, 0] / depth
            y = self.height / 2 - self.focal_px * local[:, 1] / depth
        return np.stack([x, y], axis=1), depth

    def visible(self, points):
        xy, depth = self.project(points)
        return (depth > 0) & (xy[:, 0] >= 0) & (xy[:, 0] <= self.width) & \
            (xy[:, 1] >= 0) & (xy[:, 1] <= self.height)


def angle_deg(a, b):
    """Angles between unit vectors, exact near 0 (arccos of a float32 dot is not)."""
    a = a / np.maximum(np.linalg.norm(a, axis=1), 1e-30)[:, None]
    b = b / np.maximum(np.linalg.norm(b, axis=1), 1e-30)[:, None]
    half = np.clip(np.linalg.norm(a - b, axis=1) / 2.0, 0.0, 1.0)
    return np.degrees(2.0 * np.arcsin(half))


def compare(view, before, after, chunk=200000):
    """Per-vertex changes between two surfaces seen by `view`.  A sector in
    both (same id) compares vertex for vertex; the vertices of a sector in
    one only are matched along their rays with the other's sectors that are
    not in the first (a split's children with their parent, and back)."""
    pixels, normal, detail, slope, distance, missing = [], [], [], [], [], 0
    common, in_after, in_before = np.intersect1d(after.ids, before.ids, assume_unique=True,
                                                 return_indices=True)
    if len(common):
        va, vb = after.vertex_rows(in_after), before.vertex_rows(in_before)
        for s in range(0, len(va), chunk):
            a_rows, b_rows = va[s:s + chunk], vb[s:s + chunk]
            pa, pb = after.positions[a_rows], before.positions[b_rows]
            keep = view.visible(pa) | view.visible(pb)
            a, _ = view.project(pa[keep])
            b, _ = view.project(pb[keep])
            pixels.append(np.linalg.norm(a - b, axis=1))
            distance.append(np.linalg.norm(pa[keep] - view.location, axis=1))
            normal.append(angle_deg(after.normals[a_rows][keep], before.normals[b_rows][keep]))
            detail.append(np.abs(after.detail[a_rows][keep] - before.detail[b_rows][keep]))
            slope.append(np.abs(after.slope[a_rows][keep] - before.slope[b_rows][keep]))
    for mine, other, mine_common, other_common in ((after, before, in_after, in_before),
                                                   (before, after, in_before, in_after)):
        own = np.setdiff1d(np.arange(len(mine.ids)), mine_common)
        others = np.setdiff1d(np.arange(len(other.ids)), other_common)
        if not len(own):
            continue
        rows = mine.vertex_rows(own)
        p = mine.positions[rows]
        keep = view.visible(p)
        rows, p = rows[keep], p[keep]
        if not len(p):
            continue
        q = p / np.linalg.norm(p, axis=1)[:, None]
        point, n, dt, sl, found = other.hit(q, others)
        if not found.all():  # on an edge shared with a sector both surfaces hold
            lost = ~found
            retry = other.hit(q[lost], other.near_sectors(q[lost]))
            for whole, part in zip((point, n, dt, sl, found), retry):
                whole[lost] = part
        missing += int((~found).sum())
        a, _ = view.project(p[found])
        b, _ = view.project(point[found])
        pixels.append(np.linalg.norm(a - b, axis=1))
        distance.append(np.linalg.norm(p[found] - view.location, axis=1))
        normal.append(angle_deg(mine.normals[rows][found], n[found]))
        detail.append(np.abs(mine.detail[rows][found] - dt[found]))
        slope.append(np.abs(mine.slope[rows][found] - sl[found]))
    cat = (lambda xs: np.concatenate(xs) if xs else np.zeros(0))
    return dict(pixels=cat(pixels), normal_deg=cat(normal), detail_m=cat(detail),
                slope_deg=cat(slope), distance_m=cat(distance), missing=missing)


def stats_of(change):
    px = change["pixels"]
    if not len(px):
        return dict(max_px=0.0, p99_px=0.0, normal_p99=0.0, normal_max=0.0, detail_max=0.0,
                    slope_p99=0.0, vertices=0, missing=change["missing"], worst_at_m=0.0)
    return dict(max_px=float(px.max()), p99_px=float(np.percentile(px, 99)),
                worst_at_m=float(change["distance_m"][np.argmax(px)]),
                normal_p99=float(np.percentile(change["normal_deg"], 99)),
                normal_max=float(change["normal_deg"].max()),
                detail_max=float(change["detail_m"].max()),
                slope_p99=float(np.percentile(change["slope_deg"], 99)),
                vertices=int(len(px)), missing=change["missing"])


def refine_kwargs(template_level):
    """As renders refine: no hysteresis, so a frame is a function of its camera."""
    return dict(max_pixel_error=1.0, template_level=template_level, hysteresis=False)


def sampled_frames(count, every):
    """Frames f whose pair (f-1, f) is measured when a path is sampled every
    `every` frames: every, 2 every, ... and the last frame (the path's
    speed kept: each pair is two consecutive frames)."""
    frames = set(range(every, count, every))
    if count > 1:
        frames.add(count - 1)
    return frames


def fly(planet, poses, morph=True, template_level=4, timings=None, on_frame=None,
        measured=None):
    """Per frame f >= 1 (f in `measured` when given): stats of frame f's
    camera against surfaces f-1 and f.  Frames neither measured nor before
    a measured one are skipped (renders' refinement is a function of the
    camera alone).  timings (a dict) gets the summed refine and mesh seconds."""
    rows = []
    before = None
    for k, (matrix, width, height, lens) in enumerate(poses):
        if measured is not None and k not in measured and k + 1 not in measured:
            before = None
            continue
        cam = camera(planet, matrix, width, height, lens)
        t0 = time.perf_counter()
        planet.refine(cam, **refine_kwargs(template_level))
        t1 = time.perf_counter()
        mesh = planet.mesh(template_level=template_level, morph=morph, threads=2, cache=False)
        t2 = time.perf_counter()
        if timings is not None:
            timings["refine_s"] = timings.get("refine_s", 0.0) + t1 - t0
            timings["mesh_s"] = timings.get("mesh_s", 0.0) + t2 - t1
        after = Surface(mesh)
        if before is not None and (measured is None or k in measured):
            row = stats_of(compare(View(matrix, width, height, lens), before, after))
            row["frame"] = k
            rows.append(row)
            if on_frame:
                on_frame(row)
        before = after
    return rows


def summary(rows):
    if not rows:
        return dict(max_px=0.0, p99_px=0.0, worst_p99_px=0.0, normal_max=0.0, detail_max=0.0,
                    slope_p99=0.0)
    return dict(max_px=max(r["max_px"] for r in rows),
                p99_px=float(np.median([r["p99_px"] for r in rows])),
                worst_p99_px=max(r["p99_px"] for r in rows),
                normal_max=max(r["normal_max"] for r in rows),
                detail_max=max(r["detail_max"] for r in rows),
                slope_p99=max(r["slope_p99"] for r in rows))


def plot(results, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = sorted({name for name, _ in results})
    fig, axes = plt.subplots(len(names), 1, figsize=(9, 2.6 * len(names)), squeeze=False)
    for ax, name in zip(axes[:, 0], names):
        for (n, morph), rows in results.items():
            if n != name:
                continue
            f = [r["frame"] for r in rows]
            label = "morph" if morph else "no morph"
            ax.semilogy(f, [max(r["max_px"], 1e-5) for r in rows], label=f"max, {label}")
            ax.semilogy(f, [max(r["p99_px"], 1e-5) for r in rows], ls="--", label=f"p99, {label}")
        ax.axhline(0.25, color="k", lw=0.6)
        ax.axhline(0.05, color="k", lw=0.6, ls=":")
        ax.set_title(name)
        ax.set_ylabel("px per frame")
        ax.legend(fontsize=7, ncol=2)
    axes[-1, 0].set_xlabel("frame")
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def print_frame(row):
    print(f"  frame {row['frame']:4d}: max {row['max_px']:.3f} px at {row['worst_at_m']:.4g} m, "
          f"p99 {row['p99_px']:.4f} px, normal max {row['normal_max']:.3f} deg, "
          f"detail max {row['detail_max']:.4f} m", flush=True)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--paths", default=",".join(PATHS))
    p.add_argument("--frames", type=int, default=None, help="frames per path (default: its own)")
    p.add_argument("--range", default=None,
                   help="FIRST:LAST frames of each path measured (the path's speed kept)")
    p.add_argument("--every", type=int, default=None,
                   help="measure only the pairs (f-1, f) for f = N, 2N, ... and the last frame")
    p.add_argument("--at", default=None,
                   help="F1,F2,...: measure only the pairs (F-1, F) of these frames")
    p.add_argument("--template-level", type=int, default=4)
    p.add_argument("--morph", default="on,off", help="on, off or both (on,off)")
    p.add_argument("--plot", default=None, help="PNG of the per-frame maxima")
    p.add_argument("--per-frame", action="store_true",
                   help="print each measured frame (max, p99, the worst vertex's distance)")
    args = p.parse_args()
    planet = earth()
    results = {}
    print(f"{'path':8} {'morph':5} {'frames':>6} {'pairs':>5} {'max px':>8} {'p99 px':>8} {'worst p99':>9} "
          f"{'normal max':>10} {'detail max m':>12} {'slope p99':>9} {'refine s':>8} {'mesh s':>7}")
    for name in args.paths.split(","):
        poses = path_cameras(planet, name, args.frames)
        if args.range:
            first, last = (int(v) for v in args.range.split(":"))
            poses = poses[first:last + 1]
        for morph in [m.strip() == "on" for m in args.morph.split(",")]:
            planet.reset()
            timings = {}
            measured = sampled_frames(len(poses), args.every) if args.every else None
            if args.at:
                measured = {int(f) for f in args.at.split(",")}
            rows = fly(planet, poses, morph=morph, template_level=args.template_level,
                       timings=timings, measured=measured,
                       on_frame=print_frame if args.per_frame else None)
            results[(name, morph)] = rows
            s = summary(rows)
            print(f"{name:8} {'on' if morph else 'off':5} {len(poses):6d} {len(rows):5d} "
                  f"{s['max_px']:8.3f} "
                  f"{s['p99_px']:8.4f} {s['worst_p99_px']:9.4f} {s['normal_max']:10.3f} "
                  f"{s['detail_max']:12.4f} {s['slope_p99']:9.3f} {timings['refine_s']:8.2f} "
                  f"{timings['mesh_s']:7.2f}", flush=True)
    if args.plot:
        plot(results, args.plot)
        print(f"plot: {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
