"""Planet LOD: whole planets with view-dependent level of detail."""
bl_info = {
    "name": "Planet LOD",
    "author": "Planet LOD contributors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "View3D > Add > Mesh > Planet; View3D > Sidebar > Planet",
    "description": "Cube-sphere planets with HRTMR level of detail, GPU preview and flybys",
    "category": "Add Mesh",
}

if "bpy" in locals():  # script reload (F3 > Reload Scripts)
    import importlib
    for _name in ("compat", "core", "props", "materials", "live", "operators", "render",
                  "draw", "framing", "ui"):
        if _name in locals():
            importlib.reload(locals()[_name])

import bpy  # noqa: E402

from . import compat, core, props, materials, live, operators, render, draw, framing, ui  # noqa: E402,E501

_modules = (props, operators, render, ui, draw, live)


def register():
    core.load_native()
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
