"""Planet LOD: whole planets with view-dependent level of detail.

Modules, in import order (each imports only those before it; tests/test_layout.py
checks it):
  compat, core, nodes          Blender version differences; the bpy-free
                               `planetlod` package and the domain error;
                               node-tree arithmetic
  state                        per-planet runtime state and the anchor
  atmosphere, materials,       scene helpers: sky and materials, camera placement,
  placement, framing           framing a new planet
  live                         refreshing planets: LOD cameras, refinement, mesh,
                               timers and handlers
  navigation                   finding the planet with Blender's views: framing,
                               Go to Surface, altitude, pivot on the ground
  legend                       the legend of Show Levels
  draw, props, operators,      the GPU preview, settings, operators, flyby
  render, flyby_job, ui        rendering, the flyby as an interface job, panels
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
    for _name in ("compat", "core", "nodes", "runtime", "atmosphere", "materials", "placement",
                  "framing", "live", "navigation", "legend", "draw", "props", "operators", "render",
                  "flyby_job", "ui"):
        if _name in locals():
            importlib.reload(locals()[_name])

import bpy  # noqa: E402
from bpy.props import PointerProperty  # noqa: E402

from . import (compat, core, nodes, runtime, atmosphere, materials, placement,  # noqa: E402
               framing, live, navigation, legend, draw, props, operators, render, flyby_job,
               ui)

classes = (
    props.PLOD_PG_inset,
    props.PLOD_PG_settings,
    props.PLOD_PG_geo,
    operators.PLOD_OT_planet_add,
    operators.PLOD_OT_planet_refresh,
    operators.PLOD_OT_write_tiles,
    operators.PLOD_OT_planet_apply_mesh,
    operators.PLOD_OT_planet_apply_preset,
    operators.PLOD_OT_set_heightmap,
    operators.PLOD_OT_inset_add,
    operators.PLOD_OT_inset_remove,
    operators.PLOD_MT_planet_presets,
    operators.PLOD_MT_quality_presets,
    operators.PLOD_OT_preset_add,
    operators.PLOD_OT_quality_preset_add,
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
    _register_classes()
    bpy.types.Object.planet_lod = PointerProperty(type=props.PLOD_PG_settings)
    bpy.types.Object.planet_lod_geo = PointerProperty(type=props.PLOD_PG_geo)
    bpy.types.VIEW3D_MT_mesh_add.append(operators.menu_func)
    draw.add_draw_handler()
    live.add_handlers()
    navigation.register()
    legend.register()


def unregister():
    legend.unregister()
    navigation.unregister()
    live.remove_handlers()
    draw.remove_draw_handler()
    bpy.types.VIEW3D_MT_mesh_add.remove(operators.menu_func)
    del bpy.types.Object.planet_lod_geo
    del bpy.types.Object.planet_lod
    _unregister_classes()
