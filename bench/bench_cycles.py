#!/usr/bin/env python3
"""LOD + Cycles vs Cycles adaptive subdivision with displacement (part 3 of bench/README.md).

    /usr/bin/python3 -m bench.bench_cycles [--frames 3] [--resolution 320x180]
        [--samples 16] [--ref-samples 64] [--out bench/results]

For a few frames of bench/camera_path.csv (orbit over a pole, end of the
descent, skim) renders, each in its own Blender process (so its peak memory
is its own: os.wait4's ru_maxrss, plus Cycles' own "Peak" figure):
  lod       the add-on's Earth planet (FINAL quality: 1 px at render
            resolution), Cycles SUPPORTED feature set;
  adaptive  a UV sphere (128x64) of the same radius, Cycles EXPERIMENTAL,
            adaptive subdivision with dicing rate 1 px and true displacement
            of the same height map (data/earth-topology.png, 8848 m, the
            same equirectangular convention: x = lon 0, z = north);
  ref       the adaptive setup at --ref-samples (dicing --ref-dicing, default
            1 px: 0.5 px needs ~7 GB and ~2 min per 160x90 frame here).
Both test renders use --samples, denoising OFF (this Blender has no OIDN),
the same camera, clip range, sun and a plain grey diffuse material (so the
image difference is geometry + sampling noise, not texturing).  PSNR/SSIM of
each test render against the reference (numpy; SSIM on luminance, 7x7 box
windows).  Note: the reference is the displacement model's own geometry; the
LOD mesh samples the map resampled to a QSC cube map, so its PSNR also
contains the interpolation difference of the two height models.
Writes cycles.csv and cycles.json; renders go to --out/cycles/ (PNG).
Run inside Blender it is the render job (internal).
"""
import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
EARTH = os.path.join(ROOT, "data", "earth-topology.png")
HEIGHT_SCALE = 8848.0
FRAME_TIMES = (23.0, 63.0, 72.0)  # seconds on the 80 s path: over the north pole (800 km), descent, skim

try:
    import bpy  # noqa: F401
    IN_BLENDER = True
except ImportError:
    IN_BLENDER = False


# ---- inside Blender: one render ------------------------------------------------

def _grey_material():
    mat = bpy.data.materials.new("BenchGrey")
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Base Color"].default_value = (0.5, 0.5, 0.5, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Specular"].default_value = 0.0
    return mat


