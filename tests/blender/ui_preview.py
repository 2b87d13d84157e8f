"""In the real UI (xvfb), the GPU preview: the 16-bit presets (Mars-like,
asteroid) show their relief; a whole-planet view at Blender's default clip
start shows none of the far hemisphere; a view limited by the sector budget
near the asteroid's ground is covered by terrain, not emptied."""
import math
import threading

import bpy
import numpy as np
from mathutils import Matrix, Vector

import plod_testlib as lib
import plod_uilib as ui


def add(preset, **settings):
    for obj in [o for o in bpy.data.objects if o.type == 'MESH']:
        bpy.data.objects.remove(obj)
    with ui.override():
        assert bpy.ops.mesh.planet_add(preset=preset) == {'FINISHED'}
    planet = bpy.context.object
    for key, value in settings.items():
        setattr(planet.planet_lod, key, value)
    return planet


def refreshed(planet):
    """Generator: waits for the viewport's refresh of `planet` and two redraws."""
    from planet_lod import runtime
    st = runtime.state(planet)
    yield from ui.wait_until(lambda: st.settled() and st.preview is not None,
                             what="the viewport refresh")
    yield from ui.redraw(2)


def ground_view(planet, altitude, pitch):
    """Points the viewport from `altitude` metres above the ground, `pitch`
    degrees below the horizon, heading east, upright."""
    from planet_lod import core
    native = core.planets.build_planet(planet.planet_lod.as_dict())
    direction = Vector((0.3, -0.8, 0.5)).normalized()
    eye = direction * (planet.planet_lod.radius + native.height(*direction) + altitude)
    east = Vector((0.0, 0.0, 1.0)).cross(direction).normalized()
    forward = (east * math.cos(math.radians(pitch)) - direction * math.sin(math.radians(pitch)))
    _, area, _, _ = ui.view3d()
    r3d = area.spaces.active.region_3d
    rotation = forward.to_track_quat('-Z', 'Y')
    up = rotation @ Vector((0.0, 1.0, 0.0))  # roll the view upright: the local up
    roll = up.rotation_difference(direction - direction.project(forward))
    r3d.view_rotation = (roll @ rotation).normalized()
    r3d.view_distance = 1.0
    r3d.view_location = eye + forward * 1.0


def relief(preset):
    """The preview with the preset's relief against the same view with the
    height scale at 0: the asteroid whole and lit from the side (the
    terminator across it: its relief changes the outline and the shading),
    Mars-like from 2% of its radius up towards the horizon (its slopes are
    gentle, 99% below 2%: the relief shows in the skyline)."""
    planet = add(preset)
    _, area, _, _ = ui.view3d()
    r3d = area.spaces.active.region_3d
    if preset == 'MARS':
        ground_view(planet, 0.02 * planet.planet_lod.radius, 2.0)
    else:
        r3d.view_distance = 2.6 * planet.planet_lod.radius
        r3d.view_rotation = Vector((0.5, -1.0, 0.4)).to_track_quat('Z', 'Y')
        sun = next(o for o in bpy.data.objects if o.type == 'LIGHT' and o.data.type == 'SUN')
        side = r3d.view_rotation @ Vector((1.0, 0.0, 0.0))
        sun.rotation_euler = side.to_track_quat('Z', 'Y').to_euler()
    yield 0.3
    yield from refreshed(planet)
    with_relief = ui.screenshot(f"relief_{preset.lower()}.png")
    mask = ui.foreground(with_relief)
    planet.planet_lod.height_scale = 0.0
    yield 0.3
    yield from refreshed(planet)
    flat = ui.screenshot(f"relief_{preset.lower()}_flat.png")
    both = mask & ui.foreground(flat)
    a, b = ui.detail(with_relief, both), ui.detail(flat, both)
    change = float(np.abs(with_relief - flat).sum(axis=2)[both].mean())
    skyline = float((mask != ui.foreground(flat)).mean())
    print(f"{preset}: detail {a:.4f} with relief, {b:.4f} flat (ratio {a / max(b, 1e-9):.2f}), "
          f"mean change {change:.3f}, skyline moved over {skyline:.1%} of the view, "
          f"ground {mask.mean():.1%} of the view", flush=True)
    assert mask.mean() > 0.2
    if preset == 'MARS':  # ~1500 pixels of skyline moved by the relief
        assert skyline > 0.001, f"{preset}: no relief in the preview"
    else:  # the asteroid's lumps and hollows change its outline and its shading
        assert skyline > 0.05 and change > 0.05, f"{preset}: no relief in the preview"


