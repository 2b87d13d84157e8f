"""Interactive cost of each preset in Blender's real UI (run under xvfb-run):

    xvfb-run -a -s "-screen 0 1920x1080x24" blender --factory-startup \
        --python bench/bench_ui.py -- [--out bench/results]

For every planet preset (added with Add > Planet, Preview quality) and two
views of the 1586x953 viewport -- the whole planet as Add frames it, and 2 km
above the ground looking 15 degrees below the horizon -- it times the
viewport's refresh as the add-on's timer runs it (refresh.refresh: refine with
hysteresis + the surface's emission for the preview), cold (planet.reset()
first) and warm (the view moved by 0.5% of its height above the ground each
frame, 10 frames), and the GPU preview's upload of that surface
(draw._ensure_batch: the vertex buffer); for the whole-planet view also
the viewport region's redraw with the preview, with the planet hidden and with
the plain mesh of the same LOD.  Prints a table, writes ui_refresh.json.
"""
import argparse
import json
import math
import os
import statistics
import sys
import time

import bpy
from mathutils import Vector

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def view3d():
    for area in bpy.context.window_manager.windows[0].screen.areas:
        if area.type == 'VIEW_3D':
            return area, next(r for r in area.regions if r.type == 'WINDOW')


def ground_view(planet, r3d, altitude, pitch):
    from planet_lod import core
    native = core.planets.build_planet(planet.planet_lod.as_dict())
    direction = Vector((0.3, -0.8, 0.5)).normalized()
    eye = direction * (planet.planet_lod.radius + native.height(*direction) + altitude)
    east = Vector((0.0, 0.0, 1.0)).cross(direction).normalized()
    forward = east * math.cos(math.radians(pitch)) - direction * math.sin(math.radians(pitch))
    r3d.view_rotation = forward.to_track_quat('-Z', 'Y')
    r3d.view_distance = 1.0
    r3d.view_location = eye + forward
    return direction


def measure(planet, scene, move):
    from planet_lod import cameras, core, draw, refresh, runtime
    st = runtime.state(planet)
    native = core.planets.build_planet(planet.planet_lod.as_dict())
    native.reset()

    def tick_refresh():  # what the timer does: clip ranges to the horizon, then refresh
        t0 = time.perf_counter()
        cameras.fit_view_clips(scene)
        refresh.refresh(planet, scene)
        return (time.perf_counter() - t0) * 1000.0
    cold = tick_refresh()
    warm = []
    for _ in range(10):
        move()
        warm.append(tick_refresh())
    res = draw.PlanetGPU()
    t0 = time.perf_counter()
    draw._ensure_batch(res, st)
    upload = (time.perf_counter() - t0) * 1000.0
    return dict(cold_ms=round(cold, 2), warm_ms=round(statistics.median(warm), 2),
                warm_max_ms=round(max(warm), 2), sectors=st.stats.get("sectors_total"),
                drawn=st.stats.get("visible"), level=st.stats.get("max_level"),
                vertices=st.stats.get("preview_vertices"), upload_ms=round(upload, 2))


def measure_timer(planet, scene, move):
    """The timer's own path (handlers.tick, the refresh in a worker job): the
    longest tick on the main thread, each refresh's time in its job (a jump
    to a new place fills in over several progressive refreshes), and the
    time from the view's change to its first preview and to the complete
    one, cold (the planet reset) and over 10 moves."""
    from planet_lod import core, handlers, refresh, runtime
    st = runtime.state(planet)
    jobs, run = [], core.refresh.SurfaceWork.run

    def timed(work):
        t0 = time.perf_counter()
        run(work)
        jobs.append((time.perf_counter() - t0) * 1000.0)
    core.refresh.SurfaceWork.run = timed
    native = core.planets.build_planet(planet.planet_lod.as_dict())
    refresh.wait_for_jobs()
    native.reset()
    cache = native.mesh_cache_max_bytes
    native.mesh_cache_max_bytes = 0  # cold: no sector kept from before
    native.mesh_cache_max_bytes = cache
    interval, handlers.REFRESH_INTERVAL_S = handlers.REFRESH_INTERVAL_S, 0.0
    ticks, latencies, firsts = [], [], []

    def until_settled():
        st.dirty = True
        version, first = st.gpu_version, None
        start = time.perf_counter()
        while True:
            t0 = time.perf_counter()
            handlers.tick()
            ticks.append((time.perf_counter() - t0) * 1000.0)
            if first is None and st.gpu_version != version:
                first = (time.perf_counter() - start) * 1000.0
            if st.settled():
                done = (time.perf_counter() - start) * 1000.0
                firsts.append(done if first is None else first)
                return done
            time.sleep(0.002)  # the event loop's idle time
    try:
        cold_latency = until_settled()
        cold_tick, cold_first, cold_jobs = max(ticks), firsts[0], list(jobs)
        for _ in range(10):
            move()
            latencies.append(until_settled())
    finally:
        handlers.REFRESH_INTERVAL_S = interval
        core.refresh.SurfaceWork.run = run
    return dict(timer_cold_tick_ms=round(cold_tick, 2), timer_cold_latency_ms=round(cold_latency, 1),
                timer_cold_first_ms=round(cold_first, 1), timer_cold_refreshes=len(cold_jobs),
                timer_job_max_ms=round(max(jobs), 1), timer_jobs_ms=[round(j, 1) for j in jobs],
                timer_tick_max_ms=round(max(ticks), 2),
                timer_latency_ms=round(statistics.median(latencies), 1))


