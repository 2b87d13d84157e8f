#!/usr/bin/env python3
"""Cycles render time and PSNR of each LOD method, three shots from orbit to the ground.

    /usr/bin/python3 -m bench.bench_method_cycles [--size 480x270] [--samples 16]
        [--methods HRTMR,CHUNKED,GEOMIPMAP,CLIPMAP] [--ref-error 0.25]
        [--out bench/results/method_cycles] [--blender blender]

The Earth preset (FINAL quality: 1 px at render resolution, its detail field,
sky and sea) near Everest, the camera placed by the add-on's planet placement
(floating origin), one sun 20 degrees up, 90 degrees right of the view:
  orbit   2,000 km above the ground, looking straight down
  km      3 km above the ground, heading north, 20 degrees down
  ground  2 m above the ground, heading east, 2 degrees down
Each method renders in its own Blender process (`blender -b`), the shots one
after the other; the reference is HRTMR at --ref-error px, same samples and
seed.  Per method and shot: the render's seconds (bpy.ops.render.render:
the add-on's refine and mesh for the render camera, then Cycles), the
triangles of the render mesh, the process's peak resident memory
(os.wait4's ru_maxrss) and the PSNR against the reference.  A render that
fails or a planet with no triangles fails the run.  Writes the PNGs
into --out and method_cycles.json beside it (bench/plot_methods.py draws
them).  Run inside Blender it is the
render job (internal).
"""
import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
EVEREST_LON, EVEREST_LAT = 86.925, 27.988
SHOTS = (("orbit", 2.0e6, 0.0, -90.0), ("km", 3000.0, 0.0, -20.0), ("ground", 2.0, 90.0, -2.0))

try:
    import bpy  # noqa: F401
    IN_BLENDER = True
except ImportError:
    IN_BLENDER = False


# ---- inside Blender: one method's shots -----------------------------------------

def render_job(argv):
    import addon_utils
    from mathutils import Vector
    ap = argparse.ArgumentParser(prog="bench_method_cycles.py (in Blender)")
    ap.add_argument("--method", required=True)
    ap.add_argument("--pixel-error", type=float, default=1.0)
    ap.add_argument("--size", default="480x270")
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--prefix", required=True)
    a = ap.parse_args(argv)
    assert addon_utils.enable("planet_lod", default_set=True, handle_error=None)
    from planet_lod import atmosphere, runtime
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    scene = bpy.context.scene
    width, height = (int(v) for v in a.size.split("x"))
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = a.samples
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.seed = 1
    scene.render.threads_mode = 'FIXED'
    scene.render.threads = 2
    scene.render.image_settings.file_format = 'PNG'
    scene.render.image_settings.color_depth = '16'
    if bpy.ops.mesh.planet_add(preset='EARTH', quality='FINAL', add_sun=False) != {'FINISHED'}:
        raise SystemExit("planet_add failed")
    planet = bpy.context.object
    planet.planet_lod.lod_method = a.method
    planet.planet_lod.max_pixel_error = a.pixel_error
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    sun.data.energy = 4.0
    sun.data.angle = math.radians(0.5)
    scene.collection.objects.link(sun)
    cam = bpy.data.objects.new("Bench camera", bpy.data.cameras.new("Bench camera"))
    cam.data.lens, cam.data.sensor_width = 50.0, 36.0
    scene.collection.objects.link(cam)
    scene.camera = cam
    geo = cam.planet_lod_geo
    geo.planet = planet
    geo.enabled = True
    lo, la = math.radians(EVEREST_LON), math.radians(EVEREST_LAT)
    up = Vector((math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)))
    east = Vector((-math.sin(lo), math.cos(lo), 0.0))
    north = up.cross(east)
    for name, altitude, heading, pitch in SHOTS:
        geo.longitude, geo.latitude, geo.altitude = EVEREST_LON, EVEREST_LAT, altitude
        geo.heading, geo.pitch = heading, pitch
        azimuth = math.radians(heading + 90.0)
        toward = (north * math.cos(azimuth) + east * math.sin(azimuth)) * math.cos(
            math.radians(20.0)) + up * math.sin(math.radians(20.0))
        sun.rotation_euler = (planet.matrix_world.to_3x3() @ toward).to_track_quat(
            'Z', 'Y').to_euler()
        bpy.context.view_layer.update()
        scene.world = atmosphere.ensure_world(planet, scene)
        target = f"{a.prefix}_{name}.png"
        scene.render.filepath = target
        t0 = time.perf_counter()
        result = bpy.ops.render.render(write_still=True)
        seconds = time.perf_counter() - t0
        st = runtime.state(planet)
        triangles = len(planet.data.polygons)
        if result != {'FINISHED'} or not os.path.isfile(target) or st.error or not triangles:
            raise SystemExit(f"render of {a.method} {name} failed: {st.error or result}")
        print(f"BENCH-METHOD-CYCLES shot={name} render_s={seconds:.3f} triangles={triangles}",
              flush=True)


