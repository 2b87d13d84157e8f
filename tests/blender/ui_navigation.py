"""In the real UI (xvfb): an artist's second hour with a planet.

* Both preset menus open with their entries (Blender 3.4 once opened them
  empty); an entry picked with the keyboard applies its preset, the menu's
  button names it, the planet is renamed after its new preset and framed.
* A camera placed by longitude and latitude moves the floating origin: the
  planet stays where it was on screen, and Frame Selected (numpad .) frames
  the whole planet, not the box around the camera.
* Go to Surface puts the view 2 km above a given point; the altitude readout
  says so."""
import math

import bpy
from mathutils import Vector

import plod_uilib as ui


class MenuRecorder:
    """Counts the draws of a menu class and keeps the entries it drew."""

    def __init__(self, cls):
        self.count = 0
        self.errors = []
        draw = cls.draw

        def recorded(menu, context):
            try:
                draw(menu, context)
            except BaseException as exc:
                self.errors.append(f"{type(exc).__name__}: {exc}")
                raise
            self.count += 1
        cls.draw = recorded


def disk_of_view(name):
    mask = ui.foreground(ui.screenshot(name))
    found = ui.disk(mask)
    print(f"{name}: planet covers {mask.mean():.1%} of the view, disk {found}", flush=True)
    return mask.mean(), found


def refreshed(planet):
    from planet_lod import runtime
    st = runtime.state(planet)
    yield from ui.wait_until(lambda: st.settled() and st.preview is not None, timeout=120,
                             what="the viewport refresh")
    yield from ui.redraw(2)


def pick_from_menu(menu_cls, recorder, index):
    """Generator: opens a menu over the viewport, waits until it has drawn and
    clicks its `index`-th entry (Blender opens a menu with its first entry
    under the mouse; entries are a widget unit and a pixel apart)."""
    win, area, region, _ = ui.view3d()
    x, y = region.x + region.width // 2, region.y + region.height // 2
    win.event_simulate(type='MOUSEMOVE', value='NOTHING', x=x, y=y)
    yield 0.2
    before = recorder.count
    with ui.override():
        bpy.ops.wm.call_menu(name=menu_cls.__name__)
    yield from ui.wait_until(lambda: recorder.count > before, timeout=60,
                             what=f"{menu_cls.__name__} to draw")
    yield 0.5
    step = round(21 * bpy.context.preferences.system.ui_scale)
    for i in range(1, index + 1):
        win.event_simulate(type='MOUSEMOVE', value='NOTHING', x=x, y=y - i * step)
        yield 0.2
    ui.screenshot(f"menu_{menu_cls.__name__}.png", region='WINDOW')
    ui.simulate_click(win, x, y - index * step)


