"""In the real UI (xvfb), a newcomer's path with every planet preset: Add >
Mesh > Planet shows the planet; the view flies to 2 km above the ground
looking over the horizon, where terrain fills the lower view; the camera is
set to that view (View > Align View > Align Active Camera to View) and F12
renders the same shot, lit: the skyline in the render (made without the sky
world, so the skyline is the terrain's edge) runs where the viewport showed
it, within 2 px, and the preview's ground is lit as the render's.  The same
shot 3 km above the Alps checks the silhouette of mountains."""
import math
import os

import bpy
import numpy as np
from mathutils import Vector

import plod_testlib as lib
import plod_uilib as ui

ALTITUDE = 2000.0
HORIZON_ABOVE_CENTRE = 6.0  # degrees: the horizon in the upper half of the shot
SOMEWHERE = Vector((0.3, -0.8, 0.5)).normalized()
ALPS = (46.0, 7.9)  # latitude, longitude (degrees): the Valais, looking east


def direction(latitude, longitude):
    lat, lon = math.radians(latitude), math.radians(longitude)
    return Vector((math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)))


def fly_to_ground(planet, r3d, up=SOMEWHERE, altitude=ALTITUDE):
    """The viewport `altitude` above the ground at direction `up`, heading
    east, pitched so the horizon sits HORIZON_ABOVE_CENTRE degrees above the
    view's centre."""
    from planet_lod import core
    native = core.planets.build_planet(planet.planet_lod.as_dict())
    ground = planet.planet_lod.radius + native.height(*up)
    eye = up * (ground + altitude)
    dip = math.degrees(math.acos(ground / (ground + altitude)))
    pitch = math.radians(dip + HORIZON_ABOVE_CENTRE)
    east = Vector((0.0, 0.0, 1.0)).cross(up).normalized()
    forward = east * math.cos(pitch) - up * math.sin(pitch)
    rotation = forward.to_track_quat('-Z', 'Y')
    local_up = rotation @ Vector((0.0, 1.0, 0.0))
    roll = local_up.rotation_difference(up - up.project(forward))
    r3d.view_perspective = 'PERSP'
    r3d.view_rotation = (roll @ rotation).normalized()
    r3d.view_distance = 1.0
    r3d.view_location = eye + forward


