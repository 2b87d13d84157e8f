#!/usr/bin/env python3
"""Two builds of planetlod side by side in one process, frame by frame:
refine+cull with and without the detail field (as bench_detail.py); the
same with detail, each build flying whole descents alone, in turns; the
detail field's emission (cold and flyby, the Earth preset along
bench_refine.py's descent, as bench_detail.py) and an artist's viewport
refresh with the GPU preview (refine with hysteresis + mesh() +
surface.preview_data, per planet preset, as bench_viewport_detail.py); the
sector-cached emission along the whole refine descent, frames below the
25 M vertices/s target and their page faults (after the first-touch cost
of a page, bench/page_fault_cost.c).

    /usr/bin/python3 -m bench.bench_detail_builds --base DIR [--new DIR]
        [--refine-frames 240] [--refine-threads 1] [--passes 2]
        [--frames 48] [--viewport-frames 16] [--threads 2]
        [--planets EARTH,MOON,MARS,ASTEROID] [--quality PREVIEW]

--base and --new are folders holding a planetlod build (the new one
defaults to this checkout).  Both modules are loaded into one process
(each its own copy of the library), and every frame runs the base, then
the new build (descent by descent for the lone descents), so load from
other tasks falls on both alike.  Per measure:
the median and mean over the frames of each build and the median of the
per-frame ratios base / new.  Before and after, one cache line's round
trip between CPUs 0 and 1 (bench/core_latency.c): on a shared VM the two
vCPUs are sometimes close, sometimes far apart, and threaded figures move
with it.  --base-detail JSON gives the base build the Earth detail of its
own presets (a dict as planetlod.Planet(detail=...) takes it; default:
this checkout's), so a change of the preset's detail is measured with its
cost.  Not a test: figures only.
"""
import argparse
import importlib.machinery
import json
import importlib.util
import math
import os
import resource
import shutil
import statistics
import subprocess
import tempfile
import time

from bench import bench_refine
from bench.bench_viewport_detail import descent_matrices
from planetlod import presets, surface

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

R = 6371000.0


def load_build(folder):
    """The C extension of the checkout or build in `folder`, under a name of
    its own, so two builds live in one process: the package's
    planetlod/_native.abi3.so, or an older build's planetlod.abi3.so (a
    module of its own, before the package)."""
    folder = os.path.abspath(folder)
    for relative, name in ((os.path.join("planetlod", "_native.abi3.so"), "_native"),
                           ("planetlod.abi3.so", "planetlod")):
        path = os.path.join(folder, relative)
        if os.path.exists(path):
            # the init function is named after the module's last component
            loader = importlib.machinery.ExtensionFileLoader(
                f"bench_build_{len(LOADED)}.{name}", path)
            module = importlib.util.module_from_spec(importlib.util.spec_from_loader(
                loader.name, loader))
            loader.exec_module(module)
            LOADED.append(module)
            return module
    raise SystemExit(f"no planetlod build in {folder}")


LOADED = []


class BuildPresets:
    """The presets a build runs with: this checkout's, with the Earth
    preset's detail replaced by `earth_detail` when given."""

    def __init__(self, earth_detail=None):
        self.PLANETS, self.QUALITY = presets.PLANETS, presets.QUALITY
        self.earth_detail = earth_detail

    def detail_settings(self, key):
        if key == "EARTH" and self.earth_detail is not None:
            return dict(self.earth_detail)
        return presets.detail_settings(key)

    def detail_kwargs(self, settings):
        if settings is presets.PLANETS["EARTH"] and self.earth_detail is not None:
            return dict(self.earth_detail)
        return presets.detail_kwargs(settings)


def run_probe(folder, name, flags=()):
    """Builds bench/NAME.c into `folder` (once) and runs it: the line it
    prints, or why there is none."""
    exe = os.path.join(folder, name)
    if not os.path.exists(exe):
        cc = shutil.which("gcc") or shutil.which("cc")
        if not cc:
            return "(no C compiler)"
        built = subprocess.run([cc, "-std=c11", "-O2", "-o", exe,
                                os.path.join(ROOT, "bench", name + ".c"), *flags],
                               capture_output=True, text=True)
        if built.returncode != 0:
            return f"({name}.c did not build)"
    run = subprocess.run([exe], capture_output=True, text=True)
    return run.stdout.strip() or "(no result)"


