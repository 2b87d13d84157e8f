#!/usr/bin/env python3
"""What the Earth preset's detail costs over named places, side by side
with another build: bench_refine.py's descent (20,000 km to 2 m above the
local ground) flown over each place, both builds in one process, frame by
frame and build by build (so load from other tasks falls on both alike),
per frame the best of --passes.

    /usr/bin/python3 -m bench.bench_band_cost --base DIR [--new DIR]
        [--base-detail JSON] [--new-detail JSON] [--frames 30] [--passes 2]
        [--places jacksboro,alps,himalaya] [--threads 2]

Per place and build: sectors and vertices summed over the frames (free of
load), refine+cull (one thread; the refiner's own timers) and cold
emission (mesh(threads, cache=False)) summed over the frames and as the
median of the per-frame ratios new / base.  --base-detail / --new-detail
give a build its Earth detail (a dict as planetlod.Planet(detail=...)
takes it; default: this checkout's preset).  Not a test: figures only.
"""
import argparse
import json
import statistics
import time

from bench import bench_refine
from bench.bench_detail_builds import R, camera, data_path, load_build
from planetlod import presets

PLACES = {"jacksboro": (36.47, -84.35), "alps": (46.55, 7.95), "himalaya": (27.9, 86.9)}


def planet(lod, detail):
    p = lod.Planet(R, heightmap=data_path("earth-topology.png"), height_scale=8848.0,
                   sea_level=0.0, detail=detail)
    p.reserve(1 << 16)
    return p


def ground(p, lat, lon):
    import math
    la, lo = math.radians(lat), math.radians(lon)
    return p.height(math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la))


def fly(builds, details, place, args):
    lat, lon = PLACES[place]
    planets = {name: planet(lod, details[name]) for name, lod in builds.items()}
    # the descent ends 2 m above the ground under its end (the same for both)
    top = max(ground(p, lat, lon + 0.002) for p in planets.values())
    path = list(bench_refine.descent(args.frames, lat_deg=lat, lon_deg=lon, terrain_top=top))
    names = list(builds)
    sectors = {n: [0] * len(path) for n in names}
    verts = {n: [0] * len(path) for n in names}
    refine = {n: [float("inf")] * len(path) for n in names}
    emit = {n: [float("inf")] * len(path) for n in names}
    for _ in range(args.passes):
        for p in planets.values():
            p.reset()
        for k, (_alt, m) in enumerate(path):
            for n in names:
                p = planets[n]
                s = p.refine(camera(builds[n], m), template_level=4, max_level=48, threads=1)
                refine[n][k] = min(refine[n][k], (s["refine_us"] + s["cull_us"]) * 1e-6)
                t0 = time.perf_counter()
                mesh = p.mesh(threads=args.threads, cache=False)
                emit[n][k] = min(emit[n][k], time.perf_counter() - t0)
                sectors[n][k], verts[n][k] = mesh.sector_count, mesh.vertex_count
    b, n = names
    print(f"\n{place} ({lat}, {lon}), {len(path)}-frame descent, 1 px, template level 4, "
          f"best of {args.passes}")
    for label, fig in (("sectors summed", sectors), ("vertices summed", verts),
                       ("refine+cull s summed", refine), ("cold emission s summed", emit)):
        sb, sn = sum(fig[b]), sum(fig[n])
        ratios = [y / x for x, y in zip(fig[b], fig[n]) if x > 0 and y > 0]
        print(f"  {label:<24} {sb:>14,.3f} -> {sn:>14,.3f}  {sn / sb:5.2f}x  "
              f"(median per frame {statistics.median(ratios):5.2f}x)")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--base", required=True)
    parser.add_argument("--new", default=".")
    parser.add_argument("--base-detail", default=None)
    parser.add_argument("--new-detail", default=None)
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--passes", type=int, default=2)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--places", default="jacksboro,alps,himalaya")
    args = parser.parse_args()
    builds = {"base": load_build(args.base), "new": load_build(args.new)}
    preset = presets.detail_settings("EARTH")
    details = {"base": json.loads(args.base_detail) if args.base_detail else dict(preset),
               "new": json.loads(args.new_detail) if args.new_detail else dict(preset)}
    for place in args.places.split(","):
        fly(builds, details, place, args)


if __name__ == "__main__":
    main()
