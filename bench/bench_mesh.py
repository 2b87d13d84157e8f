"""Mesh emission benchmark: M vertices/s on 1 vs 2 threads, bytes per vertex.

    /usr/bin/python3 -m bench.bench_mesh [--repeat N] [--no-map]

Refines an Earth-radius planet (sphere, then the Earth topology map resampled
to a 1024 cube map with 20 km relief scale... heights in metres) for a camera
at 10 km altitude, then times planet.mesh() (every output: positions,
normals, uv, morph, triangles, sector_level, face) at template levels 4..7,
best of N runs, without the sector cache (every vertex computed: "cold").
Then the flyby: bench_refine.py's descent (20,000 km to 2 m, 240 frames,
1 px, template level 4), each frame's mesh() with the sector cache (the
default: sectors kept from the previous frame are copied) and without,
interleaved frame by frame.  Prints tables; target >= 50 M vertices/s on
2 threads.  --c adds the same two measurements at C level (bench_mesh_c.c).
"""
import argparse
import glob
import os
import shutil
import subprocess
import tempfile
import time

import planetlod
from bench.bench_refine import look_at

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def best_time(fn, repeat):
    best = float("inf")
    result = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - t0)
    return best, result


def bytes_per_vertex(mesh):
    total = sum(len(getattr(mesh, name)) * 4 for name in
                ("positions", "normals", "uv", "morph", "triangles", "sector_level", "face"))
    return total / max(1, mesh.vertex_count)


def c_emission(topo):
    """Builds bench_mesh_c.c against the core (setup.py's flags) and returns
    its table: plod_session_emit into buffers allocated once and reused."""
    cc = shutil.which("gcc") or shutil.which("cc")
    if not cc:
        return "(no C compiler: C-level table skipped)"
    cext = os.path.join(ROOT, "cext")
    sources = [p for p in sorted(glob.glob(os.path.join(cext, "*.c")))
               if not os.path.basename(p).startswith(("py_", "pymodule"))]
    sources.append(os.path.join(ROOT, "bench", "bench_mesh_c.c"))
    with tempfile.TemporaryDirectory() as tmp:
        args = []
        if topo:  # the core decodes no PNG: channel 0 as a headerless grid
            from planetlod import imageio
            width, height, _, dtype, pixels = imageio.read(topo)
            grid = os.path.join(tmp, "map.raw")
            pixels[:, :, 0].astype("<" + pixels.dtype.str[1:]).tofile(grid)
            args = [grid, str(width), str(height), dtype]
        objects = []
        for src in sources:
            obj = os.path.join(tmp, os.path.basename(src) + ".o")
            subprocess.run([cc, "-std=c11", "-O2", "-ffp-contract=off", "-D_POSIX_C_SOURCE=200809L",
                            "-I", cext, "-c", src, "-o", obj], check=True)
            objects.append(obj)
        exe = os.path.join(tmp, "bench_mesh_c")
        subprocess.run([cc] + objects + ["-lm", "-lpthread", "-o", exe], check=True)
        return subprocess.run([exe] + args, check=True,
                              capture_output=True, text=True).stdout.rstrip()


def flyby(planet, frames):
    """Planet.mesh() along bench_refine's descent, with and without the
    sector cache, interleaved per frame."""
    from bench import bench_refine
    lo, hi = planet.height_range()
    print(f"\nflyby: bench_refine.py's descent, {frames} frames, 1 px 1920x1080, template "
          "level 4, Planet.mesh() with the sector cache vs without, interleaved")
    print(f"{'thr':>4} {'vertices':>10} {'uncached':>9} {'cached':>9} {'ratio':>6} {'hit rate':>8}")
    for threads in (1, 2):
        planet.reset()
        t_plain = t_cached = 0.0
        vertices = hits = misses = 0
        for _alt, m in bench_refine.descent(frames, terrain_top=hi):
            cam = planetlod.Camera(m, lens=50.0, sensor_width=36.0, resolution_x=1920,
                                   resolution_y=1080, clip_start=0.1, clip_end=1e9)
            planet.refine(cam, template_level=4, max_level=24)
            t0 = time.perf_counter()
            plain = planet.mesh(threads=threads, cache=False)
            t1 = time.perf_counter()
            planet.mesh(threads=threads)
            t2 = time.perf_counter()
            info = planet.mesh_cache_info
            t_plain += t1 - t0
            t_cached += t2 - t1
            vertices += plain.vertex_count
            hits += info["hits"]
            misses += info["misses"]
        print(f"{threads:>4} {vertices:>10} {vertices / t_plain / 1e6:>9.1f} "
              f"{vertices / t_cached / 1e6:>9.1f} {t_plain / t_cached:>5.2f}x "
              f"{100.0 * hits / max(1, hits + misses):>7.1f}%")
    print("(M vertices/s over the whole path; the cache holds one frame's sectors, "
          f"{planet.mesh_cache_info['bytes'] / 2**20:.0f} MiB at the last frame)")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--no-map", action="store_true")
    parser.add_argument("--levels", default="4,5,6,7")
    parser.add_argument("--frames", type=int, default=240, help="flyby frames")
    parser.add_argument("--c", action="store_true",
                        help="also the C-level table (reused buffers, no Python)")
    args = parser.parse_args()
    radius = 6371e3
    planets = [("sphere", planetlod.Planet(radius))]
    topo = os.path.join(ROOT, "data", "earth-topology.png")
    if not args.no_map and os.path.exists(topo):
        cube = planetlod.CubeMap.from_image(topo, projection="qsc", size=1024)
        planets.append(("earth-topology", planetlod.Planet(radius, heightmap=cube,
                                                           height_scale=8848.0)))
    camera = planetlod.Camera(look_at((radius + 10e3, 0.0, 0.0), (radius, 50e3, 20e3), (0.0, 0.0, 1.0)))
    print(f"{'planet':>15} {'tl':>3} {'sectors':>8} {'vertices':>10} {'thr':>4} "
          f"{'ms':>8} {'Mvert/s':>8} {'morph Mv/s':>10} {'B/vert':>7}")
    for name, planet in planets:
        planet.refine(camera, backface=False, frustum=False)
        for tl in (int(x) for x in args.levels.split(",")):
            for threads in (1, 2):
                dt, mesh = best_time(lambda: planet.mesh(template_level=tl, threads=threads,
                                                         cache=False), args.repeat)
                dtm, _ = best_time(lambda: planet.mesh(template_level=tl, threads=threads,
                                                       morph=True, cache=False), args.repeat)
                rate = mesh.vertex_count / dt / 1e6
                mrate = mesh.vertex_count / dtm / 1e6
                print(f"{name:>15} {tl:>3} {mesh.sector_count:>8} {mesh.vertex_count:>10} "
                      f"{threads:>4} {dt * 1e3:>8.2f} {rate:>8.1f} {mrate:>10.1f} "
                      f"{bytes_per_vertex(mesh):>7.1f}")
    print("(cold: no sector cache; all outputs written; fresh output buffers allocated inside "
          "each call (first-touch page faults included); target >= 50 M vertices/s on 2 threads)")
    if len(planets) > 1:
        flyby(planets[1][1], args.frames)
    if args.c:
        print("\nC level (plod_session_emit, buffers allocated once and reused, best of 5):")
        print(c_emission(None if args.no_map or not os.path.exists(topo) else topo))


if __name__ == "__main__":
    main()