def core_round_trip(folder):
    """One cache line's round trip between CPUs 0 and 1 (bench/core_latency.c):
    how far apart the two threads of the measures sit on a shared machine."""
    return run_probe(folder, "core_latency", ("-lpthread",))


def data_path(name):
    for folder in (os.path.join(ROOT, "data"), os.path.join(ROOT, "..", "shared", "data")):
        if os.path.exists(os.path.join(folder, name)):
            return os.path.join(folder, name)
    raise FileNotFoundError(name)


def camera(lod, m):
    return lod.Camera(m, lens=50.0, sensor_width=36.0, resolution_x=1920, resolution_y=1080,
                      clip_start=0.1, clip_end=1e10)


def report(title, unit, figures, higher_is_better):
    base, new = figures["base"], figures["new"]
    ratios = [(n / b if higher_is_better else b / n) for b, n in zip(base, new) if b > 0 and n > 0]
    print(f"{title:<44} {unit:>10}: base median {statistics.median(base):9.2f} "
          f"mean {statistics.mean(base):9.2f} | new median {statistics.median(new):9.2f} "
          f"mean {statistics.mean(new):9.2f} | speed-up per frame, median "
          f"{statistics.median(ratios):5.2f}x")


def earth_planets(builds, presets):
    """A planet per build: the Earth map and preset's detail, refiner room
    reserved, a sector cache of 1 GiB (nothing evicted along a descent)."""
    planets = {name: lod.Planet(R, heightmap=data_path("earth-topology.png"),
                                height_scale=8848.0, sea_level=0.0,
                                detail=presets[name].detail_settings("EARTH"))
               for name, lod in builds.items()}
    for p in planets.values():
        p.reserve(1 << 16)
        p.mesh_cache_max_bytes = 1 << 30
    return planets


def emission(builds, presets, args):
    planets = earth_planets(builds, presets)
    top = planets["base"].height_range()[1]
    path = bench_refine.descent(args.frames, terrain_top=top)
    cold = {name: [] for name in builds}
    flyby = {name: [] for name in builds}
    for _alt, m in path:
        for name, lod in builds.items():
            p = planets[name]
            p.refine(camera(lod, m), template_level=4, max_level=48)
            t0 = time.perf_counter()
            mesh = p.mesh(threads=args.threads, cache=False)
            t1 = time.perf_counter()
            p.mesh(threads=args.threads)
            t2 = time.perf_counter()
            cold[name].append(mesh.vertex_count / (t1 - t0) / 1e6)
            flyby[name].append(mesh.vertex_count / (t2 - t1) / 1e6)
    print(f"Earth preset's detail, {args.frames}-frame descent, 1 px, template level 4, "
          f"{args.threads} threads")
    report("emission, cold (mesh(cache=False))", "M vert/s", cold, True)
    report("emission, flyby (sector cache)", "M vert/s", flyby, True)


GROUND_FROM = 184 / 240  # where bench_refine.py's descent is below ~70 m


def flyby(builds, presets, args):
    """The sector-cached emission along the refine descent (--refine-frames,
    240), --passes passes with fresh planets, both builds frame by frame
    (each first every other frame): the frames below the 25 M vertices/s
    target per pass, which ones and how often, with the minor page faults
    of their mesh() (first touches of memory: a growing mesh and sector
    cache fault their new pages in, ~1.5 us a 4 KB page on this VM)."""
    below = {name: [] for name in builds}
    slow = {name: {} for name in builds}
    rates = {name: [[] for _ in range(args.refine_frames)] for name in builds}
    faults = {name: [] for name in builds}
    for _ in range(args.passes):
        planets = earth_planets(builds, presets)
        top = planets["base"].height_range()[1]
        path = list(bench_refine.descent(args.refine_frames, terrain_top=top))
        count = {name: 0 for name in builds}
        faulted = {name: 0 for name in builds}
        meshes = {}
        for k, (_alt, m) in enumerate(path):
            order = list(builds.items())
            for name, lod in (order if k % 2 == 0 else order[::-1]):
                p = planets[name]
                p.refine(camera(lod, m), template_level=4, max_level=48, threads=args.threads)
                f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
                t0 = time.perf_counter()
                mesh = p.mesh(threads=args.threads)
                t = time.perf_counter() - t0
                f = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0
                meshes[name] = mesh  # the frame before's freed now, untimed
                rate = mesh.vertex_count / t / 1e6
                rates[name][k].append(rate)
                faulted[name] += f
                if rate < 25.0:
                    count[name] += 1
                    seen, most = slow[name].get(k, (0, 0))
                    slow[name][k] = (seen + 1, max(most, f))
        for name in builds:
            below[name].append(count[name])
            faults[name].append(faulted[name])
    print(f"\nEarth preset's detail, {args.refine_frames}-frame descent, mesh() with the sector "
          f"cache, {args.threads} threads, {args.passes} passes")
    for name in builds:
        median = [statistics.median(r) for r in rates[name]]
        ground = median[int(GROUND_FROM * len(median)):]
        print(f"{name}: per-frame median {statistics.median(median):.1f} M vert/s (the ground, "
              f"below ~70 m: {statistics.median(ground):.1f}); frames below 25 M/s per "
              f"pass {below[name]} (median {statistics.median(below[name])}); "
              f"page faults in mesh() per pass {faults[name]}")
        print("    frame: passes below, most faults in that mesh(): " +
              ", ".join(f"{k}: {n}, {f}" for k, (n, f) in sorted(slow[name].items())))


