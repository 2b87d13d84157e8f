"""Soak test of the add-on inside Blender (headless, no rendering):

    PYTHONPATH=. blender -b --factory-startup --python tools/soak_blender.py -- --frames 200

(from the repository root: Blender runs the file by path, PYTHONPATH gives
it the `tools` package.)

Adds the Earth preset and the flyby camera, then steps scene.frame_set() over
the flyby path down and back (first half of --frames down the path, second
half back up), so the frame-change handlers place the camera, refine for it
and rewrite the planet's mesh every frame, as an animation render does.
Every --every frames it records resident memory (VmRSS), the visible sector
count and the number of meshes / images / materials / objects / cameras and
their orphans (zero users).  Exits 1 (via --python-exit-code 1) when a
datablock count or orphan count changes after the first frame, a frame has
more sectors than the budget or a refresh error, or the RSS at the end exceeds
the RSS after the warm-up (first half) by more than --max-growth-mb.
Uses the installed add-on `planet_lod`, or the repository's with PYTHONPATH=addon.
"""
import argparse
import os
import sys
import time

import bpy

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
from tools import flyby  # noqa: E402  (enable_addon)
from tools.soak import rss_kib  # noqa: E402

KINDS = ("meshes", "images", "materials", "objects", "cameras")


def parse(argv):
    p = argparse.ArgumentParser(prog="blender -b --python tools/soak_blender.py --")
    p.add_argument("--frames", type=int, default=200)
    p.add_argument("--every", type=int, default=50)
    p.add_argument("--quality", default="preview", choices=["draft", "preview", "final"])
    p.add_argument("--resolution", default="640x360")
    p.add_argument("--max-growth-mb", type=float, default=16.0)
    return p.parse_args(argv)


def datablocks():
    counts = {}
    for kind in KINDS:
        coll = getattr(bpy.data, kind)
        counts[kind] = len(coll)
        counts["orphan " + kind] = sum(1 for item in coll if item.users == 0)
    return counts


def main(argv):
    args = parse(argv)
    flyby.enable_addon()
    planet_lod = flyby.package()  # the add-on, whatever module name Blender gave it
    scene = bpy.context.scene
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    for mesh in list(bpy.data.meshes):
        if mesh.users == 0:
            bpy.data.meshes.remove(mesh)
    width, height = (int(v) for v in args.resolution.split("x"))
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality=args.quality.upper()) \
        == {'FINISHED'}
    planet = bpy.context.object
    half = max(2, args.frames // 2)
    scene.frame_start, scene.frame_end = 1, half
    planet_lod.ensure_flyby_camera(scene, planet, half)
    budget = planet.planet_lod.budget

    failures, rows = [], []
    reference = None
    rss_start = rss_kib()
    rss_warm = None
    t0 = time.perf_counter()
    for index in range(args.frames):
        frame = index + 1 if index < half else 2 * half - index
        scene.frame_set(min(max(frame, 1), half))
        st = planet_lod.planet_state(planet)
        if st.error:
            failures.append(f"frame {index + 1}: {st.error}")
        visible = st.stats.get("visible", 0)
        if visible > budget:
            failures.append(f"frame {index + 1}: {visible} sectors > budget {budget}")
        if index == 0:
            reference = datablocks()
        if index + 1 == half:
            rss_warm = rss_kib()
        if index == 0 or (index + 1) % args.every == 0 or index + 1 == args.frames:
            counts = datablocks()
            if counts != reference:
                failures.append(f"frame {index + 1}: datablocks {counts} != {reference}")
            rows.append((index + 1, frame, visible, len(planet.data.polygons), rss_kib(),
                         counts))
    elapsed = time.perf_counter() - t0
    rss_end = rss_kib()
    rss_warm = rss_warm or rss_end

    print(f"soak_blender: {args.frames} frames ({half} down the flyby path, then back), "
          f"Blender {bpy.app.version_string}, {args.quality} quality, budget {budget}, "
          f"{elapsed:.1f} s ({elapsed / args.frames * 1000:.1f} ms/frame)")
    header = " ".join(f"{k.replace('orphan ', 'o.'):>10}" for k in reference)
    print(f"{'frame':>6} {'path':>5} {'sectors':>8} {'triangles':>10} {'RSS KiB':>10} {header}")
    for frame, path_frame, visible, triangles, rss, counts in rows:
        cells = " ".join(f"{v:>10}" for v in counts.values())
        print(f"{frame:>6} {path_frame:>5} {visible:>8} {triangles:>10} {rss:>10} {cells}")
    growth = (rss_end - rss_warm) / 1024.0
    print(f"RSS start {rss_start} KiB, after warm-up (frame {half}) {rss_warm} KiB, end "
          f"{rss_end} KiB: growth after warm-up {growth:+.2f} MiB "
          f"(limit {args.max_growth_mb} MiB)")
    if growth > args.max_growth_mb:
        failures.append(f"RSS grew {growth:.2f} MiB after the warm-up")
    for failure in failures[:20]:
        print("soak_blender: FAIL:", failure)
    print("soak_blender:", "FAILED" if failures else "OK", flush=True)
    if failures:
        raise SystemExit(1)


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
