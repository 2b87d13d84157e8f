#!/usr/bin/env python3
"""Refine+cull cost per frame along a descent from 20,000 km to 2 m over an
Earth-radius planet with the Earth topology map (1 px at 1920x1080).

    /usr/bin/python3 -m bench.bench_refine [--frames 240] [--size 0] [--sphere]
                                           [--passes 3] [--threads 1]

Prints a table (every --every frames) and a summary: refine and cull µs
per frame (mean, median, p95, max, frames over 1 ms), sectors per frame,
splits/merges, bytes per sector.  The first descent from a new planet also
grows the refiner's arrays (once per planet) and is summarised on its own,
and again side by side for new planets without and with Planet.reserve()
(--reserve sectors allocated and touched before the first frame);
then --passes descents after reset() (capacity kept: the steady state of a
flyby) give per frame the median and the best of the passes (the best
drops preemption by other tasks), by the refiner's wall-clock timers and by
the calling thread's CPU time around refine().  Also the same path on a
perfect sphere, and a "fresh" column: the cost of refining each frame from
the base sectors (what incrementality saves).  Not a test: figures only.
"""
import argparse
import math
import os
import statistics
import sys
import time

import planetlod
from planetlod.flyby import look_matrix

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

R = 6371000.0


def look_at(eye, target, up):
    """Camera matrix (row-major 4x4, nested lists) at eye looking at target."""
    return [list(row) for row in look_matrix(eye, [t - e for t, e in zip(target, eye)], up)]


def descent(frames, lat_deg=27.9, lon_deg=86.9, terrain_top=0.0, radius=R, start=2e7):
    """The reference descent: (altitude, camera matrix) per frame from `start`
    (20,000 km) to 2 m above the terrain top of a planet of `radius`,
    pitching from straight down to 10 degrees below the horizon while moving
    east (tools/descent_hash.py flies it too)."""
    lat, lon0 = math.radians(lat_deg), math.radians(lon_deg)
    for k in range(frames):
        t = k / (frames - 1)
        alt = math.exp(math.log(start) * (1 - t) + math.log(2.0) * t)
        lon = lon0 + 0.002 * t
        d = [math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)]
        east = [-math.sin(lon), math.cos(lon), 0.0]
        pitch = math.radians(-90 + 80 * min(1.0, t * 1.25))
        view = [east[i] * math.cos(pitch) + d[i] * math.sin(pitch) for i in range(3)]
        eye = [d[i] * (radius + terrain_top + alt) for i in range(3)]
        target = [eye[i] + view[i] for i in range(3)]
        up = d if abs(pitch) < math.radians(89) else [-math.sin(lat) * math.cos(lon),
                                                        -math.sin(lat) * math.sin(lon),
                                                        math.cos(lat)]
        yield alt, look_at(eye, target, up)


def cameras(planet, frames, terrain_top):
    out = []
    for alt, m in descent(frames, terrain_top=terrain_top):
        cam = planetlod.Camera(m, lens=50.0, sensor_width=36.0, resolution_x=1920,
                               resolution_y=1080, clip_start=0.1, clip_end=1e9)
        near, far = planet.recommended_clip(cam)
        out.append((alt, planetlod.Camera(m, lens=50.0, sensor_width=36.0, resolution_x=1920,
                                          resolution_y=1080, clip_start=near, clip_end=far)))
    return out


def descend(planet, cams, template_level, threads):
    """One descent from the base sectors: per-frame stats, with the calling
    thread's CPU time around refine()."""
    planet.reset()
    rows = []
    for alt, cam in cams:
        t_cpu = time.thread_time()
        s = planet.refine(cam, template_level=template_level, threads=threads)
        s["cpu_us"] = (time.thread_time() - t_cpu) * 1e6
        s["us"] = s["refine_us"] + s["cull_us"]
        rows.append(s)
    return rows


def summary(label, per):
    ordered = sorted(per)
    print(f"{label}: mean {statistics.mean(per):.1f}, median {statistics.median(per):.1f}, "
          f"p95 {ordered[int(0.95 * len(per))]:.1f}, max {max(per):.1f}; "
          f"frames over 1000 µs: {sum(p > 1000 for p in per)}/{len(per)}")