def _displaced_material(image_path, radius_m):
    """Grey diffuse + true displacement: height = map(equirect(object position)) * 8848 m."""
    mat = _grey_material()
    mat.cycles.displacement_method = 'DISPLACEMENT'
    nt = mat.node_tree
    nodes, links = nt.nodes, nt.links
    coord = nodes.new("ShaderNodeTexCoord")
    sep = nodes.new("ShaderNodeSeparateXYZ")
    links.new(coord.outputs["Object"], sep.inputs[0])
    length = nodes.new("ShaderNodeVectorMath")
    length.operation = 'LENGTH'
    links.new(coord.outputs["Object"], length.inputs[0])

    def math_node(op, a, b=None, value_b=None):
        n = nodes.new("ShaderNodeMath")
        n.operation = op
        links.new(a, n.inputs[0])
        if b is not None:
            links.new(b, n.inputs[1])
        elif value_b is not None:
            n.inputs[1].default_value = value_b
        return n.outputs[0]
    lon = math_node('ARCTAN2', sep.outputs["Y"], sep.outputs["X"])
    u = math_node('ADD', math_node('DIVIDE', lon, value_b=2.0 * math.pi), value_b=0.5)
    sin_lat = math_node('DIVIDE', sep.outputs["Z"], length.outputs["Value"])
    v = math_node('ADD', math_node('DIVIDE', math_node('ARCSINE', sin_lat), value_b=math.pi),
                  value_b=0.5)
    comb = nodes.new("ShaderNodeCombineXYZ")
    links.new(u, comb.inputs[0])
    links.new(v, comb.inputs[1])
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.load(image_path)
    tex.image.colorspace_settings.name = 'Non-Color'
    tex.interpolation = 'Linear'
    tex.extension = 'EXTEND'
    links.new(comb.outputs[0], tex.inputs["Vector"])
    # vector displacement onto the true sphere + height: normalize(P) * (R + h) - P
    # (the UV sphere's flat facets sag up to R (1 - cos(pi / 128)) = 1.9 km below it;
    # a plain height displacement along the normal would keep that sag)
    height = math_node('MULTIPLY', tex.outputs["Color"], value_b=HEIGHT_SCALE)
    radius = math_node('ADD', height, value_b=radius_m)
    unit = nodes.new("ShaderNodeVectorMath")
    unit.operation = 'NORMALIZE'
    links.new(coord.outputs["Object"], unit.inputs[0])
    scaled = nodes.new("ShaderNodeVectorMath")
    scaled.operation = 'SCALE'
    links.new(unit.outputs[0], scaled.inputs[0])
    links.new(radius, scaled.inputs["Scale"])
    offset = nodes.new("ShaderNodeVectorMath")
    offset.operation = 'SUBTRACT'
    links.new(scaled.outputs[0], offset.inputs[0])
    links.new(coord.outputs["Object"], offset.inputs[1])
    disp = nodes.new("ShaderNodeVectorDisplacement")
    disp.space = 'OBJECT'
    disp.inputs["Midlevel"].default_value = 0.0
    disp.inputs["Scale"].default_value = 1.0
    links.new(offset.outputs[0], disp.inputs["Vector"])
    out = nodes.get("Material Output")
    links.new(disp.outputs[0], out.inputs["Displacement"])
    return mat


def render_job(argv):
    from mathutils import Matrix, Vector
    from bench import camera_path
    ap = argparse.ArgumentParser(prog="bench_cycles.py (in Blender)")
    ap.add_argument("--method", choices=("lod", "adaptive", "ref"), required=True)
    ap.add_argument("--t", type=float, required=True)
    ap.add_argument("--resolution", default="320x180")
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--dicing", type=float, default=1.0)
    ap.add_argument("--png", required=True)
    a = ap.parse_args(argv)
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    scene = bpy.context.scene
    rx, ry = (int(v) for v in a.resolution.split("x"))
    scene.render.resolution_x, scene.render.resolution_y = rx, ry
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
    scene.render.filepath = a.png
    world = bpy.data.worlds.new("Black")
    world.color = (0.0, 0.0, 0.0)
    scene.world = world
    keys = camera_path.load()
    m, alt, seg = camera_path.pose(keys, a.t)
    cam_data = bpy.data.cameras.new("BenchCam")
    cam_data.lens, cam_data.sensor_width = 50.0, 36.0
    cam_data.clip_start, cam_data.clip_end = 1.0, 1.0e9
    cam = bpy.data.objects.new("BenchCam", cam_data)
    scene.collection.objects.link(cam)
    cam.matrix_world = Matrix(m)
    scene.camera = cam
    # sun from behind-left of the camera's zenith direction
    up = Vector((m[0][3], m[1][3], m[2][3])).normalized()
    side = Vector((m[0][0], m[1][0], m[2][0]))
    sun_dir = (up + 0.5 * side).normalized()
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    sun.data.energy = 3.0
    sun.rotation_euler = sun_dir.to_track_quat('Z', 'Y').to_euler()
    scene.collection.objects.link(sun)
    bpy.context.view_layer.update()
    grey = _grey_material()
    if a.method == "lod":
        os.environ.setdefault("PLANET_LOD_NATIVE", ROOT)
        import addon_utils
        assert addon_utils.enable("planet_lod", default_set=True, handle_error=None)
        scene.cycles.feature_set = 'SUPPORTED'
        assert bpy.ops.mesh.planet_add(preset='EARTH', quality='FINAL') == {'FINISHED'}
        obj = bpy.context.view_layer.objects.active
        obj.planet_lod.ocean_sphere = False
        obj.planet_lod.clip_from_horizon = False
        obj.planet_lod.heightmap = EARTH
        obj.planet_lod.height_scale = HEIGHT_SCALE
        obj.material_slots[0].link = 'OBJECT'
        obj.material_slots[0].material = grey
    else:
        scene.cycles.feature_set = 'EXPERIMENTAL'
        bpy.ops.mesh.primitive_uv_sphere_add(segments=128, ring_count=64,
                                             radius=camera_path.R_EARTH)
        obj = bpy.context.view_layer.objects.active
        bpy.ops.object.shade_smooth()
        obj.data.materials.append(_displaced_material(EARTH, camera_path.R_EARTH))
        mod = obj.modifiers.new("Subdivision", 'SUBSURF')
        mod.subdivision_type = 'SIMPLE'
        obj.cycles.use_adaptive_subdivision = True
        obj.cycles.dicing_rate = a.dicing
        scene.cycles.dicing_rate = a.dicing
        scene.cycles.max_subdivisions = 12
        scene.cycles.dicing_camera = cam
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    print(f"BENCH-CYCLES render_s={time.perf_counter() - t0:.3f} segment={seg} "
          f"altitude={alt:.1f}", flush=True)


