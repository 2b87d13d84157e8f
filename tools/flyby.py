"""Headless Planet LOD flyby (run inside Blender):

    blender -b --python tools/flyby.py -- --preset earth --frames 1-120 \
        --resolution 640x360 --samples 16 --out out/flyby

Builds a scene with one planet (a preset), a sun and a flyby camera whose path
(orbit -> descent -> skim at a few metres) is a pure function of the frame
number over --path-frames frames, or flies a path of your own:

    blender -b --python tools/flyby.py -- --path alps.gpx --path-frames 240
    blender -b --python tools/flyby.py -- --waypoint 1,7.0,46.0,3000,90,-20 \
        --waypoint 120,7.1,46.0,2,90,-5 --altitude-reference ground

(planetlod/waypoints.py: CSV, GPX and KML files); renders the chosen frames with Cycles (CPU,
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
    p.add_argument("--frames", default=None,
                   help="frames to render, e.g. 31-60 (default: the whole path)")
    p.add_argument("--path-frames", type=int, default=None,
                   help="frames of the orbit-descent-skim path (default 120), or over "
                        "which a GPX/KML track is spread (default: one frame per point)")
    p.add_argument("--path", metavar="FILE",
                   help="fly waypoints from a .csv, .gpx or .kml file instead of the "
                        "orbit, descent and skim")
    p.add_argument("--waypoint", action="append", metavar="F,LON,LAT,ALT[,HEADING[,PITCH]]",
                   help="a waypoint (repeat for each; instead of --path): frame, degrees, "
                        "metres, degrees from north, degrees above the horizon")
    p.add_argument("--altitude-reference", choices=["ground", "sea", "radius"],
                   help="waypoint altitudes are above the ground (default for --waypoint), "
                        "the sea level or the planet's radius")
    p.add_argument("--min-clearance", type=float, default=None,
                   help="metres the camera stays above the ground (default 0.5)")
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


def package():
    """The enabled add-on's package (its functions for scripts: planets(),
    refresh_planet(), render_flyby() ...)."""
    return importlib.import_module(_package)


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
    # no date or render time in the PNGs: a frame's file is the same whichever
    # machine, chunk or run rendered it
    scene.render.use_stamp_date = False
    scene.render.use_stamp_render_time = False
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


def read_path(args, waypoints):
    """The waypoint path the arguments give (None: orbit, descent and skim)."""
    if args.path and args.waypoint:
        raise waypoints.PathError("give --path or --waypoint, not both")
    if args.path:
        return waypoints.read_path(args.path, path_frames=args.path_frames,
                                   reference=args.altitude_reference,
                                   min_clearance=args.min_clearance)
    if args.waypoint:
        return waypoints.Path([waypoints.parse_waypoint(w) for w in args.waypoint],
                              args.altitude_reference or "ground",
                              0.5 if args.min_clearance is None else args.min_clearance)
    return None


def main(argv):
    args = parse(argv)
    from_t = time.perf_counter()
    enable_addon()
    core, render = addon("core"), addon("render")
    path = read_path(args, core.waypoints)  # a bad path file fails before Blender works
    path_frames = path.last if path is not None else (args.path_frames or 120)
    frames = args.frames or (f"{path.first}-{path.last}" if path is not None
                             else f"1-{path_frames}")
    first, last = core.report.parse_frames(frames)
    render.check_flyby_frames(first, last, path_frames, path)
    scene, planet = build_scene(args)
    scene.frame_start = path.first if path is not None else 1
    scene.frame_end = path_frames
    print(f"planet_lod flyby: {planet.name} frames {first}-{last} of "
          f"{'the path ' + str(path.first) + '-' + str(path.last) if path else path_frames} "
          f"at {args.resolution}, {args.samples} samples, Blender {bpy.app.version_string}, "
          f"add-on {_package} -> {args.out}", flush=True)
    rows = render.render_flyby(scene, planet, first, last, os.path.abspath(args.out),
                               path_frames, path=path)
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
