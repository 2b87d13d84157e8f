"""The Blender hand-off (part 5 of bench/README.md), run inside Blender 3.4:

    PYTHONPATH=.:addon blender -b --factory-startup --python bench/bench_blender.py -- \
        [--frames 36] [--quality FINAL] [--out bench/results]
    PYTHONPATH=.:addon xvfb-run -a blender --factory-startup \
        --python bench/bench_blender.py -- --gpu ...

(from the repository root: PYTHONPATH gives Blender the `bench` package and
the repository's add-on).

Replays bench/camera_path.csv with the add-on itself (planet added with
mesh.planet_add, Earth preset): per frame
  lod:   planet_lod.refresh_planet(build_mesh=True, for_render=True) = refine +
         emission + the mesh written (the add-on's foreach_set update path), then the
         depsgraph evaluation of the changed mesh;
  emit:  planet.mesh() of the same state again (emission alone, so
         update = mesh_ms - emit);
  floor: Blender's own floor: an equal mesh, precomputed (numpy arrays built
         before the clock starts), pushed into a plain object with foreach_set
         (clear + add + vertex_index/loop_start/loop_total/co) and evaluated.
With --gpu (needs a window: run under xvfb-run without -b) also the GPU
preview's per-update cost: the surface (planet.mesh +
surface.preview_data) and the upload (draw._ensure_batch: the surface texture).
In background mode the gpu module cannot build batches; that column is then
reported as not measurable.  Writes blender_handoff.csv and blender_handoff.json.
"""
import argparse
import json
import os
import platform
import statistics
import sys
import time

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
os.environ.setdefault("PLANET_LOD_NATIVE", ROOT)

import numpy as np  # noqa: E402  (Blender bundles numpy)

from bench import camera_path  # noqa: E402


def parse():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="bench_blender.py")
    ap.add_argument("--frames", type=int, default=36)
    ap.add_argument("--quality", default="FINAL", choices=("DRAFT", "PREVIEW", "FINAL"))
    ap.add_argument("--resolution", default="1280x720")
    ap.add_argument("--gpu", action="store_true", help="also time the GPU preview build")
    ap.add_argument("--out", default=os.path.join(HERE, "results"))
    return ap.parse_args(argv)


def enable_addon():
    import addon_utils
    mod = addon_utils.enable("planet_lod", default_set=True, handle_error=None)
    assert mod is not None, "planet_lod add-on could not be enabled"
    from planet_lod import core
    assert core.load_native() is not None, core.native_error
    return mod


def evaluate():
    t0 = time.perf_counter()
    bpy.context.evaluated_depsgraph_get().update()
    return (time.perf_counter() - t0) * 1e3


def floor_push(me, pre):
    """Blender's floor: an equal precomputed mesh through foreach_set + evaluation."""
    nv, nt = pre["nv"], pre["nt"]
    t0 = time.perf_counter()
    me.clear_geometry()
    me.vertices.add(nv)
    me.loops.add(3 * nt)
    me.polygons.add(nt)
    me.vertices.foreach_set("co", pre["co"])
    me.loops.foreach_set("vertex_index", pre["tris"])
    me.polygons.foreach_set("loop_start", pre["loop_start"])
    me.polygons.foreach_set("loop_total", pre["loop_total"])
    me.update()
    push_ms = (time.perf_counter() - t0) * 1e3
    return push_ms, evaluate()


def gpu_update(draw, planet_obj, planet, template_level, res, st):
    import planet_lod
    from planetlod import surface
    s = planet_obj.planet_lod
    t0 = time.perf_counter()
    visible = planet.mesh(template_level=template_level, morph=s.morph)
    st.preview = surface.preview_data(visible, planet_lod.anchor(planet_obj), s.radius,
                                      s.sea_level if s.use_sea_level else None)
    t1 = time.perf_counter()
    st.gpu_version += 1
    draw._ensure_batch(res, st)
    t2 = time.perf_counter()
    return (t1 - t0) * 1e3, (t2 - t1) * 1e3