# ---- driver (plain Python) -------------------------------------------------------

def run_blender(blender, job_args, log_path):
    """(wall seconds, ru_maxrss MB, Cycles 'Peak' MB, render_s) of one Blender render."""
    cmd = ["nice", blender, "-b", "--factory-startup", "--python-exit-code", "1",
           "--python", os.path.abspath(__file__), "--"] + job_args
    # Blender runs this file by path: the `bench` package and the add-on come
    # from the repository through PYTHONPATH
    env = dict(os.environ, PYTHONPATH=os.pathsep.join((ROOT, os.path.join(ROOT, "addon"))))
    t0 = time.perf_counter()
    with open(log_path, "w") as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
        _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    text = open(log_path).read()
    if os.waitstatus_to_exitcode(status) != 0 or "BENCH-CYCLES" not in text:
        raise RuntimeError(f"render failed ({' '.join(job_args)}), see {log_path}:\n"
                           + text[-3000:])
    peaks = [float(v) for v in re.findall(r"Peak[: ]+([0-9.]+)M", text)]
    render_s = float(re.search(r"render_s=([0-9.]+)", text).group(1))
    # ru_maxrss of the child (its largest resident set); nice is exec'd, same process
    return wall, usage.ru_maxrss / 1024.0, (max(peaks) if peaks else None), render_s


def load_png(path):
    import numpy as np
    import matplotlib.image as mpimg
    img = mpimg.imread(path).astype(np.float64)
    return img[..., :3]


def psnr(a, b):
    import numpy as np
    mse = float(np.mean((a - b) ** 2))
    return float("inf") if mse == 0 else 10.0 * math.log10(1.0 / mse)


def ssim(a, b, win=7):
    import numpy as np
    ya = a @ np.array([0.2126, 0.7152, 0.0722])
    yb = b @ np.array([0.2126, 0.7152, 0.0722])

    def box(x):
        c = np.cumsum(np.cumsum(np.pad(x, ((1, 0), (1, 0))), 0), 1)
        return (c[win:, win:] - c[:-win, win:] - c[win:, :-win] + c[:-win, :-win]) / win ** 2
    mu_a, mu_b = box(ya), box(yb)
    va = box(ya * ya) - mu_a ** 2
    vb = box(yb * yb) - mu_b ** 2
    cov = box(ya * yb) - mu_a * mu_b
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    s = ((2 * mu_a * mu_b + c1) * (2 * cov + c2)) / ((mu_a ** 2 + mu_b ** 2 + c1) * (va + vb + c2))
    return float(s.mean())