# ---- driver (plain Python) -------------------------------------------------------

def run_method(blender, method, pixel_error, size, samples, prefix, scripts):
    cmd = ["nice", blender, "-b", "--factory-startup", "--python-exit-code", "1",
           "--python", os.path.abspath(__file__), "--", "--method", method,
           "--pixel-error", str(pixel_error), "--size", size, "--samples", str(samples),
           "--prefix", prefix]
    env = dict(os.environ, BLENDER_USER_SCRIPTS=scripts, PYTHONPATH=ROOT)
    env.setdefault("PLANET_LOD_NATIVE", ROOT)
    with open(prefix + ".log", "w") as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
        _, status, usage = os.wait4(proc.pid, 0)
    text = open(prefix + ".log").read()
    shots = {}
    for line in text.splitlines():
        if line.startswith("BENCH-METHOD-CYCLES"):
            fields = dict(kv.split("=") for kv in line.split()[1:])
            shots[fields["shot"]] = dict(render_s=float(fields["render_s"]),
                                         triangles=int(fields["triangles"]))
    if os.waitstatus_to_exitcode(status) != 0 or len(shots) != len(SHOTS):
        raise RuntimeError(f"{method} renders failed, see {prefix}.log:\n{text[-3000:]}")
    return shots, usage.ru_maxrss / 1024.0


def main():
    from bench.bench_cycles import load_png, psnr, ssim
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="480x270")
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--methods", default="HRTMR,CHUNKED,GEOMIPMAP,CLIPMAP")
    ap.add_argument("--ref-error", type=float, default=0.25)
    ap.add_argument("--out", default=os.path.join(HERE, "results", "method_cycles"))
    ap.add_argument("--blender", default=os.environ.get("BLENDER", shutil.which("blender")
                                                        or "blender"))
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    scripts = tempfile.mkdtemp(prefix="plod_scripts_")
    os.makedirs(os.path.join(scripts, "addons"))
    os.symlink(os.path.join(ROOT, "addon", "planet_lod"),
               os.path.join(scripts, "addons", "planet_lod"))
    runs = [("reference", "HRTMR", args.ref_error)] + [
        (m.lower(), m, 1.0) for m in args.methods.split(",")]
    result = {"size": args.size, "samples": args.samples, "ref_error": args.ref_error,
              "methods": {}}
    for label, method, error in runs:
        prefix = os.path.join(args.out, label)
        t0 = time.perf_counter()
        shots, rss = run_method(args.blender, method, error, args.size, args.samples, prefix,
                                scripts)
        result["methods"][label] = dict(method=method, pixel_error=error, maxrss_mb=rss,
                                        wall_s=time.perf_counter() - t0, shots=shots)
        for name, *_ in SHOTS:
            s = shots[name]
            if label != "reference":
                img = load_png(f"{prefix}_{name}.png")
                ref = load_png(os.path.join(args.out, f"reference_{name}.png"))
                s["psnr_db"], s["ssim"] = psnr(img, ref), ssim(img, ref)
            print(f"{label:10s} {name:7s} {s['triangles']:9d} tris  render {s['render_s']:7.2f} s"
                  f"  PSNR {s.get('psnr_db', float('nan')):6.2f} dB  "
                  f"SSIM {s.get('ssim', float('nan')):.4f}  maxrss {rss:.0f} MB", flush=True)
    with open(os.path.join(os.path.dirname(os.path.abspath(args.out)), "method_cycles.json"),
              "w") as f:
        json.dump(result, f, indent=1)
    shutil.rmtree(scripts)
    return 0


if __name__ == "__main__":
    if IN_BLENDER:
        argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
        try:
            render_job(argv)
        except SystemExit:
            raise
        except BaseException:
            import traceback
            traceback.print_exc()
            sys.exit(1)
    else:
        sys.exit(main())
