"""In the real UI (xvfb): near the ground of a previewed planet.

* The viewport's sky is the render's: a camera 2 km above the Alps, looking a
  little above the horizon: in camera view the solid viewport's sky (above
  the planet preview) is blue, not Blender's grey background, and matches the
  sky a Cycles render of the same camera gets, and its ground below the
  horizon the render's ground colour; from orbit the viewport's space is
  black around the planet.
* Shift-RMB puts the 3D cursor on the planet's ground under the mouse (the
  preview is drawn outside the depth buffer Blender's own cursor reads).
* Blender's own depth-based tools see the planet through its viewport
  ground (a coarse mesh under the preview, which draws over it): Zoom
  Border over the ground zooms in (without it: "Depth too large"), Walk's
  teleport lands near the ground, above it.
* The wheel zooms towards the ground in shrinking steps, never through it;
  near the ground no bounding box crosses the sky."""
import os

import bpy
import numpy as np
from mathutils import Vector

import plod_testlib as lib
import plod_uilib as ui


# Largest difference per display channel (0..1) between the viewport's and a
# render's mean ground colour in camera view.  Both show the same colour map
# and ground types under the same sun (Lambert: strength x cos / pi) and haze
# through the same view transform; the render adds what the preview leaves
# out: bounced light, shadows and the ground's small-scale tints (fields,
# canopy, rock blocks).  On the Alps' snow with the sun 50 degrees high they
# differ by about 0.03 (the render a little brighter); Cycles' noise at 4 samples,
# averaged over the band's ~250 pixels, stays under 0.01.
GROUND_TOLERANCE = 0.1


def refreshed(planet):
    from planet_lod import runtime
    st = runtime.state(planet)
    yield from ui.wait_until(lambda: st.settled() and st.preview is not None, timeout=300,
                             what="the viewport refresh")
    yield from ui.redraw(2)