def main():
    args = parse()
    os.makedirs(args.out, exist_ok=True)
    enable_addon()
    import planet_lod
    from planet_lod import core
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    scene = bpy.context.scene
    rx, ry = (int(v) for v in args.resolution.split("x"))
    scene.render.resolution_x, scene.render.resolution_y = rx, ry
    scene.render.resolution_percentage = 100
    cam_data = bpy.data.cameras.new("BenchCam")
    cam_data.lens, cam_data.sensor_width = 50.0, 36.0
    cam_data.clip_start, cam_data.clip_end = 1.0, 1.0e10
    cam = bpy.data.objects.new("BenchCam", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    from mathutils import Matrix
    poses = camera_path.frames(args.frames)
    cam.matrix_world = Matrix(poses[0][1])
    bpy.context.view_layer.update()
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality=args.quality) == {'FINISHED'}
    planet_obj = bpy.context.view_layer.objects.active
    planet_obj.planet_lod.lod_camera = 'SCENE'
    settings = planet_obj.planet_lod.as_dict()
    tl = int(settings["template_level"])
    planet = core.planets.build_planet(settings)
    floor_me = bpy.data.meshes.new("Floor")
    floor_obj = bpy.data.objects.new("Floor", floor_me)
    scene.collection.objects.link(floor_obj)

    draw = shader = res = None
    gpu_note = ""
    if args.gpu:
        if bpy.app.background:
            gpu_note = "not measurable headless (-b): gpu batches need a window; use xvfb-run"
        else:
            from planet_lod import draw as draw_mod
            draw, shader = draw_mod, draw_mod.preview_shader()
            res = draw_mod.PlanetGPU()
            if shader is None:
                gpu_note = "preview shader unavailable"
                draw = None
    elif bpy.app.background:
        gpu_note = "not measured (run with --gpu under xvfb-run)"

    rows = []
    precomputed = []
    # pass 1: the add-on's path, frame by frame (the LOD state carries on, as in
    # an animation render); keeps each frame's mesh for the floor pass
    for k, (t, m, alt, seg) in enumerate(poses):
        cam.matrix_world = Matrix(m)
        bpy.context.view_layer.update()
        t0 = time.perf_counter()
        stats = planet_lod.refresh_planet(planet_obj, scene, build_mesh=True, for_render=True)
        refresh_ms = (time.perf_counter() - t0) * 1e3
        eval_ms = evaluate()
        t1 = time.perf_counter()
        mesh = planet.mesh(template_level=tl, morph=planet_obj.planet_lod.morph)
        emit_ms = (time.perf_counter() - t1) * 1e3
        nt, nv = mesh.triangle_count, mesh.vertex_count
        co = np.frombuffer(mesh.positions, dtype=np.float32).reshape(-1, 3) \
            + np.asarray(tuple(mesh.origin), dtype=np.float64).astype(np.float32)
        precomputed.append({"nv": nv, "nt": nt, "co": co.ravel().copy(),
                            "tris": np.frombuffer(mesh.triangles, dtype=np.int32).copy(),
                            "loop_start": np.arange(0, 3 * nt, 3, dtype=np.int32),
                            "loop_total": np.full(nt, 3, dtype=np.int32)})
        row = {"frame": k, "t_s": round(t, 3), "segment": seg, "altitude_m": round(alt, 1),
               "sectors_after_frustum": stats["sectors_after_frustum"],
               "triangles": nt, "vertices": nv,
               "refine_ms": round((stats["refine_us"] + stats["cull_us"]) / 1e3, 3),
               "emit_ms": round(emit_ms, 3),
               "mesh_ms": stats["mesh_ms"],
               "update_ms": round(max(0.0, stats["mesh_ms"] - emit_ms), 3),
               "refresh_ms": round(refresh_ms, 3), "lod_eval_ms": round(eval_ms, 3),
               "lod_total_ms": round(refresh_ms + eval_ms, 3)}
        if draw is not None:
            surface_ms, build_ms = gpu_update(draw, planet_obj, planet, tl, res,
                                              planet_lod.planet_state(planet_obj))
            row["gpu_surface_ms"] = round(surface_ms, 3)
            row["gpu_build_ms"] = round(build_ms, 3)
        rows.append(row)
        print(f"bench_blender: frame {k + 1}/{len(poses)} {seg} {nt} tris "
              f"{row['lod_total_ms']:.1f} ms", flush=True)
    # pass 2: the floor, same meshes, precomputed
    for row, pre in zip(rows, precomputed):
        push_ms, feval_ms = floor_push(floor_me, pre)
        row["floor_push_ms"] = round(push_ms, 3)
        row["floor_eval_ms"] = round(feval_ms, 3)
        row["floor_total_ms"] = round(push_ms + feval_ms, 3)
        assert len(floor_me.polygons) == row["triangles"]

    gpu_run = args.gpu and not bpy.app.background
    stem = "blender_handoff_gpu" if gpu_run else "blender_handoff"
    path = os.path.join(args.out, stem + ".csv")
    with open(path, "w") as f:
        keys = list(rows[0].keys())
        f.write(",".join(keys) + "\n")
        for r in rows:
            f.write(",".join(str(r[key]) for key in keys) + "\n")

    def med(key):
        vals = [r[key] for r in rows if key in r]
        return statistics.median(vals) if vals else None

    def total(key):
        return sum(r[key] for r in rows if key in r)
    summary = {
        "frames": len(rows), "quality": args.quality, "template_level": tl,
        "resolution": [rx, ry], "blender": bpy.app.version_string,
        "machine": platform.machine(), "cpus": os.cpu_count(),
        "background": bool(bpy.app.background),
        "triangles_median": med("triangles"), "triangles_max": max(r["triangles"] for r in rows),
        "refine_ms_median": med("refine_ms"), "emit_ms_median": med("emit_ms"),
        "update_ms_median": med("update_ms"), "lod_eval_ms_median": med("lod_eval_ms"),
        "lod_total_ms_median": med("lod_total_ms"), "floor_total_ms_median": med("floor_total_ms"),
        "floor_push_ms_median": med("floor_push_ms"), "floor_eval_ms_median": med("floor_eval_ms"),
        "lod_over_floor_total": total("lod_total_ms") / max(1e-9, total("floor_total_ms")),
        "gpu_surface_ms_median": med("gpu_surface_ms"),
        "gpu_build_ms_median": med("gpu_build_ms"),
        "gpu_note": gpu_note,
    }
    with open(os.path.join(args.out, stem + ".json"), "w") as f:
        json.dump(summary, f, indent=1)
    print("bench_blender:", json.dumps(summary), flush=True)


def _run_and_exit():
    code = 0
    try:
        main()
    except BaseException:
        import traceback
        traceback.print_exc()
        code = 1
    sys.stdout.flush()
    if not bpy.app.background:
        os._exit(code)
    if code:
        sys.exit(code)


if bpy.app.background:
    _run_and_exit()
else:
    # with a window: run once the UI (and its GPU context) is up
    bpy.app.timers.register(lambda: _run_and_exit(), first_interval=0.5)
