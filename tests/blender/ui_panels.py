"""In the real UI (xvfb): every panel of the add-on's sidebar tab draws without
error in each state -- no planet, each planet preset, a planet whose height map
path is wrong, a text file named .png, a radius too small, one with a missing
inset file, a Large Map without its tile file -- and the error is shown in
plain words in the panel (a red box); Write Tile File
writes it from the panel (a modal operator) and the planet refreshes."""
import os

import bpy
import numpy as np

import plod_testlib as lib
import plod_uilib as ui

ALL = {"PLOD_PT_planet", "PLOD_PT_surface", "PLOD_PT_detail", "PLOD_PT_lod",
       "PLOD_PT_display", "PLOD_PT_render", "PLOD_PT_stats"}


def redraw_and_check(recorder, expected, label, planet=None):
    """Generator: (once `planet` has refreshed) waits until the `expected`
    panels have drawn again."""
    if planet is not None:
        yield from ui.settled(planet)
    win, area, region, sidebar = ui.view3d()
    before = recorder.snapshot()
    area.tag_redraw()
    yield from ui.wait_until(lambda: expected <= recorder.drawn_since(before) or recorder.errors,
                             what=f"{label}: the panels' redraw")
    drawn = recorder.drawn_since(before)
    print(f"{label}: drew {sorted(drawn)}", flush=True)
    assert not recorder.errors, recorder.errors
    assert expected <= drawn, f"{label}: {sorted(expected - drawn)} not drawn"


def red_pixels(name):
    """Pixels of the sidebar that are the alert box's red."""
    _, _, _, sidebar = ui.view3d()
    image = ui.crop_region(ui.screenshot(name, region='WINDOW'), sidebar)
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    return int(np.sum((r > 0.5) & (r > g + 0.25) & (r > b + 0.25)))


