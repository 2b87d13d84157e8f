#!/usr/bin/env python3
"""Screen error of each LOD method against the full-detail surface.

    /usr/bin/python3 -m bench.bench_method_error [--frames 24] [--at 0,5,10,15,20,23]
        [--methods hrtmr,chunked,geomipmap,geomipmap/256,clipmap,clipmap/128]
        [--samples 250000] [--json bench/results/method_error.json]

The Earth preset with its detail field (every octave), refined at 1 px
(1920x1080, 50 mm, template level 4, no hysteresis, mesh without morph) on
the thesis's camera path (bench/camera_path.csv) and bench_refine's descent
(20,000 km to 2 m over Everest), a few sampled frames each.  For each
emitted mesh, the triangles reaching the image are sampled on barycentric
lattices about 8 px apart on the screen (at least corners and edge
midpoints; of the small triangles at most --samples, at random with a fixed
seed); each sample point p on the mesh is compared with the exact surface on the same
ray from the planet's centre (the height source with every detail octave,
the sea where it is higher), and the two points' distance on the screen of
that frame's camera is the error in pixels.  Occlusion is ignored.  Per
method and path: triangles (mean, max), the error's max over the sampled
points, its 99th percentile (median and worst frame) and the share of
samples over 1 px.  Not a test: figures only.
"""
import argparse
import json
import os
import sys
import time

import numpy as np

import planetlod
from bench import bench_pops, camera_path
from bench.bench_refine import descent

METHOD_SPECS = {
    "hrtmr": ("hrtmr", {}),
    "chunked": ("chunked", {"chunk_cracks": "stitch"}),
    "chunked/skirts": ("chunked", {"chunk_cracks": "skirts"}),
    "geomipmap": ("geomipmap", {}),
    "geomipmap/256": ("geomipmap", {"geomipmap_tiles": 256}),
    "clipmap": ("clipmap", {}),
    "clipmap/64": ("clipmap", {"clipmap_ring_cells": 64}),
    "clipmap/128": ("clipmap", {"clipmap_ring_cells": 128}),
    "clipmap/256": ("clipmap", {"clipmap_ring_cells": 256}),
}
WIDTH, HEIGHT, LENS = 1920, 1080, 50.0


def refine_options(method, options, pixel_error=1.0, template_level=4):
    kwargs = dict(method=method, max_pixel_error=pixel_error, template_level=template_level,
                  threads=2, **options)
    if method == "hrtmr":
        kwargs["hysteresis"] = False  # a function of the camera alone, as renders refine
    return kwargs


def exact_surface(planet, points):
    """Points of the full-detail surface on the rays from the centre through `points`."""
    heights, _ = planet.surface(points.reshape(-1))
    h = np.frombuffer(heights, np.float64)
    if planet.sea_level is not None:
        h = np.maximum(h, planet.sea_level)
    up = points / np.linalg.norm(points, axis=1)[:, None]
    return up * (planet.radius + h)[:, None]


def lattice(n):
    """Barycentric points (i/n, j/n) of a triangle, i + j <= n."""
    return np.array([[1 - (i + j) / n, i / n, j / n] for i in range(n + 1)
                     for j in range(n + 1 - i)], np.float64)


def screen_error(planet, mesh, view, samples, rng, spacing_px=8.0, most=64):
    """Pixel distances between sampled points of `mesh` in `view` and the
    exact surface.  Each triangle reaching the image is sampled on a
    barycentric lattice whose spacing is about `spacing_px` on the screen
    (at least its corners and edge midpoints, at most `most` steps an edge;
    a triangle crossing the camera plane gets `most`); of the triangles
    sampled at the coarsest lattice at most `samples` are kept (at random)."""
    pos = np.frombuffer(mesh.positions, np.float32).reshape(-1, 3).astype(np.float64) \
        + np.asarray(mesh.origin, np.float64)
    tri = np.frombuffer(mesh.triangles, np.int32).reshape(-1, 3)
    if not len(tri):
        return np.zeros(0)
    xy, depth = view.project(pos)
    front = depth[tri] > 0
    reach = front.any(axis=1)
    tri, front = tri[reach], front[reach]
    crossing = ~front.all(axis=1)
    with np.errstate(invalid="ignore"):
        txy = xy[tri]
        lo = np.where(front[..., None], txy, np.inf).min(axis=1)
        hi = np.where(front[..., None], txy, -np.inf).max(axis=1)
    on_screen = crossing | ((hi[:, 0] >= 0) & (lo[:, 0] <= view.width) & (hi[:, 1] >= 0)
                            & (lo[:, 1] <= view.height))
    tri, txy, crossing = tri[on_screen], txy[on_screen], crossing[on_screen]
    with np.errstate(invalid="ignore"):
        edge = np.max(np.linalg.norm(txy - np.roll(txy, 1, axis=1), axis=2), axis=1)
    steps = np.where(crossing | ~np.isfinite(edge), most,
                     np.clip(np.ceil(np.nan_to_num(edge) / spacing_px), 2, most)).astype(int)
    steps = 2 ** np.ceil(np.log2(steps)).astype(int)  # a few lattice sizes
    out = []
    for n in np.unique(steps):
        group = tri[steps == n]
        if n == 2 and len(group) > samples:
            group = group[rng.choice(len(group), samples, replace=False)]
        points = np.einsum("sc,tcx->tsx", lattice(int(n)), pos[group]).reshape(-1, 3)
        points = points[view.visible(points)]
        if not len(points):
            continue
        exact = exact_surface(planet, points)
        a, depth_a = view.project(points)
        b, depth_b = view.project(exact)
        ok = (depth_a > 0) & (depth_b > 0)
        out.append(np.linalg.norm(a[ok] - b[ok], axis=1))
    return np.concatenate(out) if out else np.zeros(0)


