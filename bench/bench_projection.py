"""Projection benchmark: QSC forward+inverse points/s on one
core through the vectorised C path, plus round-trip errors and cell-area
ratios for every mapping.  Prints a table; asserts nothing about speed.

    /usr/bin/python3 -m bench.bench_projection [--points N] [--area-n 512]

Throughput is timed (thread CPU time, best of 5) around one Python call over
a large array, so the per-call overhead (input copy, output allocation) is
amortised; the calls run on one thread.  "lon/lat" is sphere_to_cube /
cube_to_sphere in degrees; "dir" is dirs_to_faces / faces_to_dirs (unit
vectors <-> face u, v: the path the cube map and mesh code use).
"fwd+inv" is points/s for a point taken forward and back.  Needs numpy.
"""
import argparse
import math
import os
import platform
import shutil
import subprocess
import tempfile
import time

import numpy as np

import planetlod

from tests.test_projection import angle_deg, area_ratio, lonlat_to_vec, sphere_points

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def best_of(fn, repeats=5):
    best = math.inf
    for _ in range(repeats):
        t0 = time.thread_time()  # CPU time: robust on a shared machine
        fn()
        best = min(best, time.thread_time() - t0)
    return best


def throughput(proj, n):
    rng = np.random.default_rng(1)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    lon = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    lat = np.degrees(np.arcsin(np.clip(d[:, 2], -1, 1)))
    x, y = planetlod.sphere_to_cube(proj, lon, lat)
    faces, u, v = planetlod.dirs_to_faces(proj, d.ravel())
    flat = d.ravel()
    t_s2x = best_of(lambda: planetlod.sphere_to_cube(proj, lon, lat))
    t_x2s = best_of(lambda: planetlod.cube_to_sphere(proj, x, y))
    t_d2f = best_of(lambda: planetlod.dirs_to_faces(proj, flat))
    t_f2d = best_of(lambda: planetlod.faces_to_dirs(proj, faces, u, v))
    return {
        "lonlat fwd": n / t_s2x, "lonlat inv": n / t_x2s,
        "lonlat fwd+inv": n / (t_s2x + t_x2s),
        "dir fwd": n / t_d2f, "dir inv": n / t_f2d, "dir fwd+inv": n / (t_d2f + t_f2d),
    }


def roundtrips(proj):
    lon, lat = sphere_points()
    x, y = planetlod.sphere_to_cube(proj, lon, lat)
    lon2, lat2 = planetlod.cube_to_sphere(proj, x, y)
    sph = np.radians(angle_deg(lonlat_to_vec(lon, lat), lonlat_to_vec(np.asarray(lon2), np.asarray(lat2))))
    rng = np.random.default_rng(2)
    nfaces = 1 if proj == "car" else 6
    f = rng.integers(0, nfaces, 200000).astype(np.int32)
    u, v = rng.uniform(-1, 1, (2, 200000))
    dirs = np.asarray(planetlod.faces_to_dirs(proj, f, u, v)).reshape(-1, 3)
    f2, u2, v2 = planetlod.dirs_to_faces(proj, dirs.ravel())
    dirs2 = np.asarray(planetlod.faces_to_dirs(proj, f2, u2, v2)).reshape(-1, 3)
    face = np.radians(angle_deg(dirs, dirs2))
    return sph.max(), face.max()


def c_kernels(points):
    """Builds bench_projection_c.c against cext/projection.c (same flags as
    setup.py) and returns its table, or a note if there is no compiler."""
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if not cc:
        return "(no C compiler: C-level table skipped)"
    with tempfile.TemporaryDirectory() as tmp:
        exe = os.path.join(tmp, "bench_projection_c")
        subprocess.run([cc, "-std=c11", "-O2", "-ffp-contract=off", "-D_POSIX_C_SOURCE=200809L",
                        "-I", os.path.join(ROOT, "cext"),
                        os.path.join(ROOT, "bench", "bench_projection_c.c"),
                        os.path.join(ROOT, "cext", "projection.c"), "-lm", "-o", exe],
                       check=True)
        return subprocess.run([exe, str(points)], check=True, capture_output=True,
                              text=True).stdout.rstrip()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=2_000_000)
    ap.add_argument("--area-n", type=int, default=512)
    args = ap.parse_args()
    print(f"machine: {platform.machine()} {platform.processor() or ''} python {platform.python_version()}")
    print(f"points per call: {args.points}; best of 5; single thread")
    print()
    print("C kernels alone (plod_*_n loops, no Python):")
    print(c_kernels(args.points))
    print()
    print("Through the Python module (includes output allocation):")
    print("| mapping | fwd M/s (lon/lat) | inv M/s (lon/lat) | fwd+inv M/s (lon/lat) | fwd M/s (dir) | inv M/s (dir) | fwd+inv M/s (dir) |")
    print("|---|---|---|---|---|---|---|")
    for proj in planetlod.PROJECTIONS:
        t = throughput(proj, args.points)
        print(f"| {proj} | {t['lonlat fwd'] / 1e6:.1f} | {t['lonlat inv'] / 1e6:.1f} | "
              f"{t['lonlat fwd+inv'] / 1e6:.1f} | {t['dir fwd'] / 1e6:.1f} | "
              f"{t['dir inv'] / 1e6:.1f} | {t['dir fwd+inv'] / 1e6:.1f} |")
    print()
    print(f"| mapping | round trip sphere->cross->sphere [rad] | round trip face->dir->face [rad] | cell area max/min ({args.area_n}x{args.area_n} per face) |")
    print("|---|---|---|---|")
    for proj in planetlod.PROJECTIONS:
        sph, face = roundtrips(proj)
        if proj == "car":
            ratio = "n/a (one octahedral square)"
        else:
            ratio = f"{area_ratio(planetlod, proj, args.area_n)[0]:.6f}"
        print(f"| {proj} | {sph:.2e} | {face:.2e} | {ratio} |")


if __name__ == "__main__":
    main()
