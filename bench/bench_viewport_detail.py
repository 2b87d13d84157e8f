#!/usr/bin/env python3
"""An artist's viewport refresh with every planet preset's detail, side by
side with the same planet without detail, in one run: refine (hysteresis,
as the viewport refines) plus mesh emission (sector cache on, 2 threads)
per frame along bench_refine.py's descent scaled to each planet (from 3
radii to 2 m above its highest map point), with the add-on's viewport
quality presets (Draft, Preview: template density, pixel error, budget from
planetlod/presets.py), 1920x1080.

    /usr/bin/python3 -m bench.bench_viewport_detail [--frames 48]
        [--planets EARTH,MOON,MARS,ASTEROID] [--quality DRAFT,PREVIEW]

Per planet and quality: the slowest refresh (ms), the mean, the refreshes
over 50 ms, and the vertices of the slowest, for the two refreshes the
add-on's viewport timer runs: with the GPU preview (the default display:
refine + planet.mesh(changed_only=True) + surface.preview_update, the
sectors that changed replaced in the previous preview, uploaded and drawn by
the GPU) and with the plain mesh (refine + planet.mesh).  Writing the mesh into Blender
is not included (bench_blender.py measures that hand-off).  Not a test:
figures only.
"""
import argparse
import math
import os
import statistics
import time

import numpy

import planetlod
from planetlod import presets, surface

from bench import bench_refine

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def data_path(name):
    for folder in (os.path.join(ROOT, "data"), os.path.join(ROOT, "..", "shared", "data")):
        if os.path.exists(os.path.join(folder, name)):
            return os.path.join(folder, name)
    raise FileNotFoundError(name)


def template_level(density):
    level = 0
    while 4 ** (level + 1) <= density and level < 7:
        level += 1
    return level


def planet_for(presets, key, detail):
    s = presets.PLANETS[key]
    kw = dict(projection=s["projection"].lower(), height_scale=s["height_scale"])
    if s["heightmap"]:
        kw["heightmap"] = data_path(s["heightmap"])
    if s["use_sea_level"]:
        kw["sea_level"] = s["sea_level"]
    if detail:
        kw["detail"] = presets.detail_kwargs(s)
    p = planetlod.Planet(s["radius"], **kw)
    p.reserve(1 << 14)
    return p


def descent_matrices(radius, top, frames):
    """bench_refine's descent (Himalaya, 20,000 km to 2 m) scaled to the
    planet: the same angles, altitudes from 3 radii down; (altitude, camera
    matrix) per frame."""
    out = []
    for alt, m in bench_refine.descent(frames, terrain_top=0.0):
        eye = [m[i][3] for i in range(3)]
        d = [x / math.sqrt(sum(y * y for y in eye)) for x in eye]
        a = math.exp(math.log(3.0 * radius) * (1 - alt_t(alt)) + math.log(2.0) * alt_t(alt))
        for i in range(3):
            m[i][3] = d[i] * (radius + top + a)
        out.append((a, m))
    return out


def cameras(radius, top, frames):
    """descent_matrices as planetlod cameras (1920x1080)."""
    return [(a, planetlod.Camera(m, lens=50.0, sensor_width=36.0, resolution_x=1920,
                                 resolution_y=1080, clip_start=0.1, clip_end=1e10))
            for a, m in descent_matrices(radius, top, frames)]


def alt_t(alt):
    """The descent's parameter t in [0, 1] for its altitude."""
    return (math.log(2e7) - math.log(alt)) / (math.log(2e7) - math.log(2.0))


def preview_refresh(planet, level, previous):
    """The GPU preview's surface as the add-on's refresh makes it
    (planetlod.refresh.SurfaceWork): only the changed sectors, replaced in the previous
    preview, while the planet's last mesh was that preview's."""
    ids = numpy.frombuffer(planet.sector_ids(), numpy.uint64)
    if previous is not None and previous.serial == planet.mesh_cache_info["emissions"]:
        changed = planet.mesh(template_level=level, threads=2, changed_only=True)
        data = surface.preview_update(previous, changed, ids, (0.0, 0.0, 0.0), planet.radius)
    else:
        visible = planet.mesh(template_level=level, threads=2)
        data = surface.preview_data(visible, (0.0, 0.0, 0.0), planet.radius)
    data.serial = planet.mesh_cache_info["emissions"]
    return data


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--frames", type=int, default=48)
    parser.add_argument("--planets", default="EARTH,MOON,MARS,ASTEROID")
    parser.add_argument("--quality", default="DRAFT,PREVIEW")
    parser.add_argument("--set", default="", help="detail overrides, e.g. roughness=0.5")
    args = parser.parse_args()
    for item in filter(None, args.set.split(",")):
        name, value = item.split("=")
        for s in presets.PLANETS.values():
            s["detail_" + name] = float(value)
    print(f"{'':>26} {'GPU preview refresh':>25}   {'plain mesh refresh':>34}")
    print(f"{'planet':>9} {'quality':>8} {'detail':>6} {'max ms':>8} {'mean ms':>8} "
          f"{'>50 ms':>6}   {'max ms':>8} {'mean ms':>8} {'>50 ms':>6} {'vertices':>9}")
    for key in args.planets.split(","):
        planets = {name: planet_for(presets, key, name == "on") for name in ("off", "on")}
        top = planets["on"].height_range()[1]
        cams = cameras(presets.PLANETS[key]["radius"], top, args.frames)
        for quality in args.quality.split(","):
            q = presets.QUALITY[quality]
            level = template_level(int(q["template_density"]))
            ms = {name: [] for name in planets}
            preview_ms = {name: [] for name in planets}
            verts = {name: [] for name in planets}
            for p in planets.values():  # normal map and first arrays: not a refresh
                p.refine(cams[0][1], template_level=level)
                p.mesh(template_level=level, cache=False)
                p.reset()
            # each display on its own pass (each keeps its own sectors in
            # the mesh cache, as the add-on does)
            for preview in (True, False):
                for p in planets.values():
                    p.reset()
                kept = {name: None for name in planets}
                for _alt, cam in cams:
                    for name, p in planets.items():
                        t0 = time.perf_counter()
                        p.refine(cam, max_pixel_error=q["max_pixel_error"], budget=q["budget"],
                                 template_level=level, hysteresis=True)
                        if preview:
                            kept[name] = preview_refresh(p, level, kept[name])
                            preview_ms[name].append((time.perf_counter() - t0) * 1e3)
                        else:
                            mesh = p.mesh(template_level=level, threads=2)
                            ms[name].append((time.perf_counter() - t0) * 1e3)
                            verts[name].append(mesh.vertex_count)
            for name in planets:
                worst = max(range(len(cams)), key=lambda k: ms[name][k])
                pv = preview_ms[name]
                print(f"{key:>9} {quality:>8} {name:>6} {max(pv):>8.1f} "
                      f"{statistics.mean(pv):>8.1f} {sum(1 for x in pv if x > 50.0):>6}   "
                      f"{ms[name][worst]:>8.1f} {statistics.mean(ms[name]):>8.1f} "
                      f"{sum(1 for x in ms[name] if x > 50.0):>6} {verts[name][worst]:>9}")


if __name__ == "__main__":
    main()
