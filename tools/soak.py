#!/usr/bin/env python3
"""Soak test of the refine/emit path in C (planetlod, no Blender).

    /usr/bin/python3 -m tools.soak                    # 1000 frames, Earth, budget 8000
    /usr/bin/python3 -m tools.soak --frames 100       # the quick version pytest runs

Flies the add-on's deterministic flyby path (orbit -> descent -> skim at 5 m;
planetlod.flyby.flyby_pose) down and back up: the first half of --frames goes down the
path, the second half comes back, so the second half revisits every LOD state
of the first and any memory kept per frame shows up as growth.  Each frame:
Camera -> refine (with hysteresis, as the viewport) -> mesh (sector meshes,
morph on) -> instances (the GPU preview), like one live refresh.

Checked every frame: visible sectors <= budget, emitted triangles == sectors x
template.  Resident memory (VmRSS from /proc/self/status) is sampled every
--every frames and printed as a table; the run fails (exit 1) when the RSS at
the end exceeds the RSS after the warm-up (the first half) by more than
--max-growth-mb, or when a frame breaks the budget.
"""
import argparse
import math
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def rss_kib():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    raise RuntimeError("no VmRSS in /proc/self/status")


def parse(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--frames", type=int, default=1000, help="total frames (down + back)")
    p.add_argument("--budget", type=int, default=8000)
    p.add_argument("--template-level", type=int, default=3, help="0..7 (3: 64 triangles)")
    p.add_argument("--max-pixel-error", type=float, default=2.0)
    p.add_argument("--max-level", type=int, default=24, help="the add-on's default")
    p.add_argument("--resolution", default="1280x720")
    p.add_argument("--heightmap", default=os.path.join(ROOT, "data", "earth-topology.png"))
    p.add_argument("--radius", type=float, default=6371000.0)
    p.add_argument("--height-scale", type=float, default=8848.0)
    p.add_argument("--every", type=int, default=0, help="table row every N frames "
                                                        "(default: frames/10)")
    p.add_argument("--max-growth-mb", type=float, default=4.0,
                   help="allowed RSS growth after the warm-up (first half)")
    return p.parse_args(argv)


def main(argv=None):
    args = parse(argv)
    import planetlod
    from planetlod import flyby
    width, height = (int(v) for v in args.resolution.split("x"))
    half = max(2, args.frames // 2)
    every = args.every or max(1, args.frames // 10)
    planet = planetlod.Planet(args.radius, heightmap=args.heightmap or None,
                              height_scale=args.height_scale)
    ground = (lambda d: planet.height(*d)) if args.heightmap else None

    rows, failures = [], []
    max_visible = max_triangles = 0
    rss_start = rss_kib()
    rss_warm = None
    t0 = time.perf_counter()
    for index in range(args.frames):
        # down the path (1..half), then back up (half..1)
        frame = index + 1 if index < half else 2 * half - index
        frame = min(max(frame, 1), half)
        pose = flyby.flyby_pose(frame, half, args.radius, ground_height=ground)
        camera = planetlod.Camera(matrix_world=[list(r) for r in pose], lens=24.0,
                                  resolution_x=width, resolution_y=height,
                                  clip_start=0.05, clip_end=args.radius * 6.0)
        stats = planet.refine(camera, max_pixel_error=args.max_pixel_error, hysteresis=True,
                              template_level=args.template_level, budget=args.budget,
                              max_level=args.max_level)
        visible = planet.visible_count
        mesh = planet.mesh(template_level=args.template_level, morph=True)
        instances = planet.instances(template_level=args.template_level)
        if visible > args.budget:
            failures.append(f"frame {index + 1}: {visible} sectors > budget {args.budget}")
        if mesh.triangle_count != visible * 4 ** args.template_level:
            failures.append(f"frame {index + 1}: {mesh.triangle_count} triangles for "
                            f"{visible} sectors")
        max_visible = max(max_visible, visible)
        max_triangles = max(max_triangles, mesh.triangle_count)
        del mesh, instances, camera
        if index + 1 == half:
            rss_warm = rss_kib()
        if (index + 1) % every == 0 or index == 0 or index + 1 == args.frames:
            pos = [r[3] for r in pose[:3]]
            altitude = math.sqrt(sum(c * c for c in pos)) - args.radius
            rows.append((index + 1, frame, visible, stats["max_level"], altitude,
                         rss_kib(), planet.memory_bytes))
    elapsed = time.perf_counter() - t0
    rss_end = rss_kib()
    if rss_warm is None:
        rss_warm = rss_end

    print(f"soak: {args.frames} frames ({half} down the flyby path, then back), budget "
          f"{args.budget}, template level {args.template_level}, {width}x{height}, "
          f"{elapsed:.1f} s ({elapsed / args.frames * 1000:.1f} ms/frame)")
    print(f"{'frame':>6} {'path':>5} {'sectors':>8} {'level':>5} {'altitude m':>14} "
          f"{'RSS KiB':>10} {'planet B':>10}")
    for frame, path_frame, visible, level, altitude, rss, planet_bytes in rows:
        print(f"{frame:>6} {path_frame:>5} {visible:>8} {level:>5} {altitude:>14.1f} "
              f"{rss:>10} {planet_bytes:>10}")
    growth = (rss_end - rss_warm) / 1024.0
    print(f"RSS start {rss_start} KiB, after warm-up (frame {half}) {rss_warm} KiB, end "
          f"{rss_end} KiB: growth after warm-up {growth:+.2f} MiB (limit "
          f"{args.max_growth_mb} MiB); most sectors {max_visible} (budget {args.budget}), "
          f"most triangles {max_triangles}")
    cache = planet.mesh_cache_info
    print(f"mesh sector cache at the end: {cache['sectors']} sectors, "
          f"{cache['bytes'] / 2**20:.2f} MiB (the last frame's; budget "
          f"{cache['max_bytes'] / 2**20:.0f} MiB)")
    if growth > args.max_growth_mb:
        failures.append(f"RSS grew {growth:.2f} MiB after the warm-up")
    for failure in failures[:20]:
        print("soak: FAIL:", failure)
    print("soak:", "FAILED" if failures else "OK")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