def paths(planet, frames, at):
    _, hi = planet.height_range()
    path = [m for _, m, _, _ in camera_path.frames(frames)]
    down = [m for _, m in descent(frames, terrain_top=hi)]
    return [("camera path", [(k, path[k]) for k in at]),
            ("descent", [(k, down[k]) for k in at])]


def measure(planet, name, poses, samples, pixel_error):
    method, options = METHOD_SPECS[name]
    rows = []
    planet.reset()
    for k, matrix in poses:
        cam = bench_pops.camera(planet, matrix, WIDTH, HEIGHT, LENS)
        t0 = time.perf_counter()
        planet.refine(cam, **refine_options(method, options, pixel_error))
        mesh = planet.mesh(threads=2, morph=False)
        t1 = time.perf_counter()
        px = screen_error(planet, mesh, bench_pops.View(matrix, WIDTH, HEIGHT, LENS), samples,
                          np.random.default_rng(k))
        rows.append(dict(frame=k, tris=mesh.triangle_count, seconds=t1 - t0,
                         max_px=float(px.max()) if len(px) else 0.0,
                         p99_px=float(np.percentile(px, 99)) if len(px) else 0.0,
                         over_1px=float(np.mean(px > 1.0)) if len(px) else 0.0,
                         samples=int(len(px))))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=24, help="frames of each path")
    ap.add_argument("--at", default="0,5,10,15,20,23", help="the frames measured")
    ap.add_argument("--methods", default="hrtmr,chunked,geomipmap,geomipmap/256,clipmap,"
                                         "clipmap/128")
    ap.add_argument("--samples", type=int, default=250000, help="triangles sampled a frame")
    ap.add_argument("--pixel-error", type=float, default=1.0)
    ap.add_argument("--json", default=None, help="write the per-frame rows here")
    ap.add_argument("--per-frame", action="store_true")
    args = ap.parse_args()
    planet = bench_pops.earth()
    at = [int(f) for f in args.at.split(",")]
    print(f"screen error against the full-detail surface; {WIDTH}x{HEIGHT}, "
          f"{args.pixel_error} px; frames {at} of {args.frames}")
    print(f"{'path':12s} {'method':14s} {'tris mean':>10s} {'tris max':>10s} {'max px':>9s} "
          f"{'p99 px':>8s} {'worst p99':>9s} {'> 1 px':>7s}")
    out = {}
    for title, poses in paths(planet, args.frames, at):
        for name in args.methods.split(","):
            rows = measure(planet, name, poses, args.samples, args.pixel_error)
            out[f"{title}|{name}"] = rows
            if args.per_frame:
                for r in rows:
                    print(f"    frame {r['frame']:3d}: {r['tris']:9d} tris, max {r['max_px']:9.2f}"
                          f" px, p99 {r['p99_px']:7.3f} px, > 1 px {100 * r['over_1px']:.2f} %,"
                          f" {r['seconds']:.1f} s", flush=True)
            print(f"{title:12s} {name:14s} {np.mean([r['tris'] for r in rows]):10.0f} "
                  f"{max(r['tris'] for r in rows):10d} {max(r['max_px'] for r in rows):9.2f} "
                  f"{np.median([r['p99_px'] for r in rows]):8.3f} "
                  f"{max(r['p99_px'] for r in rows):9.3f} "
                  f"{100 * np.mean([r['over_1px'] for r in rows]):6.2f}%", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