def redraw_ms(area, region, n=3):
    """Best of n region redraws (wm.redraw_timer), milliseconds."""
    best = float("inf")
    win = bpy.context.window_manager.windows[0]
    for _ in range(n):
        t0 = time.perf_counter()
        with bpy.context.temp_override(window=win, area=area, region=region):
            bpy.ops.wm.redraw_timer(type='DRAW', iterations=1)
        best = min(best, time.perf_counter() - t0)
    return round(best * 1000.0, 1)


def draw_costs(planet, scene, area, region):
    """Region redraw with the GPU preview, with the planet hidden, and with the
    plain mesh of the same LOD (preview off, Solid shading)."""
    from planet_lod import refresh
    out = {"draw_preview_ms": redraw_ms(area, region)}
    planet.hide_viewport = True
    out["draw_hidden_ms"] = redraw_ms(area, region)
    planet.hide_viewport = False
    planet.planet_lod.gpu_preview = False
    refresh.refresh(planet, scene, build_mesh=True)
    out["draw_mesh_ms"] = redraw_ms(area, region)
    planet.planet_lod.gpu_preview = True
    refresh.refresh(planet, scene)
    return out


def run(args):
    import addon_utils
    addon_utils.enable("planet_lod", default_set=True)
    scene = bpy.context.scene
    area, region = view3d()
    r3d = area.spaces.active.region_3d
    rows = []
    for preset in ("EARTH", "MOON", "MARS", "ASTEROID"):
        for obj in [o for o in bpy.data.objects if o.type == 'MESH']:
            bpy.data.objects.remove(obj)
        with bpy.context.temp_override(window=bpy.context.window_manager.windows[0],
                                       area=area, region=region):
            bpy.ops.mesh.planet_add(preset=preset, quality='PREVIEW')
        planet = bpy.context.object
        radius = planet.planet_lod.radius

        def orbit():
            r3d.view_rotation = (r3d.view_rotation @ Vector((0.0, 0.0, 1.0))
                                 .rotation_difference(Vector((0.001, 0.0, 1.0)))).normalized()
        rows.append(dict(preset=preset, view="whole planet", **measure(planet, scene, orbit),
                         **measure_timer(planet, scene, orbit),
                         **draw_costs(planet, scene, area, region)))
        up = ground_view(planet, r3d, 2000.0, 15.0)

        def fly():
            r3d.view_location = r3d.view_location + up * 10.0
        rows.append(dict(preset=preset, view="2 km, towards the horizon",
                         **measure(planet, scene, fly), **measure_timer(planet, scene, fly)))
        print(rows[-2], flush=True)
        print(rows[-1], flush=True)
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "ui_refresh.json"), "w") as f:
        json.dump(rows, f, indent=1)
    print(f"{'preset':9} {'view':26} {'cold':>7} {'warm':>7} {'max':>7} {'sectors':>8} "
          f"{'drawn':>6} {'vertices':>9} {'upload':>7}")
    for r in rows:
        print(f"{r['preset']:9} {r['view']:26} {r['cold_ms']:7.1f} {r['warm_ms']:7.1f} "
              f"{r['warm_max_ms']:7.1f} {r['sectors']:8} {r['drawn']:6} {r['vertices']:9} "
              f"{r['upload_ms']:7.1f}")
    print("the timer's path (refresh in a worker job), ms: longest main-thread tick cold / "
          "over all, view change to preview complete cold / warm median; cold: first "
          "preview, refreshes; longest refresh in its job")
    for r in rows:
        print(f"{r['preset']:9} {r['view']:26} {r['timer_cold_tick_ms']:7.1f} "
              f"{r['timer_tick_max_ms']:7.1f} {r['timer_cold_latency_ms']:8.1f} "
              f"{r['timer_latency_ms']:8.1f} {r['timer_cold_first_ms']:8.1f} "
              f"{r['timer_cold_refreshes']:3} {r['timer_job_max_ms']:8.1f}")
    print("whole-planet redraw of the viewport region (ms): preview / planet hidden / plain mesh")
    for r in rows:
        if "draw_preview_ms" in r:
            print(f"{r['preset']:9} {r['draw_preview_ms']:7.1f} {r['draw_hidden_ms']:7.1f} "
                  f"{r['draw_mesh_ms']:7.1f}")


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser()
    p.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    args = p.parse_args(argv)

    def step():
        try:
            run(args)
        finally:
            os._exit(0)
    bpy.context.preferences.view.show_splash = False
    bpy.app.timers.register(step, first_interval=1.0)


main()
