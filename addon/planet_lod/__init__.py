"""Planet LOD: whole planets with view-dependent level of detail.

Modules, in pipeline order (each imports only modules before it;
tests/test_layout.py checks it):
  compat, core, nodes          Blender version differences; the bpy-free
                               `planetlod` package and the domain error;
                               node-tree arithmetic
  prefs, mappaths              add-on preferences (map search folders, path
                               mapping); map references that travel
  runtime                      per-planet runtime state and the anchor
  atmosphere, terrain_shading, the planet's sky, its ground shading and
  materials                    materials
  cameras                      the LOD camera; clip ranges fitted to planets
  placement, framing           cameras and objects placed in planet space;
                               framing a new planet
  refresh                      refreshing planets: refinement, the mesh, the
                               GPU preview's jobs, the render refresh
  handlers                     the viewport's timer and Blender's handlers
  navigation                   finding the planet with Blender's views: framing,
                               Go to Surface
  planet_fly                   flying a view at the altitude's pace
  view_follow                  the views kept on the planet: altitude readout,
                               pivot on the ground, level horizon, floating origin
  legend                       the legend of Show Levels
  draw, sky_preview            the GPU preview; the viewport's sky
  props                        the settings
  operators, mesh_jobs,        operators on the planet; Refresh and Apply as
  map_files, preset_menus      Mesh as interface jobs; on its height files; the
                               preset menus
  render, flyby_job,           flybys, the flyby as an interface job; recording
  recordpath, ui               a camera path; the panels

For scripts (the render farm's job, tools/, bench/) the package names a
few functions that stay when the modules behind them move:
  planets(scene)               the scene's planet objects
  planet_state(obj)            a planet's runtime state (.error, .warning, .stats)
  planet_errors(scene)         "planet: reason" of each planet whose refresh failed
  anchor(obj)                  the planet-space point at the planet object's origin
  refresh_planet(obj, scene, build_mesh=False, for_render=False)
                               refines a planet (and rebuilds its mesh)
  refresh_for_render(scene)    every planet for the render camera, mesh rebuilt
  ensure_flyby_camera(scene, planet, path_frames)
                               the planet's flyby camera, made the scene camera
  render_flyby(scene, planet, first, last, out_dir, path_frames)
                               renders flyby frames, stats.csv and a contact sheet
  contact_sheet(paths, out_path)
                               a contact sheet of rendered frames
  merge_frame_stats(folder, frames=None)
                               folder/stats.csv from the per-frame stats files
                               that headless renders through a planet_lod_geo
                               camera write beside their frames
bench/ also measures the refresh's own steps through their modules.
"""
bl_info = {
    "name": "Planet LOD",
    "author": "Planet LOD contributors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "View3D > Add > Mesh > Planet; View3D > Sidebar > Planet",
    "description": "Cube-sphere planets with view-dependent level of detail, GPU preview and flybys",
    "category": "Add Mesh",
}

if "bpy" in locals():  # script reload (F3 > Reload Scripts)
    import importlib
    for _name in ("compat", "core", "prefs", "mappaths", "nodes", "runtime", "ground_proxy",
                  "atmosphere",
                  "terrain_shading", "materials", "cameras", "placement", "framing", "refresh",
                  "handlers", "navigation", "planet_fly", "view_follow", "legend", "draw", "sky_preview",
                  "props", "operators", "mesh_jobs", "map_files", "preset_menus", "render", "flyby_job", "recordpath", "ui"):
        if _name in locals():
            importlib.reload(locals()[_name])

import bpy  # noqa: E402
from bpy.props import PointerProperty  # noqa: E402

from . import (compat, core, prefs, mappaths, nodes, runtime, ground_proxy,  # noqa: E402
               atmosphere, terrain_shading, materials, cameras, placement, framing, refresh,
               handlers, navigation, planet_fly, view_follow, legend, draw, sky_preview, props, operators,
               mesh_jobs, map_files, preset_menus, render, flyby_job, recordpath, ui)

classes = (
    props.PLOD_PG_inset,
    props.PLOD_PG_settings,
    props.PLOD_PG_geo,
    operators.PLOD_OT_planet_add,
    mesh_jobs.PLOD_OT_planet_refresh,
    map_files.PLOD_OT_write_tiles,
    mesh_jobs.PLOD_OT_planet_apply_mesh,
    operators.PLOD_OT_planet_apply_preset,
    map_files.PLOD_OT_set_heightmap,
    map_files.PLOD_OT_set_color_map,
    map_files.PLOD_OT_inset_add,
    map_files.PLOD_OT_inset_remove,
    preset_menus.PLOD_MT_planet_presets,
    preset_menus.PLOD_MT_quality_presets,
    preset_menus.PLOD_OT_preset_add,
    preset_menus.PLOD_OT_quality_preset_add,
    render.PLOD_OT_flyby,
    flyby_job.PLOD_OT_flyby_job,
    ui.PLOD_UL_insets,
    ui.PLOD_PT_planet,
    ui.PLOD_PT_surface,
    ui.PLOD_PT_detail,
    ui.PLOD_PT_lod,
    ui.PLOD_PT_display,
    ui.PLOD_PT_render,
    ui.PLOD_PT_stats,
    ui.PLOD_PT_geo,
)

_register_classes, _unregister_classes = bpy.utils.register_classes_factory(classes)


def register():
    core.load_native()
    prefs.register()
    mappaths.register()
    _register_classes()
    bpy.types.Object.planet_lod = PointerProperty(type=props.PLOD_PG_settings)
    bpy.types.Object.planet_lod_geo = PointerProperty(type=props.PLOD_PG_geo)
    bpy.types.VIEW3D_MT_mesh_add.append(operators.menu_func)
    sky_preview.add_draw_handler()  # first: the planet preview draws over it
    draw.add_draw_handler()
    handlers.add_handlers()
    render.add_handlers()
    recordpath.register()
    navigation.register()
    planet_fly.register()
    view_follow.register()
    legend.register()
    ground_proxy.register()


def unregister():
    ground_proxy.unregister()
    legend.unregister()
    view_follow.unregister()
    planet_fly.unregister()
    navigation.unregister()
    recordpath.unregister()
    render.remove_handlers()
    handlers.remove_handlers()
    sky_preview.remove_draw_handler()
    draw.remove_draw_handler()
    bpy.types.VIEW3D_MT_mesh_add.remove(operators.menu_func)
    del bpy.types.Object.planet_lod_geo
    del bpy.types.Object.planet_lod
    _unregister_classes()
    mappaths.unregister()
    prefs.unregister()


# ---- for scripts (see the module's docstring) -----------------------------------

planets = runtime.planet_objects
planet_state = runtime.state
anchor = runtime.anchor
refresh_planet = refresh.refresh
refresh_for_render = refresh.refresh_for_render
ensure_flyby_camera = placement.ensure_flyby_camera
render_flyby = render.render_flyby
contact_sheet = render.contact_sheet
merge_frame_stats = render.merge_frame_stats


def planet_errors(scene):
    """'planet: reason' for each planet of `scene` whose last refresh failed."""
    return [f"{obj.name}: {runtime.state(obj).error}" for obj in runtime.planet_objects(scene)
            if runtime.state(obj).error]
