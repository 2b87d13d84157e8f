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
Uses the installed add-on, legacy (`planet_lod`, tools/install_addon.py) or
extension (`bl_ext.<repository>.planet_lod`), or the repository's with
PYTHONPATH=addon.
"""
import argparse
import importlib
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


ADDON_NAME = "planet_lod"
_package = None  # the enabled add-on's module name


def addon_module_name():
    """The add-on's module name as Blender knows it: `planet_lod` (legacy add-on,
    or the repository's with PYTHONPATH=addon) or `bl_ext.<repository>.planet_lod`
    (an extension, Blender 4.2+); an enabled one first."""
    enabled = set(bpy.context.preferences.addons.keys())
    names = [mod.__name__ for mod in addon_utils.modules(refresh=False)
             if mod.__name__ == ADDON_NAME or mod.__name__.endswith("." + ADDON_NAME)]
    names.sort(key=lambda name: (name not in enabled, name != ADDON_NAME, name))
    return names[0] if names else ADDON_NAME


def addon(submodule):
    """A module of the enabled add-on (`core`, `render` ...), whatever its package."""
    return importlib.import_module(f"{_package}.{submodule}")


def enable_addon():
    """The installed add-on (legacy or extension), or the repository's when
    PYTHONPATH names addon/."""
    global _package
    name = addon_module_name()
    mod = addon_utils.enable(name, default_set=True, handle_error=None)
    if mod is None:
        raise SystemExit("planet_lod: the add-on is not installed: run tools/install_addon.py, "
                         f"or run Blender with PYTHONPATH={os.path.join(REPO, 'addon')}")
    _package = mod.__name__
    core = addon("core")
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
    compat = addon("compat")
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
    core = addon("core")
    sun.data.energy = core.flyby.FLYBY_SUN_STRENGTH
    sun.rotation_euler = core.flyby.FLYBY_SUN_ROTATION
    scene.collection.objects.link(sun)
    bpy.ops.mesh.planet_add(preset=args.preset.upper(), quality=args.quality.upper())
    return scene, bpy.context.object


def main(argv):
    args = parse(argv)
    from_t = time.perf_counter()
    enable_addon()
    core, render = addon("core"), addon("render")
    first, last = core.report.parse_frames(args.frames)
    scene, planet = build_scene(args)
    scene.frame_start, scene.frame_end = 1, args.path_frames
    print(f"planet_lod flyby: {planet.name} frames {first}-{last} of {args.path_frames} "
          f"at {args.resolution}, {args.samples} samples, Blender {bpy.app.version_string}, "
          f"add-on {_package} -> {args.out}", flush=True)
    rows = render.render_flyby(scene, planet, first, last, os.path.abspath(args.out),
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
