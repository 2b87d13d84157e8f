#!/usr/bin/env python3
"""The LOD methods side by side: HRTMR, chunked LOD (stitched and skirts) and
geomipmapping on the Earth topology map, at the same 1 px screen error
(1920x1080, 50 mm), along the thesis's camera path (bench/camera_path.csv)
and bench_refine's descent from 20,000 km to 2 m.

    /usr/bin/python3 -m bench.bench_methods [--frames 40] [--size 0]
                                            [--cracks-every 4] [--threads 2] [--json FILE]

Per method and path: triangles and vertices per frame (mean, max), refine
and mesh() milliseconds per frame (median, max), the method's own state
(state_bytes, max) and the mesh's bytes (what Blender receives: 40 bytes a
vertex, 20 a triangle; max), and cracks: boundary edges after welding
equal float32 positions, counted every --cracks-every frames with culling
off (a closed sphere has none; skirts: the open edges that are not a
skirt's bottom).  Not a test: figures only.
"""
import argparse
import json
import os
import statistics
import sys
import time

import numpy as np

import planetlod
from bench import camera_path
from bench.bench_refine import R, descent

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

METHODS = [("hrtmr", {}), ("chunked", {"chunk_cracks": "stitch"}),
           ("chunked", {"chunk_cracks": "skirts"}), ("geomipmap", {}),
           ("geomipmap", {"skip_sea": True}), ("clipmap", {}),
           ("clipmap", {"clipmap_ring_cells": 64})]


def label(method, options):
    if options.get("skip_sea"):  # Jankauskas's lower-bound culling, the sea as gap plane
        return method + "/sea"
    if "clipmap_ring_cells" in options:
        return f"{method}/{options['clipmap_ring_cells']}"
    return method + ("/" + options["chunk_cracks"] if "chunk_cracks" in options else "")


def camera(planet, matrix):
    cam = planetlod.Camera(matrix, lens=50.0, sensor_width=36.0, resolution_x=1920,
                           resolution_y=1080, clip_start=0.1, clip_end=1e9)
    near, far = planet.recommended_clip(cam)
    return planetlod.Camera(matrix, lens=50.0, sensor_width=36.0, resolution_x=1920,
                            resolution_y=1080, clip_start=near, clip_end=far)


def open_edges(mesh, planet=None):
    """Boundary edges after welding equal float32 positions; with `planet`,
    only those with an end on the surface (a skirt's bottom lies below it)."""
    pos = np.frombuffer(mesh.positions, np.float32).reshape(-1, 3)
    tri = np.frombuffer(mesh.triangles, np.int32).reshape(-1, 3)
    if len(tri) == 0:
        return 0
    welded, remap = np.unique(pos, axis=0, return_inverse=True)
    t = remap.reshape(-1)[tri]
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    boundary = unique[counts == 1]
    if planet is None or len(boundary) == 0:
        return len(boundary)
    world = welded.astype(np.float64) + np.asarray(mesh.origin)
    heights, _ = planet.surface(world.reshape(-1).tolist())
    on_surface = np.linalg.norm(world, axis=1) >= R + np.frombuffer(heights, np.float64) - 1e-3
    return int(np.sum(on_surface[boundary].any(axis=1)))


def fly(planet, cams, method, options, threads, cracks_every):
    rows = []
    planet.reset()
    for k, cam in enumerate(cams):
        t0 = time.perf_counter()
        stats = planet.refine(cam, method=method, threads=threads, **options)
        t1 = time.perf_counter()
        mesh = planet.mesh(threads=threads)
        t2 = time.perf_counter()
        row = dict(tris=mesh.triangle_count, verts=mesh.vertex_count,
                   refine_ms=(t1 - t0) * 1e3, mesh_ms=(t2 - t1) * 1e3,
                   state=stats.get("state_bytes", planet.memory_bytes),
                   mesh_bytes=40 * mesh.vertex_count + 20 * mesh.triangle_count, cracks=None)
        if cracks_every and k % cracks_every == 0:
            planet.refine(cam, method=method, threads=threads, backface=False, frustum=False,
                          **options)
            whole = planet.mesh(threads=threads)
            row["cracks"] = open_edges(whole, planet if "skirts" in options.values() else None)
        rows.append(row)
    return rows


def table(title, results):
    print(f"\n{title}")
    print(f"{'method':18s} {'tris mean':>10s} {'tris max':>9s} {'verts mean':>10s} "
          f"{'refine ms':>10s} {'max':>7s} {'mesh ms':>8s} {'max':>7s} {'state MB':>9s} "
          f"{'mesh MB':>8s} {'cracks':>7s}")
    for name, rows in results:
        cracks = [r["cracks"] for r in rows if r["cracks"] is not None]
        print(f"{name:18s} {statistics.mean(r['tris'] for r in rows):10.0f} "
              f"{max(r['tris'] for r in rows):9d} "
              f"{statistics.mean(r['verts'] for r in rows):10.0f} "
              f"{statistics.median(r['refine_ms'] for r in rows):10.2f} "
              f"{max(r['refine_ms'] for r in rows):7.1f} "
              f"{statistics.median(r['mesh_ms'] for r in rows):8.2f} "
              f"{max(r['mesh_ms'] for r in rows):7.1f} "
              f"{max(r['state'] for r in rows) / 2 ** 20:9.2f} "
              f"{max(r['mesh_bytes'] for r in rows) / 2 ** 20:8.1f} "
              f"{max(cracks) if cracks else '-':>7}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--size", type=int, default=0, help="cube map face size (0 = from image)")
    ap.add_argument("--cracks-every", type=int, default=4)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--json", default=None, help="write the per-frame rows here (plot_methods.py)")
    args = ap.parse_args()
    print(f"planetlod LOD methods benchmark; python {sys.version.split()[0]}; "
          f"{os.cpu_count()} cpus; threads={args.threads}; {args.frames} frames per path")
    earth = planetlod.Planet(R, projection="qsc",
                             heightmap=os.path.join(ROOT, "data", "earth-topology.png"),
                             height_scale=8848.0, sea_level=0.0, heightmap_size=args.size)
    lo, hi = earth.height_range()
    paths = [
        ("camera path (bench/camera_path.csv)",
         [camera(earth, m) for _, m, _, _ in camera_path.frames(args.frames)]),
        ("descent 20,000 km -> 2 m over Everest",
         [camera(earth, m) for _, m in descent(args.frames, terrain_top=hi)]),
    ]
    out = {}
    for title, cams in paths:
        results = [(label(m, o), fly(earth, cams, m, o, args.threads, args.cracks_every))
                   for m, o in METHODS]
        table(title, results)
        out[title] = dict(results)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
