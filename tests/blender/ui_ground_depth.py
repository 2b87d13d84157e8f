"""In the real UI (xvfb): the 3D cursor on a previewed planet.  Shift-RMB
(the add-on's Cursor to Planet Ground) puts it on the ground under the mouse:
2 km over the Alps within 1 % of the eye's distance and within a few metres
of the ground's height (the steep relief included), and from 5,000 km on the
planet within 1 % of the distance."""
import bpy
from mathutils import Vector

import plod_uilib as ui

NEAR_METRES = 5.0  # the cursor's height above the ground at 2 km altitude


def proxy_ready(planet):
    from planet_lod import ground_proxy, runtime
    proxy = ground_proxy.proxy_of(planet)
    return proxy is not None and not ground_proxy._jobs and \
        ground_proxy._key_if_stale(planet, runtime.state(planet)) is None


def go_to(planet, altitude, pitch, ground=True):
    with ui.override():
        assert bpy.ops.view3d.planet_go_to_surface(longitude=7.9, latitude=46.0,
                                                   altitude=altitude, pitch=pitch) == {'FINISHED'}
    yield from ui.refreshed(planet)
    if ground:  # (the viewport ground exists near the ground only)
        yield from ui.wait_until(lambda: proxy_ready(planet), timeout=300,
                                 what="the viewport ground")
    yield from ui.redraw(2)
    from planet_lod import navigation
    eye = navigation.eye_of(ui.view3d()[1].spaces.active.region_3d)
    print(f"view {navigation.altitude(planet, eye):.0f} m above the ground", flush=True)


def shift_rmb(planet, space, dx, dy, found):
    """Shift-RMB `dx`, `dy` pixels from the view's centre; appends (distance
    from the eye, height above the ground, distance off the mouse's ray) to
    `found`."""
    from bpy_extras import view3d_utils
    from planet_lod import navigation
    scene = bpy.context.scene
    r3d = space.region_3d
    win, area, region, _ = ui.view3d()
    mx, my = region.width // 2 + dx, region.height // 2 + dy
    origin = view3d_utils.region_2d_to_origin_3d(region, r3d, (mx, my))
    ray = view3d_utils.region_2d_to_vector_3d(region, r3d, (mx, my)).normalized()
    before = Vector(origin) + ray * 7.0  # (somewhere the tool will not put it)
    scene.cursor.location = before
    x, y = region.x + mx, region.y + my
    yield from ui.shift_right_click(win, x, y)
    yield from ui.wait_until(lambda: (scene.cursor.location - before).length > 1e-3,
                             timeout=60, what="Shift-RMB to move the 3D cursor")
    cursor = Vector(scene.cursor.location)
    distance = (cursor - origin).length
    off_ray = (cursor - origin - ray * (cursor - origin).dot(ray)).length
    height = navigation.altitude(planet, cursor)
    print(f"Shift-RMB at ({dx}, {dy}): cursor {distance:.1f} m from the eye, "
          f"{height:.2f} m above the ground, {off_ray:.2f} m off the mouse's ray", flush=True)
    found.append((distance, height, off_ray))


def test():
    ui.lib.enable()
    space = ui.clean_view()
    with ui.override():
        assert bpy.ops.mesh.planet_add(preset='EARTH') == {'FINISHED'}
    planet = bpy.context.object
    planet.planet_lod.quality = 'DRAFT'
    yield from ui.refreshed(planet)

    # 2 km over the Alps, looking down a valley side
    yield from go_to(planet, 2000.0, -20.0)
    found = []
    for dx, dy in ((120, -80), (-260, -200), (0, -300), (300, 40)):
        yield from shift_rmb(planet, space, dx, dy, found)
    space.overlay.show_overlays = True
    yield from ui.redraw(2)
    ui.screenshot("cursor_over_the_alps.png", region='AREA')
    space.overlay.show_overlays = False
    for distance, height, off_ray in found:
        assert abs(height) < min(0.01 * distance, NEAR_METRES), "not on the ground"
        assert off_ray < 0.01 * distance, "the 3D cursor is not under the mouse"

    # from 5,000 km, looking straight down
    yield from go_to(planet, 5.0e6, -90.0, ground=False)
    found = []
    for dx, dy in ((60, 40), (-150, -90)):
        yield from shift_rmb(planet, space, dx, dy, found)
    for distance, height, off_ray in found:
        assert abs(height) < 0.01 * distance, "the 3D cursor is not on the planet"
        assert off_ray < 0.01 * distance, "the 3D cursor is not under the mouse"


ui.run(test)