def test():
    ui.lib.enable()
    from planet_lod import navigation, preset_menus, view_follow
    space = ui.clean_view()
    r3d = space.region_3d
    planet_menu = MenuRecorder(bpy.types.PLOD_MT_planet_presets)
    quality_menu = MenuRecorder(bpy.types.PLOD_MT_quality_presets)
    with ui.override():
        assert bpy.ops.mesh.planet_add(preset='EARTH') == {'FINISHED'}
    planet = bpy.context.object
    assert planet.name == "Earth"
    cube = bpy.data.objects["Cube"]  # the factory Cube, inside the new planet
    assert cube.hide_render and cube.hide_viewport, "the Cube inside the planet is not hidden"
    yield from refreshed(planet)

    # ---- the preset menus: entries drawn, one picked, the planet renamed and framed
    entries = ["Asteroid", "Earth", "Mars-like", "Moon"]
    yield from pick_from_menu(preset_menus.PLOD_MT_planet_presets, planet_menu,
                              entries.index("Moon"))
    yield from ui.wait_until(lambda: planet.planet_lod.preset == 'MOON', timeout=60,
                             what="the Moon preset from the menu")
    assert not planet_menu.errors, planet_menu.errors
    assert planet.name == "Moon", f"the planet is still called {planet.name}"
    assert preset_menus.PLOD_MT_planet_presets.button_text(bpy.context) == "Moon"
    assert abs(planet.planet_lod.radius - 1737400.0) < 1.0
    yield from refreshed(planet)
    cover, _ = disk_of_view("preset_moon.png")
    assert 0.1 < cover < 0.9, "the Moon is not framed after its preset"

    yield from pick_from_menu(preset_menus.PLOD_MT_quality_presets, quality_menu,
                              ["Draft", "Final", "Preview"].index("Draft"))
    yield from ui.wait_until(lambda: planet.planet_lod.quality == 'DRAFT', timeout=60,
                             what="the Draft quality from the menu")
    assert not quality_menu.errors, quality_menu.errors
    assert preset_menus.PLOD_MT_quality_presets.button_text(bpy.context) == "Draft"
    print(f"menus drawn: planet {planet_menu.count}, quality {quality_menu.count}", flush=True)

    # ---- a camera placed by longitude/latitude moves the floating origin
    with ui.override():
        assert bpy.ops.object.planet_apply_preset(planet='EARTH') == {'FINISHED'}
    assert planet.name == "Earth"
    yield from refreshed(planet)
    _, before = disk_of_view("before_placement.png")
    cam = bpy.data.objects.new("Shot", bpy.data.cameras.new("Shot"))
    bpy.context.scene.collection.objects.link(cam)
    geo = cam.planet_lod_geo
    geo.planet = planet
    geo.longitude, geo.latitude, geo.altitude = 10.0, 45.0, 3000.0
    geo.floating_origin = True
    geo.enabled = True
    yield from ui.wait_until(lambda: any(abs(v) > 1e5 for v in planet.get("planet_lod_anchor",
                                                                         (0, 0, 0))),
                             timeout=60, what="the floating origin to move")
    yield from refreshed(planet)
    _, after = disk_of_view("after_placement.png")
    jump = math.hypot(after[0] - before[0], after[1] - before[1])
    print(f"the planet moved {jump:.1f} px on screen when the origin moved", flush=True)
    assert jump < 3.0, "the planet jumped when the floating origin moved"

    # Frame Selected (numpad .) with the planet selected frames the whole planet
    win, area, region, _ = ui.view3d()
    r3d.view_location = Vector((0.0, 0.0, 0.0))  # looking at the camera's spot
    r3d.view_distance = 50.0
    for obj in bpy.context.selected_objects:
        obj.select_set(False)
    planet.select_set(True)
    bpy.context.view_layer.objects.active = planet
    yield from ui.press_key(win, region, 'NUMPAD_PERIOD', settle=0.5)
    centre = navigation.planet_centre(planet)
    yield from ui.wait_until(lambda: (Vector(r3d.view_location) - centre).length < 1000.0,
                             timeout=60, what="Frame Selected to frame the planet")
    yield from refreshed(planet)
    cover, _ = disk_of_view("frame_selected.png")
    assert 0.1 < cover < 0.9, "Frame Selected does not frame the planet"

    # ---- Go to Surface: 2 km above a point, the readout says so
    with ui.override():
        assert bpy.ops.view3d.planet_go_to_surface(longitude=7.9, latitude=46.0,
                                                   altitude=2000.0, pitch=-20.0) == {'FINISHED'}
    yield from refreshed(planet)
    eye = navigation.eye_of(r3d)
    height = navigation.altitude(planet, eye)
    local = eye - centre
    lat = math.degrees(math.asin(local.z / local.length))
    lon = math.degrees(math.atan2(local.y, local.x))
    print(f"Go to Surface: {height:.1f} m above the ground at {lat:.4f} N {lon:.4f} E",
          flush=True)
    assert abs(height - 2000.0) < 20.0, height
    assert abs(lat - 46.0) < 0.01 and abs(lon - 7.9) < 0.01, (lat, lon)
    with ui.override():
        text = view_follow.readout(bpy.context)
    print("readout:", text, flush=True)
    assert text.startswith("Altitude 2.0") and "above the ground" in text, text
    ui.screenshot("go_to_surface.png", region='AREA')


ui.run(test)
