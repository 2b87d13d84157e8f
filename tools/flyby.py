"""Headless Planet LOD flyby (run inside Blender):

    blender -b --python tools/flyby.py -- --preset earth --frames 1-120 \
        --resolution 640x360 --samples 16 --out out/flyby

Builds a scene with one planet (a preset), a sun and a flyby camera whose path
(orbit -> descent -> skim at a few metres) is a pure function of the frame
number over --path-frames frames; renders the chosen frames with Cycles (CPU,
no denoising) to DIR/frame_####.png and writes DIR/stats.csv and
DIR/contact_sheet.png.  Frames are independent: `--frames 31-60` renders the
same LOD and images as frames 31-60 of a `--frames 1-120` run, so a long flyby
can be split over a render farm (one job per range).
Uses the installed add-on `planet_lod` (tools/install_addon.py), or the
repository's with PYTHONPATH=addon.
"""
import argparse
import os
import sys
import time

import addon_utils
import bpy

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def parse(argv):
    p = argparse.ArgumentParser(prog="blender -b --python tools/flyby.py --")
    p.add_argument("--preset", default="earth", choices=["earth", "moon", "mars", "asteroid"])
    p.add_argument("--quality", default="preview", choices=["draft", "preview", "final"])
    p.add_argument("--frames", default="1-120")
    p.add_argument("--path-frames", type=int, default=120)
    p.add_argument("--resolution", default="640x360")
    p.add_argument("--samples", type=int, default=16)
    p.add_argument("--engine", default="CYCLES", choices=["CYCLES", "BLENDER_EEVEE"])
    p.add_argument("--skim-height", type=float, default=5.0)
    p.add_argument("--transparent", action="store_true", help="film_transparent (alpha)")
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--out", default=os.path.join(REPO, "out", "flyby"))
    return p.parse_args(argv)


def enable_addon():
    """The installed add-on, or the repository's when PYTHONPATH names addon/."""
    mod = addon_utils.enable("planet_lod", default_set=True, handle_error=None)
    if mod is None:
        raise SystemExit("planet_lod: the add-on is not installed: run tools/install_addon.py, "
                         f"or run Blender with PYTHONPATH={os.path.join(REPO, 'addon')}")
    from planet_lod import core
    if core.load_native() is None:
        raise SystemExit("planet_lod: " + core.native_error)
    return mod


def build_scene(args):
    scene = bpy.context.scene
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    width, height = (int(v) for v in args.resolution.lower().split("x"))
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    from planet_lod import compat
    scene.render.engine = compat.render_engine(args.engine)
    scene.render.film_transparent = args.transparent
    if args.engine == "CYCLES":
        scene.cycles.device = 'CPU'
        scene.cycles.samples = args.samples
        scene.cycles.use_denoising = False
        scene.cycles.use_adaptive_sampling = False
        scene.cycles.max_bounces = 2
        if args.threads:
            scene.render.threads_mode = 'FIXED'
            scene.render.threads = args.threads
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    from planet_lod import core
    sun.data.energy = core.flyby.FLYBY_SUN_STRENGTH
    sun.rotation_euler = core.flyby.FLYBY_SUN_ROTATION
    scene.collection.objects.link(sun)
    bpy.ops.mesh.planet_add(preset=args.preset.upper(), quality=args.quality.upper())
    return scene, bpy.context.object


def main(argv):
    args = parse(argv)
    from_t = time.perf_counter()
    enable_addon()
    import planet_lod
    from planet_lod import core
    first, last = core.report.parse_frames(args.frames)
    scene, planet = build_scene(args)
    scene.frame_start, scene.frame_end = 1, args.path_frames
    print(f"planet_lod flyby: {planet.name} frames {first}-{last} of {args.path_frames} "
          f"at {args.resolution}, {args.samples} samples, Blender {bpy.app.version_string} "
          f"-> {args.out}", flush=True)
    rows = planet_lod.render_flyby(scene, planet, first, last, os.path.abspath(args.out),
                                   args.path_frames)
    print(f"planet_lod flyby: {len(rows)} frames, stats.csv and contact_sheet.png in "
          f"{args.out} ({time.perf_counter() - from_t:.1f} s)", flush=True)


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    try:
        main(argv)
    except SystemExit:
        raise
    except Exception as exc:  # a clear one-line error for the command line
        import traceback
        traceback.print_exc()
        raise SystemExit(f"planet_lod flyby failed: {exc}")