def skyline(image):
    """Per column, the first row (from the top) that differs from the sky --
    the median of the top rows -- by more than a threshold; as a fraction of
    the height (1.0: no ground in that column)."""
    h = image.shape[0]
    sky = np.median(image[2:max(4, h // 20)].reshape(-1, 3), axis=0)
    ground = np.abs(image - sky).sum(axis=2) > 0.1
    ground[:2] = False
    rows = np.where(ground.any(axis=0), np.argmax(ground, axis=0), h)
    return rows / h, ground


def add(preset):
    from planet_lod import runtime
    for obj in [o for o in bpy.data.objects if o.type == 'MESH']:
        bpy.data.objects.remove(obj)
    ui.view3d()[1].spaces.active.region_3d.view_perspective = 'PERSP'
    with ui.override():
        assert bpy.ops.mesh.planet_add(preset=preset) == {'FINISHED'}
    planet = bpy.context.object
    return planet, runtime.state(planet)


def frame_and_render(name, planet, st):
    """Generator: the camera to the view, a look through it, F12 without the
    sky world (the skyline is the terrain's edge); compares the preview's
    camera frame with the render."""
    _, _, region, _ = ui.view3d()
    r3d = ui.view3d()[1].spaces.active.region_3d
    scene = bpy.context.scene
    with ui.override():
        assert bpy.ops.view3d.camera_to_view() == {'FINISHED'}
    r3d.view_perspective = 'CAMERA'
    with ui.override():
        bpy.ops.view3d.view_center_camera()
    world, scene.world = scene.world, None  # viewport and render without the sky
    yield from ui.redraw(3)  # the add-on's timer sees the camera view meanwhile
    yield from ui.settled(planet)
    yield from ui.redraw(2)
    camera = scene.camera
    view = ui.screenshot(f"{name}_camera.png")
    x0, y0, x1, y1 = ui.camera_frame_rect(scene, camera, region, r3d)
    framed = view[y0:y1, x0:x1]
    preview_before = st.preview
    with ui.override():
        bpy.ops.render.render()
    scene.world = world
    assert st.preview is preview_before, "the render's LOD leaked into the viewport's"
    path = os.path.join(lib.out_dir(), f"{name}_render.png")
    bpy.data.images["Render Result"].save_render(filepath=path)
    render = ui.load_png(path)
    view_rows, view_ground = skyline(framed)
    render_rows, render_ground = skyline(render)
    columns = np.linspace(0.05, 0.95, 37)
    at_view = view_rows[(columns * framed.shape[1]).astype(int)]
    at_render = render_rows[(columns * render.shape[1]).astype(int)]
    error = float(np.median(np.abs(at_view - at_render)))
    # in the render's pixels: the preview draws the render's surface
    pixels = np.abs(at_view - at_render) * render.shape[0]
    p95 = float(np.percentile(pixels, 95))
    lit = render[render_ground].mean(axis=1) if render_ground.any() else np.zeros(1)
    preview_lit = framed[view_ground].mean() if view_ground.any() else 0.0
    print(f"{name}: ground {view_ground.mean():.1%} of the camera frame, "
          f"{render_ground.mean():.1%} of the render; skyline at "
          f"{np.median(at_view):.3f} / {np.median(at_render):.3f} of the height, median "
          f"difference {error:.3f}, 95th percentile {p95:.1f} px of {render.shape[0]}, "
          f"spread {np.ptp(at_render) * render.shape[0]:.0f} px; lit ground "
          f"{lit.mean():.3f} (preview {preview_lit:.3f}), "
          f"{st.stats.get('visible')} sectors drawn", flush=True)
    # ground under the skyline across the frame, in the viewport and the render
    assert (view_rows < 0.9).mean() > 0.9 and render_ground.mean() > 0.3, \
        f"{name}: no ground"
    assert error < 0.03, f"{name}: F12 does not show the skyline the viewport framed"
    assert p95 <= 2.0, f"{name}: the preview's skyline is not the render's"
    # lit by the same sun through the same exposure and view transform
    # (the render's ground types and shadows are not in the preview)
    assert 0.7 < preview_lit / lit.mean() < 1.4, f"{name}: the preview is not lit as the render"
    assert lit.mean() > 0.05, f"{name}: the render is dark"
    r3d.view_perspective = 'PERSP'


def test():
    lib.enable()
    from planetlod import presets
    space = ui.clean_view()
    r3d = space.region_3d
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 640, 360
    scene.render.resolution_percentage = 100
    scene.render.engine = 'BLENDER_EEVEE'
    scene.eevee.taa_render_samples = 4
    for preset in presets.PLANETS:
        planet, st = add(preset)
        yield from ui.refreshed(planet)
        mask = ui.foreground(ui.screenshot(f"{preset.lower()}_added.png"))
        print(f"{preset}: after Add, the planet covers {mask.mean():.1%} of the view",
              flush=True)
        assert 0.1 < mask.mean() < 0.9, f"{preset}: the new planet is not in view"

        since = ui.serial(planet)
        fly_to_ground(planet, r3d)
        yield from ui.refreshed(planet, since)
        ui.screenshot(f"{preset.lower()}_2km.png")
        assert not st.error and not st.warning, (st.error, st.warning)
        yield from frame_and_render(f"{preset.lower()}_2km", planet, st)

    # mountains: 3 km above the Alps, the ridges against the sky
    planet, st = add('EARTH')
    since = ui.serial(planet)
    fly_to_ground(planet, r3d, up=direction(*ALPS), altitude=3000.0)
    yield from ui.refreshed(planet, since)
    yield from frame_and_render("earth_alps_3km", planet, st)


ui.run(test)