def status_bar(window_image):
    """The left half of the status bar (its text), from a window screenshot:
    the window's bottom strip (a global area, not among the screen's areas)."""
    height = round(20 * bpy.context.preferences.system.ui_scale)
    part = window_image[-height:]
    return part[:, :part.shape[1] // 2]


def sky_band(image, rect):
    """Mean display colour of the top fifth of `rect` (x0, y0, x1, y1), inset."""
    x0, y0, x1, y1 = rect
    dx = (x1 - x0) // 10
    band = image[y0 + 2:y0 + max((y1 - y0) // 5, 3), x0 + dx:x1 - dx]
    return band.reshape(-1, 3).mean(axis=0)


def ground_band(image, rect):
    """Mean display colour of the bottom fifth of `rect` (x0, y0, x1, y1), inset."""
    x0, y0, x1, y1 = rect
    dx = (x1 - x0) // 10
    band = image[y1 - max((y1 - y0) // 5, 3):y1 - 2, x0 + dx:x1 - dx]
    return band.reshape(-1, 3).mean(axis=0)


def render_camera(scene):
    """(sky, ground): the mean colours of a small Cycles render's sky and ground bands."""
    scene.render.resolution_x, scene.render.resolution_y = 64, 36
    scene.render.resolution_percentage = 100
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = 4
    scene.cycles.use_denoising = False
    scene.render.image_settings.file_format = 'PNG'
    path = os.path.join(lib.out_dir(), "camera_render.png")
    scene.render.filepath = path
    with ui.override():
        bpy.ops.render.render(write_still=True)
    image = ui.load_png(path)
    whole = (0, 0, image.shape[1], image.shape[0])
    return sky_band(image, whole), ground_band(image, whole)


def test():
    ui.lib.enable()
    space = ui.clean_view()
    scene = bpy.context.scene
    # Add > Planet says what it does in the status bar while it builds
    before = status_bar(ui.screenshot("status_before.png", region='WINDOW'))
    with ui.override():
        assert bpy.ops.mesh.planet_add('INVOKE_DEFAULT', preset='EARTH') == {'RUNNING_MODAL'}
    yield 0.02
    during = status_bar(ui.screenshot("status_building.png", region='WINDOW'))
    changed = float(np.abs(during - before).sum(axis=2).max(axis=0).mean())
    print(f"status bar while building: {changed:.3f} of its columns changed", flush=True)
    assert changed > 0.05, "no status line while the planet builds"
    yield from ui.wait_until(lambda: "Earth" in bpy.data.objects, timeout=600,
                             what="Add > Planet to finish")
    planet = bpy.data.objects["Earth"]
    planet.planet_lod.quality = 'DRAFT'
    sun = bpy.data.objects["Sun"]  # the sun Add > Planet put in the scene
    yield from refreshed(planet)

    # from orbit: black space around the planet, as the render's world
    image = ui.screenshot("sky_orbit.png")
    corner = image[:20, :20].reshape(-1, 3).mean(axis=0)
    print(f"orbit: space {np.round(corner, 3)}", flush=True)
    assert corner.max() < 0.05, f"space is not black around the planet: {corner}"

    cam = bpy.data.objects.new("Shot", bpy.data.cameras.new("Shot"))
    cam.data.lens = 24.0
    cam.data.clip_start, cam.data.clip_end = 0.5, 1.0e8
    scene.collection.objects.link(cam)
    scene.camera = cam
    geo = cam.planet_lod_geo
    geo.planet = planet
    geo.longitude, geo.latitude, geo.altitude = 7.9, 46.0, 2000.0
    geo.heading, geo.pitch = 200.0, 5.0
    geo.floating_origin = True
    geo.enabled = True
    r3d = space.region_3d
    r3d.view_perspective = 'CAMERA'
    yield from refreshed(planet)
    # the sun 50 degrees high, behind the camera
    from planet_lod import navigation
    up = (cam.matrix_world.translation - navigation.planet_centre(planet)).normalized()
    back = cam.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0))
    back = (back - back.project(up)).normalized()
    sun.rotation_euler = (up * 1.2 + back).normalized().to_track_quat('Z', 'Y').to_euler()
    yield from refreshed(planet)
    yield from ui.redraw(3)
    win, area, region, _ = ui.view3d()
    image = ui.screenshot("sky_ground_camera_view.png")
    rect = ui.camera_frame_rect(scene, cam, region, r3d)
    viewport = sky_band(image, rect)
    viewport_soil = ground_band(image, rect)
    print(f"camera view: frame {rect}, viewport sky {np.round(viewport, 3)}, ground "
          f"{np.round(viewport_soil, 3)}", flush=True)
    assert viewport[2] > viewport[0] + 0.1 and viewport[2] > 0.35, \
        f"the viewport's sky is not blue near the ground: {viewport}"
    rendered, rendered_soil = render_camera(scene)
    print(f"render sky {np.round(rendered, 3)}, difference "
          f"{np.round(np.abs(viewport - rendered), 3)}", flush=True)
    assert rendered[2] > rendered[0], f"the render's sky is not blue: {rendered}"
    assert np.abs(viewport - rendered).max() < 0.12, \
        f"viewport sky {viewport} against the render's {rendered}"
    # the ground below the horizon likewise: the same colour map, sun and haze;
    # the render adds the sky's light and the ground's small-scale colours
    # (field, forest and rock tints that average to the map's colour)
    print(f"render ground {np.round(rendered_soil, 3)}, difference "
          f"{np.round(np.abs(viewport_soil - rendered_soil), 3)}", flush=True)
    assert np.abs(viewport_soil - rendered_soil).max() < GROUND_TOLERANCE, \
        f"viewport ground {viewport_soil} against the render's {rendered_soil}"

    yield from cursor_on_ground(planet, space)
    yield from viewport_ground(planet, space)
    yield from zoom_border(planet, space)
    yield from walk_teleport(planet, space)
    yield from zoom_and_horizon(planet, space)


def cursor_on_ground(planet, space):
    from planet_lod import navigation
    r3d = space.region_3d
    with ui.override():
        assert bpy.ops.view3d.planet_go_to_surface(longitude=7.9, latitude=46.0,
                                                   altitude=2000.0, pitch=-20.0) == {'FINISHED'}
    yield from refreshed(planet)
    scene = bpy.context.scene
    scene.cursor.location = (0.0, 0.0, 0.0)
    win, area, region, _ = ui.view3d()
    from bpy_extras import view3d_utils
    # a point right of and below the view's centre
    mx, my = region.width // 2 + 120, region.height // 2 - 80
    origin = view3d_utils.region_2d_to_origin_3d(region, r3d, (mx, my))
    ray = view3d_utils.region_2d_to_vector_3d(region, r3d, (mx, my)).normalized()
    x, y = region.x + mx, region.y + my
    yield from ui.shift_right_click(win, x, y)
    yield from ui.wait_until(lambda: scene.cursor.location.length > 1.0, timeout=60,
                             what="Shift-RMB to move the 3D cursor")
    yield from ui.redraw(2)
    cursor = Vector(scene.cursor.location)
    distance = (cursor - origin).length
    off_ray = (cursor - origin - ray * (cursor - origin).dot(ray)).length
    height = navigation.altitude(planet, cursor)
    print(f"Shift-RMB: cursor {distance:.1f} m from the eye, {height:.2f} m above the ground, "
          f"{off_ray:.2f} m off the mouse's ray", flush=True)
    assert abs(height) < 0.01 * distance, "the 3D cursor is not on the planet's ground"
    assert off_ray < 0.01 * distance, "the 3D cursor is not under the mouse"
    space.overlay.show_overlays = True  # the cursor drawn
    yield from ui.redraw(2)
    ui.screenshot("cursor_on_ground.png", region='AREA')



def go_to_surface(planet, pitch=-20.0):
    with ui.override():
        assert bpy.ops.view3d.planet_go_to_surface(longitude=7.9, latitude=46.0,
                                                   altitude=2000.0, pitch=pitch) == {'FINISHED'}
    yield from refreshed(planet)


def proxy_ready(planet):
    from planet_lod import ground_proxy, runtime
    proxy = ground_proxy.proxy_of(planet)
    return proxy is not None and not ground_proxy._jobs and \
        ground_proxy._key_if_stale(planet, runtime.state(planet)) is None


def viewport_ground(planet, space):
    """The viewport ground exists under a previewed planet, out of renders and
    selection, and the preview draws over it: the view looks the same with
    it hidden; no orange box (the selected planet's bounds) in the sky."""
    from planet_lod import ground_proxy, runtime
    yield from go_to_surface(planet, pitch=5.0)
    yield from ui.wait_until(lambda: proxy_ready(planet), timeout=120,
                             what="the viewport ground")
    proxy = ground_proxy.proxy_of(planet)
    assert proxy.hide_render and proxy.hide_select and proxy not in runtime.planet_objects(
        bpy.context.scene)
    print(f"viewport ground: {len(proxy.data.vertices)} vertices, "
          f"{len(proxy.data.polygons)} triangles", flush=True)
    planet.select_set(True)
    bpy.context.view_layer.objects.active = planet
    space.overlay.show_overlays = True
    yield from ui.redraw(3)
    with_ground = ui.screenshot("viewport_ground_shown.png")
    orange = (np.abs(with_ground - np.array([1.0, 0.63, 0.16])).max(axis=2) < 0.12).mean()
    print(f"orange pixels near the ground: {orange:.5f}", flush=True)
    assert orange < 1e-4, "the planet's bounding box shows near the ground"
    proxy.hide_set(True)
    yield from ui.redraw(3)
    without = ui.screenshot("viewport_ground_hidden.png")
    proxy.hide_set(False)
    space.overlay.show_overlays = False
    differs = (np.abs(with_ground - without).sum(axis=2) > 0.1).mean()
    print(f"pixels the viewport ground changes: {differs:.5f}", flush=True)
    assert differs < 0.002, "the viewport ground shows through the preview"


def zoom_border(planet, space):
    """Zoom Border over the ground reads the depth there: without the viewport
    ground Blender cancels it ("Depth too large")."""
    from planet_lod import ground_proxy, navigation
    r3d = space.region_3d
    yield from go_to_surface(planet)
    yield from ui.wait_until(lambda: proxy_ready(planet), timeout=120,
                             what="the viewport ground")
    win, area, region, _ = ui.view3d()
    box = dict(xmin=region.width // 2 - 60, xmax=region.width // 2 + 60,
               ymin=region.height // 2 - 140, ymax=region.height // 2 - 40, wait_for_input=False)
    proxy = ground_proxy.proxy_of(planet)
    proxy.hide_set(True)
    yield from ui.redraw(2)
    try:
        with ui.override():
            without = bpy.ops.view3d.zoom_border(**box)
    except RuntimeError as exc:  # Blender's error report
        without = str(exc)
    proxy.hide_set(False)
    yield from ui.redraw(2)
    before = navigation.altitude(planet, navigation.eye_of(r3d))
    with ui.override():
        result = bpy.ops.view3d.zoom_border(**box)
    yield from ui.redraw(2)
    after = navigation.altitude(planet, navigation.eye_of(r3d))
    print(f"Zoom Border: {result} ({without} without the viewport ground), altitude "
          f"{before:.0f} m -> {after:.0f} m", flush=True)
    assert "Depth too large" in str(without) and result == {'FINISHED'}
    assert 0.0 < after < before


def walk_teleport(planet, space):
    """Walk's teleport (Space) flies to the ground at the view's centre and
    stops near it, above it."""
    from bpy_extras import view3d_utils
    from planet_lod import navigation
    r3d = space.region_3d
    yield from go_to_surface(planet)
    yield from ui.wait_until(lambda: proxy_ready(planet), timeout=120,
                             what="the viewport ground")
    win, area, region, _ = ui.view3d()
    mx, my = region.width // 2, region.height // 2
    origin = view3d_utils.region_2d_to_origin_3d(region, r3d, (mx, my))
    ray = view3d_utils.region_2d_to_vector_3d(region, r3d, (mx, my)).normalized()
    target = navigation.ground_hit(planet, origin, ray)
    assert target is not None
    x, y = region.x + mx, region.y + my
    win.event_simulate(type='MOUSEMOVE', value='NOTHING', x=x, y=y)
    yield 0.3
    with ui.override():
        assert bpy.ops.view3d.walk('INVOKE_DEFAULT') == {'RUNNING_MODAL'}
    yield from ui.redraw(2)
    win.event_simulate(type='SPACE', value='PRESS', x=x, y=y)
    win.event_simulate(type='SPACE', value='RELEASE', x=x, y=y)
    yield from ui.redraw(6)
    win.event_simulate(type='RET', value='PRESS', x=x, y=y)
    win.event_simulate(type='RET', value='RELEASE', x=x, y=y)
    yield from ui.redraw(3)
    start = (target - origin).length

    def eye_height():
        return navigation.altitude(planet, navigation.eye_of(r3d))
    yield from ui.wait_until(lambda: eye_height() > 0.0, timeout=30,
                             what="the eye above the ground after the teleport")
    left = (navigation.eye_of(r3d) - target).length
    print(f"Walk teleport: {start:.0f} m to the ground point, {left:.1f} m from it after, "
          f"{eye_height():.1f} m above the ground", flush=True)
    # (the viewport ground lies up to a few hundred metres under the Alps'
    # ground: the teleport ends beyond the point, under the ground, and the
    # view is taken back along its ray above it)
    assert left < 0.05 * start, "Walk's teleport did not stop at the ground"


def zoom_and_horizon(planet, space):
    """The wheel never takes the view through the ground; a rolled view near
    the ground comes back level with the planet's local up."""
    import math
    from planet_lod import navigation
    r3d = space.region_3d
    win, area, region, _ = ui.view3d()
    x, y = region.x + region.width // 2, region.y + region.height // 2
    yield from go_to_surface(planet)

    def measure():
        eye = navigation.eye_of(r3d)
        ahead = r3d.view_rotation @ Vector((0.0, 0.0, -1.0))
        hit = navigation.ground_hit(planet, eye, ahead)
        return navigation.altitude(planet, eye), (hit - eye).length if hit else None
    heights, distances = zip(*[measure()])
    heights, distances = list(heights), list(distances)
    for notches in (3, 20):
        for _ in range(notches):
            win.event_simulate(type='MOUSEMOVE', value='NOTHING', x=x, y=y)
            win.event_simulate(type='WHEELUPMOUSE', value='PRESS', x=x, y=y)
            yield 0.05
            assert navigation.altitude(planet, navigation.eye_of(r3d)) > 0.0
        yield from ui.redraw(2)
        height, distance = measure()
        heights.append(height)
        distances.append(distance)
    print("after 0, 3 and 23 wheel notches: altitude "
          + ", ".join(f"{h:.1f} m" for h in heights) + "; ground ahead "
          + ", ".join(f"{d:.1f} m" for d in distances), flush=True)
    # each notch takes a sixth of the distance left to the ground ahead (the
    # altitude above the ground below can grow, over a valley), never through it
    assert min(heights) > 0.0 and None not in distances, (heights, distances)
    assert 0.5 < distances[1] / distances[0] < 0.65, distances
    assert distances[2] / distances[0] < 0.03, distances

    forward = r3d.view_rotation @ Vector((0.0, 0.0, -1.0))
    from mathutils import Quaternion
    r3d.view_rotation = (Quaternion(forward, math.radians(20.0)) @ r3d.view_rotation).normalized()

    def tilt():
        eye = navigation.eye_of(r3d)
        up = (eye - navigation.planet_centre(planet)).normalized()
        ahead = r3d.view_rotation @ Vector((0.0, 0.0, -1.0))
        wanted = (up - up.project(ahead)).normalized()
        return math.degrees((r3d.view_rotation @ Vector((0.0, 1.0, 0.0))).angle(wanted, 0.0))
    print(f"horizon rolled by {tilt():.1f} degrees", flush=True)
    yield from ui.wait_until(lambda: tilt() < 0.1, timeout=60, what="the horizon to level")
    yield from ui.redraw(2)
    print(f"horizon levelled to {tilt():.3f} degrees", flush=True)
    ui.screenshot("horizon_levelled.png", region='AREA')


ui.run(test)