def far_side():
    """The same whole-planet view three ways: a reference whose clip range ends
    at the horizon (nothing of the far side can be drawn), Blender's default
    clip start with Horizon Clip on, and the default clip start with a huge clip
    end and Horizon Clip off (culling alone).  All three must agree."""
    planet = add('EARTH')
    _, area, _, _ = ui.view3d()
    space = area.spaces.active
    r3d = space.region_3d
    radius = planet.planet_lod.radius
    r3d.view_distance = 2.2 * radius
    r3d.view_rotation = Vector((0.3, -1.0, 0.25)).to_track_quat('Z', 'Y')
    d = r3d.view_distance
    s = planet.planet_lod
    s.view_clip_from_horizon = False
    space.clip_start, space.clip_end = 0.5 * (d - radius), math.sqrt(d * d - radius * radius)
    yield 0.3
    yield from refreshed(planet)
    reference = ui.screenshot("far_reference.png")
    shots = {}
    s.view_clip_from_horizon = True
    space.clip_start, space.clip_end = 0.01, 1000.0  # Blender's defaults
    yield from ui.wait_until(lambda: space.clip_start > 1.0, what="the horizon clip")
    yield from refreshed(planet)
    shots["default clip start, Horizon Clip"] = ui.screenshot("far_managed.png")
    s.view_clip_from_horizon = False
    space.clip_start, space.clip_end = 0.01, 1.0e10
    yield 0.3
    yield from refreshed(planet)
    shots["default clip start, clip end 1e10, culling only"] = ui.screenshot("far_culled.png")
    mask = ui.foreground(reference)
    for name, shot in shots.items():
        diff = np.abs(shot - reference).sum(axis=2) > 0.15
        print(f"far side, {name}: {diff[mask].mean():.3%} of the planet's pixels differ from "
              f"the horizon-clipped reference", flush=True)
        assert diff[mask].mean() < 0.005, name


def budget():
    """2 km above the asteroid's ground, looking 15 degrees below the horizon, with
    a budget far below what the view asks for: the ground still fills the view."""
    planet = add('ASTEROID', budget=1500)
    from planet_lod import runtime
    ground_view(planet, 2000.0, 15.0)
    yield 0.5
    yield from refreshed(planet)
    st = runtime.state(planet)
    shot = ui.screenshot("budget_asteroid.png")
    mask = ui.foreground(shot)
    print(f"budget 1500 at 2 km: {st.stats['sectors_total']} sectors kept, "
          f"{st.stats['visible']} drawn, level {st.stats['max_level']}; terrain covers "
          f"{mask.mean():.1%} of the view", flush=True)
    assert st.stats["sectors_total"] <= 1500 and st.stats["visible"] > 100
    assert mask.mean() > 0.4, "the budget emptied the view"
    planet.planet_lod.budget = 0
    yield from refreshed(planet)
    print(f"unlimited: {st.stats['sectors_total']} sectors, {st.stats['visible']} drawn, "
          f"level {st.stats['max_level']}", flush=True)


def refresh_job():
    """The timer refreshes the preview in a worker job: the tick that starts it
    returns with the previous preview still drawn, a later tick applies the new
    one; a jump to a new place fills in over several bounded (progressive)
    refreshes; a refresh made while the job runs (an operator, a render) makes
    the job's result stale, and the planet refreshes again for the view."""
    planet = add('MOON')
    from planet_lod import core, refresh, runtime
    st = runtime.state(planet)
    yield from refreshed(planet)
    gate, run = threading.Event(), core.refresh.SurfaceWork.run
    jobs = []

    def held(work):  # keeps a job in flight until the test lets it go
        if threading.current_thread() is not threading.main_thread():
            jobs.append(work)
            gate.wait(30)
        run(work)
    core.refresh.SurfaceWork.run = held
    try:
        ground_view(planet, 2000.0, 15.0)  # a new place: every sector in view is new
        before = st.preview
        yield from ui.wait_until(lambda: st.job is not None, what="a refresh job")
        yield 0.3  # ticks go on while the job works
        assert st.job is not None and st.preview is before and not st.dirty
        gate.set()
        yield from refreshed(planet)
        assert st.preview is not before and st.stats["visible"] > 100, st.stats
        # progressive: the jump filled in over several bounded refreshes, the
        # last one complete
        assert len(jobs) >= 2 and all(w.max_splits > 0 for w in jobs), len(jobs)
        assert jobs[0].stats["pending"] and not st.stats["pending"], st.stats
        job_surface = st.preview
        # a refresh on the main thread while a job is in flight: the job is dropped
        gate.clear()
        _, area, _, _ = ui.view3d()
        r3d = area.spaces.active.region_3d
        r3d.view_location = r3d.view_location + Vector((0.0, 0.0, 500.0))
        yield from ui.wait_until(lambda: st.job is not None, what="a refresh job")
        serial = st.job.serial
        threading.Timer(0.3, gate.set).start()
        refresh.refresh(planet, bpy.context.scene)  # waits for the job's lock
        assert st.serial > serial
        yield from refreshed(planet)
        assert st.preview is not job_surface and not st.error
    finally:
        gate.set()
        core.refresh.SurfaceWork.run = run


def test():
    lib.enable()
    ui.clean_view()
    for preset in ("ASTEROID", "MARS"):
        yield from relief(preset)
    yield from far_side()
    yield from budget()
    yield from refresh_job()


ui.run(test)
