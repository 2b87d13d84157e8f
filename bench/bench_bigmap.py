#!/usr/bin/env python3
"""Resident memory of a global 86400 x 43200 16-bit height map (the size of
NASA's global 500 m products; 7.5 GB of samples, 14x the in-memory cap)
flown along bench_refine.py's descent, through planetlod.TiledMap.

    /usr/bin/python3 -m bench.bench_bigmap [--width 86400] [--frames 240]
        [--cache DIR] [--cache-mb 256] [--template-level 4] [--threads 2]
        [--every 20]

The map is generated once (procedural relief, 16-bit little-endian .r16) in
--cache (default $PLANETLOD_BENCH_CACHE, else ~/.cache/planetlod-bench) and
its tile file written once next to it; later runs reuse both.  Then, for
every frame of the descent (20,000 km to 2 m over the Himalaya, 1 px at
1920x1080), refine() and mesh() (sector cache on, as in a flyby), printing
the process's resident set (VmRSS) every --every frames, its peak (VmHWM,
reset after the set-up where the kernel allows), the tile cache's bytes and
refine / mesh milliseconds.  Not a test: figures only.
"""
import argparse
import math
import os
import sys
import time

import numpy as np

import planetlod
from bench.bench_refine import R, cameras

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def status_kb(field):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    return 0