def driver():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=3, help="how many of the 3 path moments")
    ap.add_argument("--times", default="", help="path times (s), comma separated")
    ap.add_argument("--resolution", default="320x180")
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--ref-samples", type=int, default=64)
    ap.add_argument("--ref-dicing", type=float, default=1.0)
    ap.add_argument("--out", default=os.path.join(HERE, "results"))
    ap.add_argument("--blender", default=os.environ.get("BLENDER", shutil.which("blender")
                                                        or "blender"))
    args = ap.parse_args()
    img_dir = os.path.join(args.out, "cycles")
    os.makedirs(img_dir, exist_ok=True)
    frames = []
    times = [float(v) for v in args.times.split(",")] if args.times else FRAME_TIMES[:args.frames]
    for k, t in enumerate(times):
        entry = {"frame": k, "t_s": t}
        for method, samples, dicing in (("ref", args.ref_samples, args.ref_dicing),
                                        ("lod", args.samples, 1.0),
                                        ("adaptive", args.samples, 1.0)):
            png = os.path.join(img_dir, f"t{int(t):02d}_{method}.png")
            log = os.path.join(img_dir, f"t{int(t):02d}_{method}.log")
            wall, rss, peak, render_s = run_blender(
                args.blender, ["--method", method, "--t", str(t), "--resolution",
                               args.resolution, "--samples", str(samples), "--dicing",
                               str(dicing), "--png", png], log)
            entry[method] = {"time_s": render_s, "wall_s": wall, "maxrss_mb": rss,
                             "peak_mb": peak, "png": os.path.relpath(png, args.out)}
            print(f"cycles t={t} {method}: render {render_s:.2f} s, wall {wall:.1f} s, "
                  f"maxrss {rss:.0f} MB, Cycles peak {peak} MB", flush=True)
        ref = load_png(os.path.join(img_dir, f"t{int(t):02d}_ref.png"))
        for method in ("lod", "adaptive"):
            img = load_png(os.path.join(img_dir, f"t{int(t):02d}_{method}.png"))
            entry[method]["psnr_db"] = psnr(img, ref)
            entry[method]["ssim"] = ssim(img, ref)
            entry[method]["nonblack_pct"] = float((img.max(axis=2) > 0.02).mean() * 100.0)
        frames.append(entry)

    def mean(method, key):
        vals = [f[method][key] for f in frames if f[method].get(key) is not None]
        return sum(vals) / len(vals) if vals else None

    def ratio(key):
        a, b = mean("adaptive", key), mean("lod", key)
        return a / b if a is not None and b else None
    blender_version = subprocess.run([args.blender, "--version"], capture_output=True,
                                     text=True).stdout.split("\n")[0].replace("Blender ", "")
    result = {"blender": blender_version.strip(), "resolution": args.resolution,
              "samples": args.samples, "ref_samples": args.ref_samples,
              "ref_dicing": args.ref_dicing, "frames": frames,
              "aggregate": {"time_ratio": ratio("time_s"), "mem_ratio": ratio("peak_mb"),
                            "rss_ratio": ratio("maxrss_mb"),
                            "psnr_lod": mean("lod", "psnr_db"),
                            "psnr_adaptive": mean("adaptive", "psnr_db"),
                            "ssim_lod": mean("lod", "ssim"),
                            "ssim_adaptive": mean("adaptive", "ssim")}}
    with open(os.path.join(args.out, "cycles.json"), "w") as f:
        json.dump(result, f, indent=1)
    with open(os.path.join(args.out, "cycles.csv"), "w") as f:
        f.write("t_s,method,time_s,wall_s,maxrss_mb,peak_mb,psnr_db,ssim\n")
        for e in frames:
            for method in ("ref", "lod", "adaptive"):
                r = e[method]
                f.write(f"{e['t_s']},{method},{r['time_s']:.3f},{r['wall_s']:.2f},"
                        f"{r['maxrss_mb']:.1f},{r['peak_mb']},{r.get('psnr_db', '')},"
                        f"{r.get('ssim', '')}\n")
    print("cycles:", json.dumps(result["aggregate"]), flush=True)


if __name__ == "__main__":
    if IN_BLENDER:
        argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
        render_job(argv)
    else:
        driver()
