"""In the real UI (xvfb): the 3D cursor on a previewed planet.  Shift-RMB
(the add-on's Cursor to Planet Ground) and Blender's own Set 3D Cursor, which
reads the viewport's depth buffer (the preview is drawn outside it; a real
mesh under the preview stands in, as for Auto Depth, Zoom Border and Walk's
teleport), put the cursor on the ground under the mouse: 2 km over the Alps
within 1 % of the eye's distance and within a few metres of the ground's
height (the steep relief included), and from 5,000 km on the planet within
1 % of the distance; from orbit the stand-in does not show through the
preview either."""
import bpy
import numpy as np
from mathutils import Vector

import plod_uilib as ui

NEAR_METRES = 5.0  # the cursor's height above the ground at 2 km altitude


def proxy_ready(planet):
    from planet_lod import ground_proxy, runtime
    proxy = ground_proxy.proxy_of(planet)
    return proxy is not None and not ground_proxy._jobs and \
        ground_proxy._key_if_stale(planet, runtime.state(planet)) is None


def go_to(planet, altitude, pitch):
    with ui.override():
        assert bpy.ops.view3d.planet_go_to_surface(longitude=7.9, latitude=46.0,
                                                   altitude=altitude, pitch=pitch) == {'FINISHED'}
    yield from ui.refreshed(planet)
    yield from ui.wait_until(lambda: proxy_ready(planet), timeout=300,
                             what="the viewport ground")
    yield from ui.redraw(2)
    from planet_lod import navigation
    eye = navigation.eye_of(ui.view3d()[1].spaces.active.region_3d)
    print(f"view {navigation.altitude(planet, eye):.0f} m above the ground", flush=True)


def planet_cursor_key(active):
    """Turns the add-on's Shift-RMB (Cursor to Planet Ground) on or off: off,
    Blender's own Set 3D Cursor gets the click."""
    from planet_lod import navigation
    for _, item in navigation._keymaps:
        if item.idname == navigation.PLOD_OT_cursor_to_ground.bl_idname:
            item.active = active


class ShownGround:
    """The ground the preview shows now (its triangles, whose detail ends at
    their sector's resolution), for a point's height above it."""

    def __init__(self, planet):
        from mathutils.bvhtree import BVHTree
        from planet_lod import runtime
        st = runtime.state(planet)
        preview, self.anchor = st.preview, runtime.anchor(planet)
        per = preview.vertices_per_sector
        slots = np.flatnonzero(preview.slot_ids[:preview.sector_count] != 0)
        template = np.asarray(preview.template_triangles, dtype=np.int64)
        triangles = (template[None] + (slots * per)[:, None, None]).reshape(-1, 3)
        positions = preview.positions.astype(np.float64)
        self.tree = BVHTree.FromPolygons(positions.tolist(), triangles.tolist())
        self.planet = planet

    def height(self, world_point):
        """Metres above the shown ground (None: no ground below or above it)."""
        local = self.planet.matrix_world.inverted() @ Vector(world_point)
        centre = [-a for a in self.anchor]
        up = (local - Vector(centre)).normalized()
        for sign in (1.0, -1.0):
            hit = self.tree.ray_cast(local + up * 500.0 * sign, -up * sign, 1000.0)
            if hit[0] is not None:
                return (local - hit[0]).dot(up)
        return None


def shift_rmb(planet, space, dx, dy, found, shown=None):
    """Shift-RMB `dx`, `dy` pixels from the view's centre; appends (distance
    from the eye, height above the ground, distance off the mouse's ray,
    height above the ground shown) to `found`."""
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
    win.event_simulate(type='MOUSEMOVE', value='NOTHING', x=x, y=y)
    yield 0.3
    win.event_simulate(type='RIGHTMOUSE', value='PRESS', x=x, y=y, shift=True)
    yield 0.1
    win.event_simulate(type='RIGHTMOUSE', value='RELEASE', x=x, y=y, shift=True)
    yield from ui.wait_until(lambda: (scene.cursor.location - before).length > 1e-3,
                             timeout=60, what="Shift-RMB to move the 3D cursor")
    cursor = Vector(scene.cursor.location)
    distance = (cursor - origin).length
    off_ray = (cursor - origin - ray * (cursor - origin).dot(ray)).length
    height = navigation.altitude(planet, cursor)
    on_shown = shown.height(cursor) if shown is not None else None
    print(f"Shift-RMB at ({dx}, {dy}): cursor {distance:.1f} m from the eye, "
          f"{height:.2f} m above the ground ({on_shown} above the ground shown), "
          f"{off_ray:.2f} m off the mouse's ray", flush=True)
    found.append((distance, height, off_ray, on_shown))


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
    found, depth_found = [], []
    shown = ShownGround(planet)
    points = ((120, -80), (-260, -200), (0, -300), (300, 40))
    for dx, dy in points:
        yield from shift_rmb(planet, space, dx, dy, found, shown)
    planet_cursor_key(False)
    print("Blender's Set 3D Cursor (the viewport's depth):", flush=True)
    for dx, dy in points:
        yield from shift_rmb(planet, space, dx, dy, depth_found, shown)
    planet_cursor_key(True)
    space.overlay.show_overlays = True
    yield from ui.redraw(2)
    ui.screenshot("cursor_over_the_alps.png", region='AREA')
    space.overlay.show_overlays = False
    # the add-on's cursor: on the planet's ground; Blender's: on the ground shown
    for distance, height, off_ray, _ in found:
        assert abs(height) < min(0.01 * distance, NEAR_METRES), "not on the ground"
        assert off_ray < 0.01 * distance, "the 3D cursor is not under the mouse"
    for distance, height, off_ray, on_shown in depth_found:
        assert abs(height) < 0.01 * distance, "the 3D cursor is not on the ground"
        assert on_shown is not None and abs(on_shown) < NEAR_METRES, \
            "the 3D cursor is not on the ground shown"
        assert off_ray < 0.01 * distance, "the 3D cursor is not under the mouse"

    # from 5,000 km, looking straight down
    yield from go_to(planet, 5.0e6, -90.0)
    found = []
    for active in (True, False):
        planet_cursor_key(active)
        for dx, dy in ((60, 40), (-150, -90)):
            yield from shift_rmb(planet, space, dx, dy, found)
    planet_cursor_key(True)
    for distance, height, off_ray, _ in found:
        assert abs(height) < 0.01 * distance, "the 3D cursor is not on the planet"
        assert off_ray < 0.01 * distance, "the 3D cursor is not under the mouse"
    # the stand-in under the preview does not show through it from orbit
    from planet_lod import ground_proxy
    proxy = ground_proxy.proxy_of(planet)
    yield from ui.redraw(3)
    with_ground = ui.screenshot("orbit_ground_shown.png")
    proxy.hide_set(True)
    yield from ui.redraw(3)
    without = ui.screenshot("orbit_ground_hidden.png")
    proxy.hide_set(False)
    differs = (np.abs(with_ground - without).sum(axis=2) > 0.1).mean()
    print(f"orbit: pixels the viewport ground changes: {differs:.5f}", flush=True)
    assert differs < 0.002, "the viewport ground shows through the preview from orbit"


ui.run(test)
