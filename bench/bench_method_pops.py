#!/usr/bin/env python3
"""Pops per LOD method: bench_pops.py's measure for every method, a few frames a path.

    /usr/bin/python3 -m bench.bench_method_pops [--paths descent,flyby] [--pairs 5]
        [--methods hrtmr,chunked,geomipmap,clipmap] [--morph on]
        [--json bench/results/method_pops.json]

For each measured frame f (--pairs of them spread over each of bench_pops.py's
paths, each with its frame f-1), frame f's camera looks at the mesh refined
and emitted for frame f-1's camera and the one for frame f's: every vertex
of either mesh in view is matched with the point of the other mesh on the
same ray from the planet's centre, and the pair's screen distance is the
jump (bench_pops.compare).  The methods' patches differ in vertex count, so
every method's meshes are matched whole (along rays, not sector by sector
as bench_pops.py does for HRTMR; a vertex kept unchanged still scores 0),
at most --vertices of each mesh's vertices in view (at random, fixed seed).
Earth preset with its detail field, 1 px, template level 4, refined as
renders refine (a function of the camera alone); --morph as bench_pops.py.
Per method and path: the largest jump, the median and worst per-frame 99th
percentile, the worst normal change.  Not a test: figures only.
"""
import argparse
import json
import sys

import numpy as np

from bench import bench_pops
from bench.bench_method_error import METHOD_SPECS, refine_options


def whole(mesh):
    """bench_pops.Surface of `mesh` as one sector, so meshes of any layout match along rays."""
    surface = bench_pops.Surface(mesh)
    surface.ids = np.zeros(1, np.uint64)
    surface.per_sector = len(surface.positions)
    surface.triangles_per_sector = len(surface.triangles)
    return surface


def compare_whole(view, before, after, most, rng, chunk=50000):
    """bench_pops.compare's changes, every vertex of either surface in view
    (at most `most` of each, at random) matched along its ray with the other."""
    pixels, normal, detail, distance, missing = [], [], [], [], 0
    everything = np.zeros(1, np.int64)
    for mine, other in ((after, before), (before, after)):
        rows = np.flatnonzero(view.visible(mine.positions))
        if len(rows) > most:
            rows = np.sort(rng.choice(rows, most, replace=False))
        for s in range(0, len(rows), chunk):
            r = rows[s:s + chunk]
            p = mine.positions[r]
            q = p / np.linalg.norm(p, axis=1)[:, None]
            point, n, dt, _, found = other.hit(q, everything)
            missing += int((~found).sum())
            a, _ = view.project(p[found])
            b, _ = view.project(point[found])
            pixels.append(np.linalg.norm(a - b, axis=1))
            distance.append(np.linalg.norm(p[found] - view.location, axis=1))
            normal.append(bench_pops.angle_deg(mine.normals[r][found], n[found]))
            detail.append(np.abs(mine.detail[r][found] - dt[found]))
    cat = (lambda xs: np.concatenate(xs) if xs else np.zeros(0))
    return dict(pixels=cat(pixels), normal_deg=cat(normal), detail_m=cat(detail),
                slope_deg=np.zeros(1), distance_m=cat(distance), missing=missing)


def measured_frames(count, pairs):
    return sorted({int(round(count * (k + 1) / (pairs + 1))) for k in range(pairs)} - {0})


def fly(planet, name, poses, frames, morph, most, template_level=4):
    method, options = METHOD_SPECS[name]
    rows = []
    planet.reset()
    for f in frames:
        surfaces = []
        for k in (f - 1, f):
            matrix, width, height, lens = poses[k]
            cam = bench_pops.camera(planet, matrix, width, height, lens)
            planet.refine(cam, **refine_options(method, options, 1.0, template_level))
            mesh = planet.mesh(threads=2, morph=morph)
            surfaces.append((whole(mesh), mesh.triangle_count))
        (before, _), (after, tris) = surfaces
        matrix, width, height, lens = poses[f]
        row = bench_pops.stats_of(compare_whole(
            bench_pops.View(matrix, width, height, lens), before, after, most,
            np.random.default_rng(f)))
        row.update(frame=f, tris=tris)
        rows.append(row)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--paths", default="descent,flyby")
    ap.add_argument("--pairs", type=int, default=5)
    ap.add_argument("--methods", default="hrtmr,chunked,geomipmap,clipmap")
    ap.add_argument("--morph", default="on", choices=("on", "off"))
    ap.add_argument("--vertices", type=int, default=200000,
                    help="vertices in view matched a mesh (at random beyond)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--per-frame", action="store_true")
    args = ap.parse_args()
    planet = bench_pops.earth()
    out = {}
    print(f"{'path':8s} {'method':12s} {'pairs':>5s} {'tris mean':>10s} {'max px':>8s} "
          f"{'p99 px':>8s} {'worst p99':>9s} {'normal max':>10s} {'missing':>7s}")
    for path in args.paths.split(","):
        poses = bench_pops.path_cameras(planet, path)
        frames = measured_frames(len(poses), args.pairs)
        for name in args.methods.split(","):
            rows = fly(planet, name, poses, frames, args.morph == "on", args.vertices)
            out[f"{path}|{name}"] = rows
            if args.per_frame:
                for r in rows:
                    print(f"    frame {r['frame']:4d}: {r['tris']:9d} tris, max {r['max_px']:.3f}"
                          f" px at {r['worst_at_m']:.4g} m, p99 {r['p99_px']:.4f} px", flush=True)
            s = bench_pops.summary(rows)
            print(f"{path:8s} {name:12s} {len(rows):5d} "
                  f"{np.mean([r['tris'] for r in rows]):10.0f} {s['max_px']:8.3f} "
                  f"{s['p99_px']:8.4f} {s['worst_p99_px']:9.4f} {s['normal_max']:10.3f} "
                  f"{sum(r['missing'] for r in rows):7d}", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