def test():
    lib.enable()
    recorder = ui.PanelRecorder()
    from planet_lod import ui as panels
    panels.PLOD_PT_stats.bl_options = set()  # opened, so that its draw runs too
    bpy.utils.unregister_class(panels.PLOD_PT_stats)
    bpy.utils.register_class(panels.PLOD_PT_stats)
    yield from ui.open_sidebar_tab(recorder)
    # no planet selected: the main panel offers to add one
    bpy.ops.object.select_all(action='DESELECT')
    bpy.context.view_layer.objects.active = None
    yield from redraw_and_check(recorder, {"PLOD_PT_planet"}, "no planet")
    clean_red = red_pixels("panels_none.png")
    for preset in ("EARTH", "MOON", "MARS", "ASTEROID"):
        with ui.override():
            assert bpy.ops.mesh.planet_add(preset=preset) == {'FINISHED'}
        yield from redraw_and_check(recorder, ALL, preset, bpy.context.object)
        ui.screenshot(f"panels_{preset.lower()}.png", region='WINDOW')
    planet = bpy.context.object
    assert red_pixels("panels_ok.png") <= clean_red + 50
    # a bad path typed into the height map field: the panel says why, in red
    planet.planet_lod.heightmap = "/nonexistent/heights.png"
    yield from redraw_and_check(recorder, ALL, "bad height map", planet)
    red = red_pixels("panels_error.png")
    print(f"red pixels in the sidebar: {red} with the error, {clean_red} without", flush=True)
    assert red > clean_red + 200, "the error is not shown in the panel"
    from planet_lod import runtime
    assert "not found" in runtime.state(planet).error
    # fixed again: the error goes away
    planet.planet_lod.heightmap = ""
    yield from redraw_and_check(recorder, ALL, "height map cleared", planet)
    assert runtime.state(planet).error == "", runtime.state(planet).error
    # plain words: a text file named .png, a radius too small for the relief
    fake = os.path.join(lib.out_dir(), "notes.png")
    with open(fake, "w") as f:
        f.write("not pixels\n")
    planet.planet_lod.heightmap = fake
    yield from redraw_and_check(recorder, ALL, "a text file named .png", planet)
    error = runtime.state(planet).error
    print(f"fake .png: {error}", flush=True)
    assert "not an image file (notes.png)" in error, error
    assert red_pixels("panels_fake_png.png") > clean_red + 200, "the error is not shown"
    planet.planet_lod.heightmap = ""
    # (the Earth's relief: its lowest ground cannot reach half way to a 1 m centre)
    earth = bpy.data.objects["Earth"]
    bpy.context.view_layer.objects.active = earth
    radius = earth.planet_lod.radius
    earth.planet_lod.radius = 0.0  # clamped to the property's minimum
    yield from redraw_and_check(recorder, ALL, "radius 0", earth)
    yield from ui.settled(earth)
    error = runtime.state(earth).error
    print(f"radius 0: {error}", flush=True)
    assert "radius must be at least" in error, error
    assert red_pixels("panels_radius.png") > clean_red + 200, "the error is not shown"
    earth.planet_lod.radius = radius
    yield from redraw_and_check(recorder, ALL, "radius back", earth)
    yield from ui.settled(earth)
    assert runtime.state(earth).error == "", runtime.state(earth).error
    bpy.context.view_layer.objects.active = planet
    # an inset whose file is missing: the list draws, the panel says why
    inset = planet.planet_lod.insets.add()
    inset.use_box = True  # its box fields draw too
    inset.filepath = "/nonexistent/N45E006.hgt"
    yield from redraw_and_check(recorder, ALL, "missing inset", planet)
    assert red_pixels("panels_inset_error.png") > clean_red + 200, "inset error not shown"
    assert "inset not found" in runtime.state(planet).error, runtime.state(planet).error
    planet.planet_lod.insets.remove(0)
    planet.planet_lod.heightmap = ""  # the list's removal checks nothing by itself
    yield from redraw_and_check(recorder, ALL, "inset removed", planet)
    assert runtime.state(planet).error == "", runtime.state(planet).error
    # a Large Map whose tile file is not written: the panel says so and offers
    # to write it; written from the panel, the planet refreshes
    world = os.path.join(lib.out_dir(), "world.r16")
    np.full((256, 512), 30000, "<u2").tofile(world)
    if os.path.exists(world + ".plodtiles"):
        os.remove(world + ".plodtiles")
    planet.planet_lod.heightmap, planet.planet_lod.heightmap_tiled = world, True
    yield from redraw_and_check(recorder, ALL, "Large Map, no tile file", planet)
    assert "tile file is not written" in runtime.state(planet).error, runtime.state(planet).error
    assert red_pixels("panels_tiles_missing.png") > clean_red + 200, "tile error not shown"
    with ui.override():
        assert bpy.ops.object.planet_write_tiles('INVOKE_DEFAULT') == {'RUNNING_MODAL'}
    yield from ui.wait_until(lambda: os.path.isfile(world + ".plodtiles") and
                             runtime.state(planet).settled() and not runtime.state(planet).error,
                             what="the tile file and the planet's refresh")
    yield from redraw_and_check(recorder, ALL, "Large Map written")
    planet.planet_lod.heightmap_tiled, planet.planet_lod.heightmap = False, ""
    # the colour map shows by its file name (the full path in the tooltip), one
    # button loads another, one clears it
    from planet_lod import map_files, mappaths
    from planet_lod.core import presets
    earth_map = presets.planet_settings("EARTH", mappaths.bundled)["color_map"]
    with ui.override():
        assert bpy.ops.object.planet_set_color_map(clear=True) == {'FINISHED'}
        assert planet.planet_lod.color_map == ""
        assert bpy.ops.object.planet_set_color_map(
            filepath=mappaths.resolve(earth_map)) == {'FINISHED'}
        tooltip = map_files.PLOD_OT_set_color_map.description(bpy.context, None)
    assert tooltip.startswith(mappaths.resolve(earth_map)), tooltip
    yield from redraw_and_check(recorder, ALL, "colour map by its file name", planet)
    ui.screenshot("panels_color_map.png", region='WINDOW')
    print(f"colour map button: {bpy.path.basename(planet.planet_lod.color_map)}; "
          f"tooltip: {tooltip.splitlines()[0]}", flush=True)
    yield 0.8


ui.run(test)