def refine(builds, presets, args):
    """Refine+cull per frame (the refiner's own timers) along bench_refine.py's
    descent, 1 px, template level 4, with the Earth preset's detail and
    without detail; per frame the best of --passes descents.  The two builds
    must refine alike: every frame's sector counts, splits and merges are
    compared."""
    keys = ("sectors_total", "sectors_after_frustum", "sectors_after_budget", "splits", "merges")
    for label, on in (("detail on", True), ("detail off", False)):
        planets = {name: lod.Planet(R, heightmap=data_path("earth-topology.png"),
                                    height_scale=8848.0, sea_level=0.0,
                                    detail=presets[name].detail_settings("EARTH") if on else None)
                   for name, lod in builds.items()}
        for p in planets.values():
            p.reserve(1 << 16)
        top = planets["base"].height_range()[1]
        path = list(bench_refine.descent(args.refine_frames, terrain_top=top))
        cams = {name: [camera(lod, m) for _alt, m in path] for name, lod in builds.items()}
        best = {name: [float("inf")] * len(path) for name in builds}
        counts = {name: [None] * len(path) for name in builds}
        for _ in range(args.passes):
            for p in planets.values():
                p.reset()
            for k in range(len(path)):
                for name in builds:
                    s = planets[name].refine(cams[name][k], template_level=4, max_level=48,
                                             threads=args.refine_threads)
                    best[name][k] = min(best[name][k], s["refine_us"] + s["cull_us"])
                    counts[name][k] = tuple(s[key] for key in keys)
        differ = sum(1 for a, b in zip(counts["base"], counts["new"]) if a != b)
        print(f"\nrefine+cull, {label}, {len(path)}-frame descent, 1 px, template level 4, "
              f"{args.refine_threads} thread(s), per frame the best of {args.passes}; frames "
              f"whose counts differ between the builds: {differ}")
        report(f"refine+cull, {label}", "µs", best, False)
        for name in builds:
            us = best[name]
            print(f"{'':<44} {name:>10}: slowest {max(us):7.0f} µs, over 1 ms "
                  f"{sum(1 for x in us if x > 1000.0)} of {len(us)}")


def refine_alone(builds, presets, args):
    """Refine+cull with detail as above, but each build flies whole descents
    by itself, the builds taking turns descent by descent: a frame's time
    without the other planet's data in the caches between frames (and with
    the workers of threads >= 2 as a lone planet keeps them)."""
    best = {}
    for name, lod in builds.items():
        planet = lod.Planet(R, heightmap=data_path("earth-topology.png"), height_scale=8848.0,
                            sea_level=0.0, detail=presets[name].detail_settings("EARTH"))
        planet.reserve(1 << 16)
        top = planet.height_range()[1]
        path = list(bench_refine.descent(args.refine_frames, terrain_top=top))
        best[name] = (planet, [camera(lod, m) for _alt, m in path], [float("inf")] * len(path))
    for _ in range(args.passes):
        for name, (planet, cams, us) in best.items():
            planet.reset()
            for k, cam in enumerate(cams):
                s = planet.refine(cam, template_level=4, max_level=48, threads=args.refine_threads)
                us[k] = min(us[k], s["refine_us"] + s["cull_us"])
    figures = {name: us for name, (_p, _c, us) in best.items()}
    print(f"\nrefine+cull, detail on, each build alone, {args.refine_threads} thread(s), per "
          f"frame the best of {args.passes} descents")
    report("refine+cull alone, detail on", "µs", figures, False)
    for name, us in figures.items():
        print(f"{'':<44} {name:>10}: slowest {max(us):7.0f} µs, over 1 ms "
              f"{sum(1 for x in us if x > 1000.0)} of {len(us)}")


