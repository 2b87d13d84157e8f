#!/usr/bin/env python3
"""The detail field's cost, side by side with detail off, in one run:
refine+cull per frame and mesh emission (flyby with the sector cache, and
cold) along bench_refine.py's descent over the Himalaya (20,000 km to 2 m,
1 px at 1920x1080), on the Earth topology map with the Earth preset's
detail (ridged mountains).

    /usr/bin/python3 -m bench.bench_detail [--frames 120] [--passes 2]
                                           [--threads 2] [--level 4]
                                           [--set roughness=0.56,...]

--set overrides the preset's detail parameters.  Another build's package
(side-by-side runs of two builds): PYTHONPATH=DIR:$PWD /usr/bin/python3 -P
-m bench.bench_detail, DIR holding that build's planetlod/ (-P: the
checkout comes only through PYTHONPATH, after DIR).

Refine: the refiner's own timer (refine_us + cull_us) per frame, the best
of --passes descents after reset() (drops preemption by other tasks);
mean, median, p95, max and frames over 1 ms.  Emission: Planet.mesh()
per frame, cached (the flyby: sectors kept from the previous frame are
copied) and uncached (cold: every sector computed), in M vertices/s over
the whole path.  Off and on alternate frame by frame.  Not a test: figures
only.
"""
import argparse
import os
import statistics
import time

import planetlod
from planetlod import presets

from bench import bench_refine

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

R = 6371000.0
MAP = os.path.join(ROOT, "..", "shared", "data", "earth-topology.png")


def earth_detail():
    """The Earth preset's detail parameters (planetlod/presets.py)."""
    return presets.detail_settings("EARTH")


def camera(m):
    return planetlod.Camera(m, lens=50.0, sensor_width=36.0, resolution_x=1920,
                            resolution_y=1080, clip_start=0.1, clip_end=1e9)


def summary(name, us):
    us = sorted(us)
    p95 = us[int(0.95 * (len(us) - 1))]
    over = sum(1 for x in us if x > 1000.0)
    return (f"{name:>12} {statistics.mean(us):>8.0f} {statistics.median(us):>8.0f} "
            f"{p95:>8.0f} {us[-1]:>8.0f} {over:>6}")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--passes", type=int, default=2)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--level", type=int, default=4)
    parser.add_argument("--max-level", type=int, default=48)
    parser.add_argument("--skip", default="", help="'refine' or 'emission'")
    parser.add_argument("--set", default="", help="detail overrides: key=value,...")
    args = parser.parse_args()

    detail = earth_detail()
    for item in filter(None, args.set.split(",")):
        key, value = item.split("=")
        detail[key] = float(value)
    print(f"planetlod from {planetlod.__file__}")
    planets = {
        "off": planetlod.Planet(R, heightmap=MAP, height_scale=8848.0, sea_level=0.0),
        "on": planetlod.Planet(R, heightmap=MAP, height_scale=8848.0, sea_level=0.0,
                               detail=detail),
    }
    for p in planets.values():
        p.reserve(1 << 16)
    top = planets["off"].height_range()[1]
    cams = [(alt, camera(m)) for alt, m in bench_refine.descent(args.frames, terrain_top=top)]
    print(f"detail: {detail}; {planets['on'].detail['octaves']} octaves down to "
          f"{planets['on'].detail['finest_wavelength']:.3f} m; map cube "
          f"{planets['off'].heightmap.size}^2 per face")

    # ---- refine + cull -----------------------------------------------------
    if args.skip != "refine":
        refine_figures(args, planets, cams)
    if args.skip != "emission":
        emission_figures(args, planets, cams)


def refine_figures(args, planets, cams):
    best = {name: [float("inf")] * len(cams) for name in planets}
    sectors = {name: [0] * len(cams) for name in planets}
    for _ in range(args.passes):
        for p in planets.values():
            p.reset()
        for k, (_alt, cam) in enumerate(cams):
            for name, p in planets.items():
                s = p.refine(cam, template_level=args.level, max_level=args.max_level)
                best[name][k] = min(best[name][k], s["refine_us"] + s["cull_us"])
                sectors[name][k] = s["sectors_total"]
    print(f"\nrefine+cull per frame, µs, best of {args.passes} descents "
          f"({args.frames} frames, template level {args.level}, max level {args.max_level})")
    print(f"{'':>12} {'mean':>8} {'median':>8} {'p95':>8} {'max':>8} {'>1 ms':>6}")
    for name in planets:
        print(summary("detail " + name, best[name]))
    worst = max(range(len(cams)), key=lambda k: best["on"][k])
    print(f"slowest frame with detail: {best['on'][worst]:.0f} µs at "
          f"{cams[worst][0]:.0f} m ({sectors['on'][worst]} sectors, "
          f"{sectors['off'][worst]} without detail)")
    ratio = statistics.mean(best["on"]) / statistics.mean(best["off"])
    print(f"mean on/off: {ratio:.2f}x; sectors on/off (mean): "
          f"{statistics.mean(sectors['on']) / statistics.mean(sectors['off']):.2f}x")



def emission_figures(args, planets, cams):
    print(f"\nemission along the descent, {args.threads} threads, template level {args.level}, "
          f"max level {args.max_level}, M vertices/s over the path (cached = flyby, "
          "uncached = cold)")
    print(f"{'':>12} {'vertices':>10} {'cold':>8} {'flyby':>8} {'hit rate':>8}")
    totals = {name: [0, 0.0, 0.0, 0, 0] for name in planets}
    for p in planets.values():
        p.reset()
        p.mesh_cache_max_bytes = 1 << 30
    for _alt, cam in cams:
        for name, p in planets.items():
            p.refine(cam, template_level=args.level, max_level=args.max_level)
            t0 = time.perf_counter()
            cold = p.mesh(threads=args.threads, cache=False)
            t1 = time.perf_counter()
            p.mesh(threads=args.threads)
            t2 = time.perf_counter()
            info = p.mesh_cache_info
            t = totals[name]
            t[0] += cold.vertex_count
            t[1] += t1 - t0
            t[2] += t2 - t1
            t[3] += info["hits"]
            t[4] += info["misses"]
    for name, (v, cold_s, fly_s, hits, misses) in totals.items():
        print(f"{'detail ' + name:>12} {v:>10} {v / cold_s / 1e6:>8.2f} {v / fly_s / 1e6:>8.2f} "
              f"{100.0 * hits / max(1, hits + misses):>7.1f}%")
    on, off = totals["on"], totals["off"]
    print(f"on/off speed: cold {(on[0] / on[1]) / (off[0] / off[1]):.2f}x, "
          f"flyby {(on[0] / on[2]) / (off[0] / off[2]):.2f}x; vertices on/off "
          f"{on[0] / off[0]:.2f}x")


if __name__ == "__main__":
    main()