def reset_peak():
    """Resets VmHWM to the current RSS (Linux >= 4.0); False if refused."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def earth_rows():
    """The bundled Earth topology (2048 x 1024, 8-bit, north row first) as
    float metres over 0..8848."""
    car = planetlod.CubeMap.from_image(os.path.join(ROOT, "data", "earth-topology.png"),
                                       projection="car", size=1024, filter="nearest")
    cols, rows = car.face_shape
    texels = np.frombuffer(bytes(car.face(0)), np.uint8).reshape(rows, cols)[::-1]
    return texels.astype(np.float64) / 255.0


def generate(path, width):
    """An Earth-like 16-bit global map written a band of rows at a time
    (memory: one band and the noise rows): the bundled Earth topology
    resampled bilinearly to width x width/2, plus a periodic 1024 x 1024
    block of smooth noise (+-2 % of the range, more on high ground) for
    relief at every texel."""
    height = width // 2
    source = earth_rows()
    sh, sw = source.shape
    rng = np.random.default_rng(2026)
    fine = np.kron(rng.random((64, 64)), np.ones((16, 16)))
    for _ in range(3):  # smooth, periodic
        fine = 0.25 * (np.roll(fine, 1, 0) + np.roll(fine, -1, 0) + np.roll(fine, 1, 1) +
                       np.roll(fine, -1, 1))
    fine = (fine - fine.min()) / (fine.max() - fine.min()) - 0.5
    reps = -(-width // 1024)
    noise = np.tile(fine, (1, reps))[:, :width].astype(np.float32)
    # every source row resampled to the output width once (float32,
    # wrapping in longitude); an output row is then a blend of two of them
    x = (np.arange(width) + 0.5) * sw / width - 0.5
    x0 = np.floor(x).astype(np.int64)
    wx = (x - x0).astype(np.float32)
    x1 = (x0 + 1) % sw
    x0 %= sw
    wide = np.empty((sh, width), np.float32)
    for r in range(sh):
        row = source[r].astype(np.float32)
        wide[r] = row[x0] + wx * (row[x1] - row[x0])
    tmp = str(path) + ".partial"
    value = np.empty(width, np.float32)
    with open(tmp, "wb") as out:
        for y in range(height):
            t = (y + 0.5) * sh / height - 0.5
            r0 = min(max(int(math.floor(t)), 0), sh - 1)
            r1 = min(r0 + 1, sh - 1)
            wy = np.float32(t - math.floor(t))
            np.subtract(wide[r1], wide[r0], out=value)
            value *= wy
            value += wide[r0]
            value += noise[y % 1024] * (np.float32(0.01) + np.float32(0.05) * value)
            np.clip(value * np.float32(65535.0), 0, 65535, out=value)
            out.write(value.astype("<u2").tobytes())
    os.replace(tmp, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=86400)
    ap.add_argument("--frames", type=int, default=240)
    ap.add_argument("--every", type=int, default=20)
    ap.add_argument("--cache", default=os.environ.get(
        "PLANETLOD_BENCH_CACHE", os.path.join(os.path.expanduser("~"), ".cache",
                                              "planetlod-bench")))
    ap.add_argument("--cache-mb", type=int, default=128, help="TiledMap tile cache (MiB)")
    ap.add_argument("--template-level", type=int, default=4)
    ap.add_argument("--threads", type=int, default=2, help="mesh() threads")
    ap.add_argument("--no-mesh", action="store_true",
                    help="refine only (the map's own footprint: no mesh buffers)")
    ap.add_argument("--mesh-cache-mb", type=int, default=256,
                    help="planet.mesh_cache_max_bytes (MiB; the add-on's default 256)")
    args = ap.parse_args()
    os.makedirs(args.cache, exist_ok=True)
    width, height = args.width, args.width // 2
    path = os.path.join(args.cache, f"earthlike-{width}x{height}.r16")
    print(f"planetlod big-map benchmark; python {sys.version.split()[0]}; "
          f"{os.cpu_count()} cpus; map {width}x{height} u16 ({width * height * 2 / 2**30:.2f} GiB)")
    print(f"RSS at start: {status_kb('VmRSS') / 1024:.0f} MiB")
    if not os.path.exists(path):
        t = time.perf_counter()
        generate(path, width)
        print(f"generated {path} in {time.perf_counter() - t:.0f} s")
    t = time.perf_counter()
    last = [0.0]

    def progress(fraction):
        if fraction - last[0] >= 0.1 or fraction == 1.0:
            last[0] = fraction
            print(f"  tiling {fraction:4.0%}  {time.perf_counter() - t:5.0f} s", flush=True)

    tiled = planetlod.TiledMap(path, cache_bytes=args.cache_mb << 20, progress=progress)
    print(f"TiledMap ready in {time.perf_counter() - t:.1f} s ({tiled.tiles_path}, "
          f"{os.path.getsize(tiled.tiles_path) / 2**30:.2f} GiB); RSS "
          f"{status_kb('VmRSS') / 1024:.0f} MiB")
    planet = planetlod.Planet(R, projection="qsc", heightmap=tiled, height_scale=8848.0,
                              sea_level=0.0)
    planet.reserve(16384)
    planet.mesh_cache_max_bytes = args.mesh_cache_mb << 20
    lo, hi = planet.height_range()
    cams = cameras(planet, args.frames, terrain_top=hi)
    peak_reset = reset_peak()
    base = status_kb("VmRSS")
    print(f"heights {lo:.0f}..{hi:.0f} m; texel {planet.texel_size(1, 0, 0):.0f} m; RSS before "
          f"the descent {base / 1024:.0f} MiB (peak reset: {peak_reset})")
    print(f"{'frame':>5} {'altitude':>12} {'sectors':>8} {'vertices':>9} {'refine ms':>9} "
          f"{'mesh ms':>8} {'RSS MiB':>8} {'tiles MiB':>9} {'mesh MiB':>8} {'mcache':>6} "
          f"{'refiner':>7}")
    worst = 0
    refine_ms, mesh_ms = [], []
    for k, (alt, cam) in enumerate(cams):
        t0 = time.perf_counter()
        stats = planet.refine(cam, max_pixel_error=1.0, template_level=args.template_level)
        t1 = time.perf_counter()
        mesh = None if args.no_mesh else planet.mesh(threads=args.threads)
        t2 = time.perf_counter()
        mesh_bytes = 0 if mesh is None else sum(
            memoryview(getattr(mesh, name)).nbytes
            for name in ("positions", "normals", "uv", "triangles", "sector_level", "face",
                         "morph")) if k % args.every == 0 or k == len(cams) - 1 else 0
        refine_ms.append((t1 - t0) * 1e3)
        mesh_ms.append((t2 - t1) * 1e3)
        rss = status_kb("VmRSS")
        worst = max(worst, rss)
        if k % args.every == 0 or k == len(cams) - 1:
            print(f"{k:5d} {alt:12.1f} {stats['sectors_after_budget']:8d} "
                  f"{stats['vertices']:9d} {refine_ms[-1]:9.2f} {mesh_ms[-1]:8.1f} "
                  f"{rss / 1024:8.0f} {tiled.cached_bytes / 2**20:9.0f} "
                  f"{mesh_bytes / 2**20:8.0f} {planet.mesh_cache_info['bytes'] / 2**20:6.0f} "
                  f"{planet.memory_bytes / 2**20:7.0f}", flush=True)
        del mesh
    print(f"descent: RSS max over frames {worst / 1024:.0f} MiB, peak (VmHWM) "
          f"{status_kb('VmHWM') / 1024:.0f} MiB; tile cache {tiled.cached_bytes / 2**20:.0f} of "
          f"{tiled.cache_bytes / 2**20:.0f} MiB; read errors {tiled.read_errors}")
    print(f"refine ms/frame mean {np.mean(refine_ms):.2f} max {max(refine_ms):.2f}; mesh ms/frame "
          f"mean {np.mean(mesh_ms):.1f} max {max(mesh_ms):.1f}")


if __name__ == "__main__":
    main()