def viewport(builds, presets, surface, args):
    print(f"\nviewport refresh with the GPU preview (refine with hysteresis + mesh() + "
          f"preview_data), {args.viewport_frames}-frame descents from 3 radii to 2 m")
    for key in args.planets.split(","):
        s = presets["new"].PLANETS[key]
        for quality in args.quality.split(","):
            q = presets["new"].QUALITY[quality]
            level = 0  # as bench_viewport_detail.py: 4^level <= density
            while 4 ** (level + 1) <= int(q["template_density"]) and level < 7:
                level += 1
            planets = {}
            for name, lod in builds.items():
                s = presets[name].PLANETS[key]
                kw = dict(projection=s["projection"].lower(), height_scale=s["height_scale"],
                          detail=presets[name].detail_kwargs(s))
                if s["heightmap"]:
                    kw["heightmap"] = data_path(s["heightmap"])
                if s["use_sea_level"]:
                    kw["sea_level"] = s["sea_level"]
                planets[name] = lod.Planet(s["radius"], **kw)
                planets[name].reserve(1 << 14)
            top = planets["base"].height_range()[1]
            ms = {name: [] for name in builds}
            for k, (_alt, m) in enumerate(descent_matrices(s["radius"], top, args.viewport_frames)):
                for name, lod in builds.items():
                    p = planets[name]
                    t0 = time.perf_counter()
                    p.refine(camera(lod, m), max_pixel_error=q["max_pixel_error"],
                             budget=q["budget"], template_level=level, hysteresis=True)
                    visible = p.mesh(template_level=level, threads=args.threads)
                    surface.preview_data(visible, (0.0, 0.0, 0.0), p.radius)
                    ms[name].append((time.perf_counter() - t0) * 1e3)
            report(f"{key} {quality}", "ms", ms, False)
            for name in builds:
                print(f"{'':<44} {name:>10}: slowest {max(ms[name]):7.1f} ms, over 50 ms "
                      f"{sum(1 for x in ms[name] if x > 50.0)} of {len(ms[name])}")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--base", required=True, help="folder of the base build")
    parser.add_argument("--new", default=ROOT, help="folder of the new build")
    parser.add_argument("--base-detail", default="",
                        help="JSON: the base build's Earth detail (its presets')")
    parser.add_argument("--frames", type=int, default=48)
    parser.add_argument("--viewport-frames", type=int, default=16)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--planets", default="EARTH,MOON,MARS,ASTEROID")
    parser.add_argument("--quality", default="PREVIEW")
    parser.add_argument("--refine-frames", type=int, default=240)
    parser.add_argument("--refine-threads", type=int, default=1)
    parser.add_argument("--passes", type=int, default=2, help="descents per build (refine, flyby)")
    parser.add_argument("--skip", default="",
                        help="measures to leave out: 'refine', 'alone', 'emission', "
                             "'flyby', 'viewport', comma-separated")
    args = parser.parse_args()
    builds = {"base": load_build(args.base), "new": load_build(args.new)}
    base_detail = json.loads(args.base_detail) if args.base_detail else None
    build_presets = {"base": BuildPresets(base_detail), "new": BuildPresets()}
    for name, lod in builds.items():
        print(f"{name}: {lod.__file__}")
    skip = set(args.skip.split(","))
    with tempfile.TemporaryDirectory() as tmp:
        print(f"CPUs 0 and 1 before: {core_round_trip(tmp)}")
        if "refine" not in skip:
            refine(builds, build_presets, args)
        if "alone" not in skip:
            refine_alone(builds, build_presets, args)
        if "emission" not in skip:
            emission(builds, build_presets, args)
        if "flyby" not in skip:
            print(f"\nThis machine's {run_probe(tmp, 'page_fault_cost')}")
            flyby(builds, build_presets, args)
        if "viewport" not in skip:
            viewport(builds, build_presets, surface, args)
        print(f"\nCPUs 0 and 1 after: {core_round_trip(tmp)}")


if __name__ == "__main__":
    main()
