"""One hash of everything the core outputs along a descent, per planet preset.

    /usr/bin/python3 -m tools.descent_hash [--frames N] [--presets EARTH,MOON,...]

Flies bench/bench_refine.py's descent (20,000 km to 2 m, 1 px, 1920x1080)
over each planet preset (its maps, sea and detail field, and once more with
the detail off) with a budget of 8,000 sectors, refining incrementally with hysteresis as the viewport does
and without it as renders do, and hashes per frame: the refine stats that
are results (not timings), the visible sector ids and levels, every buffer
of mesh() (with the sector cache, morph on, 2 threads) and of instances().
Prints one SHA-256 per preset and configuration and one over all of them:
two builds whose lines agree emit the same bytes.  Used to check that a
change of structure changes no output.
"""
import argparse
import hashlib
import os

import planetlod
from bench.bench_refine import descent
from planetlod import presets

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

TIMING_KEYS = ("refine_us", "cull_us", "us", "cpu_us")
MESH_BUFFERS = ("origin", "positions", "normals", "uv", "triangles", "sector_level",
                "face", "morph", "detail")


def data_path(name):
    for folder in (os.path.join(ROOT, "data"), os.path.join(os.path.dirname(ROOT), "shared", "data")):
        path = os.path.join(folder, name)
        if os.path.exists(path):
            return path
    raise FileNotFoundError(name)


def build(key, detail):
    s = presets.planet_settings(key, data_path)
    kwargs = dict(projection=s["projection"].lower(), height_scale=float(s["height_scale"]))
    if s["heightmap"]:
        kwargs["heightmap"] = s["heightmap"]
    if s.get("use_sea_level"):
        kwargs["sea_level"] = float(s["sea_level"])
    if detail:
        kwargs["detail"] = presets.detail_kwargs(s)
    return planetlod.Planet(float(s["radius"]), **kwargs)


def camera(planet, matrix):
    cam = planetlod.Camera(matrix, lens=50.0, sensor_width=36.0, resolution_x=1920,
                           resolution_y=1080, clip_start=0.1, clip_end=1e12)
    near, far = planet.recommended_clip(cam)
    return planetlod.Camera(matrix, lens=50.0, sensor_width=36.0, resolution_x=1920,
                            resolution_y=1080, clip_start=near, clip_end=far)


def feed(h, value):
    h.update(bytes(memoryview(value).cast("B")) if not isinstance(value, (bytes, str))
             else (value.encode() if isinstance(value, str) else value))


def fly(key, detail, frames, hysteresis):
    planet = build(key, detail)
    h = hashlib.sha256()
    top = planet.height_range()[1]
    radius = planet.radius
    # 20,000 km (or 3 radii) to 2 m
    for _alt, matrix in descent(frames, terrain_top=top, radius=radius,
                                start=min(2e7, 3.0 * radius)):
        stats = planet.refine(camera(planet, matrix), max_pixel_error=1.0, template_level=4,
                              hysteresis=hysteresis, max_level=48,
                              budget=8000)
        feed(h, repr(sorted((k, v) for k, v in dict(stats).items() if k not in TIMING_KEYS)))
        feed(h, planet.sector_ids())
        feed(h, planet.sector_levels())
        mesh = planet.mesh(template_level=3, morph=True, threads=2)
        for name in MESH_BUFFERS:
            value = getattr(mesh, name)
            feed(h, repr(tuple(value)) if isinstance(value, tuple) else value)
        for name, value in sorted(planet.instances(template_level=2).items()):
            feed(h, name)
            feed(h, repr(value) if isinstance(value, (tuple, float, int)) else value)
    return h.hexdigest()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--presets", default=",".join(presets.PLANETS))
    args = ap.parse_args()
    total = hashlib.sha256()
    for key in args.presets.split(","):
        for detail in (True, False):
            for hysteresis in (True, False):
                digest = fly(key, detail, args.frames, hysteresis)
                total.update(digest.encode())
                print(f"{key:9s} detail={'on ' if detail else 'off'} "
                      f"hysteresis={'on ' if hysteresis else 'off'} {digest}", flush=True)
    print(f"all {total.hexdigest()}")


if __name__ == "__main__":
    main()