def run(planet, frames, every, label, terrain_top, fresh_too=True, template_level=4, threads=1,
        passes=3, reserve=16384):
    """The first descent grows the refiner's arrays (a planet's first frames
    pay that once); then `passes` descents after reset(), which keeps the
    capacity: the steady state a flyby runs in.  Per frame, the median and
    the best of those passes (the best drops preemption by other tasks)."""
    print(f"\n== {label}: {frames} frames, 1 px, 1920x1080, template level {template_level} "
          f"({4 ** template_level} triangles/sector), {threads} thread(s) ==")
    cams = cameras(planet, frames, terrain_top)
    first = descend(planet, cams, template_level, threads)
    # A planet's first descent, side by side: new planets without and with
    # reserve(), alternating; per frame the median over `passes` planets.
    new_plain, new_reserved, reserve_ms = [], [], []
    for _ in range(passes):
        for reserved in (False, True):
            twin = planetlod.Planet(planet.radius, projection=planet.projection,
                                    heightmap=planet.heightmap, height_scale=planet.height_scale)
            if reserved:
                t = time.perf_counter()
                twin.reserve(reserve)
                reserve_ms.append((time.perf_counter() - t) * 1e3)
            (new_reserved if reserved else new_plain).append(
                descend(twin, cams, template_level, threads))
            del twin
    warm = [descend(planet, cams, template_level, threads) for _ in range(passes)]
    median = [statistics.median(w[k]["us"] for w in warm) for k in range(frames)]
    best = [min(w[k]["us"] for w in warm) for k in range(frames)]
    head = (f"{'altitude m':>12} {'total':>7} {'backface':>8} {'frustum':>8} {'visible':>8} "
            f"{'splits':>6} {'merges':>6} {'level':>5} {'refine µs':>9} {'cull µs':>8} "
            f"{'median µs':>9} {'fresh µs':>9}")
    print(head)
    fresh_planet = None
    rows = warm[-1]
    for k, ((alt, cam), s) in enumerate(zip(cams, rows)):
        if k % every and k != frames - 1:
            continue
        fresh_us = float("nan")
        if fresh_too and k % every == 0:
            fresh_planet = fresh_planet or planetlod.Planet(
                planet.radius, projection=planet.projection, heightmap=planet.heightmap,
                height_scale=planet.height_scale)
            fresh_planet.reset()
            t = time.perf_counter()
            fresh_planet.refine(cam, template_level=template_level)
            fresh_us = (time.perf_counter() - t) * 1e6
        print(f"{alt:12.1f} {s['sectors_total']:7d} {s['sectors_after_backface']:8d} "
              f"{s['sectors_after_frustum']:8d} {s['sectors_after_budget']:8d} "
              f"{s['splits']:6d} {s['merges']:6d} {s['max_level']:5d} "
              f"{s['refine_us']:9.1f} {s['cull_us']:8.1f} {median[k]:9.1f} {fresh_us:9.1f}")
    summary("first descent (arrays growing), refine+cull µs/frame", [s["us"] for s in first])
    for name, runs in (("new planet", new_plain),
                       (f"new planet after reserve({reserve})", new_reserved)):
        summary(f"first descent of a {name}, median of {passes} planets",
                [statistics.median(w[k]["us"] for w in runs) for k in range(frames)])
    print(f"(reserve({reserve}) took {statistics.median(reserve_ms):.2f} ms once per planet, "
          f"median of {passes})")
    summary(f"refine+cull µs/frame, median of {passes} descents", median)
    summary(f"refine+cull µs/frame, best of {passes} descents", best)
    summary(f"refine() thread CPU µs/frame, median of {passes} descents",
            [statistics.median(w[k]["cpu_us"] for w in warm) for k in range(frames)])
    total = [s["sectors_total"] for s in rows]
    vis = [s["sectors_after_budget"] for s in rows]
    tris = [s["triangles"] for s in rows]
    print(f"sectors/frame: total mean {statistics.mean(total):.0f} max {max(total)}; "
          f"visible mean {statistics.mean(vis):.0f} max {max(vis)} "
          f"(triangles: mean {statistics.mean(tris):.0f} max {max(tris)})")
    print(f"bytes: sector record {planet.SECTOR_SIZE}; refiner state "
          f"{planet.memory_bytes} B for {planet.sector_count} sectors "
          f"= {planet.memory_bytes / planet.sector_count:.0f} B/sector (capacities included)")
    return median


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=240)
    ap.add_argument("--every", type=int, default=20)
    ap.add_argument("--size", type=int, default=0, help="cube map face size (0 = from image)")
    ap.add_argument("--sphere", action="store_true", help="only the perfect sphere")
    ap.add_argument("--threads", type=int, default=1,
                    help="refine(threads=...): parallel predicate evaluation (default 1)")
    ap.add_argument("--template-level", type=int, default=4,
                    help="sector template level (4 = 256 triangles/sector, the default)")
    ap.add_argument("--passes", type=int, default=3,
                    help="descents measured after the first (default 3)")
    ap.add_argument("--reserve", type=int, default=16384,
                    help="Planet.reserve() for the new-planet comparison (default 16384)")
    args = ap.parse_args()
    print(f"planetlod refine benchmark; python {sys.version.split()[0]}; "
          f"{os.cpu_count()} cpus; refine threads={args.threads}")
    if not args.sphere:
        path = os.path.join(ROOT, "data", "earth-topology.png")
        t = time.perf_counter()
        earth = planetlod.Planet(R, projection="qsc", heightmap=path, height_scale=8848.0,
                                 sea_level=0.0, heightmap_size=args.size)
        lo, hi = earth.height_range()
        print(f"Earth topology -> QSC cube map {earth.heightmap.size}^2 x 6 in "
              f"{time.perf_counter() - t:.2f} s; heights {lo:.0f}..{hi:.0f} m")
        run(earth, args.frames, args.every, "Earth topology (QSC), descent to 2 m over Everest",
            terrain_top=hi, template_level=args.template_level, threads=args.threads,
            passes=args.passes, reserve=args.reserve)
    sphere = planetlod.Planet(R, projection="qsc")
    run(sphere, args.frames, args.every, "perfect sphere (QSC)", terrain_top=0.0,
        template_level=args.template_level, threads=args.threads, passes=args.passes,
        reserve=args.reserve)
    side = planetlod.Planet(R, projection="qsc")
    print("\n(side/distance criterion, split 0.5, on the sphere)")
    per = []
    for alt, m in descent(args.frames):
        cam = planetlod.Camera(m, clip_start=0.1, clip_end=1e9)
        s = side.refine(cam, criterion="side_distance")
        per.append(s["refine_us"] + s["cull_us"])
    print(f"side/distance: refine+cull µs/frame mean {statistics.mean(per):.1f}, max "
          f"{max(per):.1f}; final sectors {side.sector_count}, max level "
          f"{max(side.sector_levels(visible_only=False).tolist())}")


if __name__ == "__main__":
    main()
