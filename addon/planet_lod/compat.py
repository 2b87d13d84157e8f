"""Every difference between the supported Blenders, in one place.

Supported: Blender 3.4 (Debian 12's, Python 3.11) as a legacy add-on, and
Blender 4.2 LTS, 4.5 LTS, 5.0, 5.1, 5.2 LTS and 5.3 as an extension or a
legacy add-on.  The rest
of the add-on calls these helpers instead of testing `bpy.app.version`, and
names that changed between versions are looked up here:

* `set_principled_specular(bsdf, value)`: the Principled BSDF input
  "Specular" became "Specular IOR Level" in 4.0.
* `UNIFORM_COLOR_SHADER`: the built-in shader "3D_UNIFORM_COLOR" is
  "UNIFORM_COLOR" from 3.5 (the old name is an error from 4.0).
* `set_triangle_topology(mesh, triangles)`: polygons' `loop_total` is
  read-only from 3.6 (sizes follow from `loop_start`); 3.4 needs both.
* `calc_loop_normals(mesh)`: loops' `normal` needs calc_normals_split()
  before 4.1 and is always valid (the method is gone) from 4.1.
* `action_fcurves(id_data)`: actions are layered from 4.4 (F-curves in a
  channel bag per slot); `Action.fcurves` is gone in 5.0.
* `eevee_engine()`: the render engine id of EEVEE ("BLENDER_EEVEE_NEXT" in
  4.2 .. 4.5, "BLENDER_EEVEE" before and from 5.0).
* `update_after_load()`: in a load_post handler objects' `matrix_world` is
  zero in 4.2+ until the view layer is evaluated (3.4 reads it from the file).
* `use_node_tree(id_data)`, `has_node_tree(id_data)`: materials and worlds
  switch their shader nodes on with `use_nodes` up to 4.5; from 5.0 every
  material and world has its node tree and `use_nodes` is deprecated (gone
  in 6.0).
* `user_cache_dir(subdir)`: files the add-on may rebuild at any time go to
  the extension's user folder (`bpy.utils.extension_path_user`, 4.2+) or, for
  the legacy add-on, to Blender's user config folder.

Add a new version difference here (with the versions it concerns), not as a
version check where it is used.
"""
import os

import bpy

VERSION = bpy.app.version

# The add-on's Python package: "planet_lod" when installed as a legacy
# add-on, "bl_ext.<repository>.planet_lod" when installed as an extension.
PACKAGE = __package__ or "planet_lod"
IS_EXTENSION = PACKAGE.startswith("bl_ext.")

UNIFORM_COLOR_SHADER = "UNIFORM_COLOR" if VERSION >= (3, 5, 0) else "3D_UNIFORM_COLOR"

PRINCIPLED_SPECULAR = "Specular IOR Level" if VERSION >= (4, 0, 0) else "Specular"

_LOOP_TOTAL_WRITABLE = VERSION < (3, 6, 0)

_USE_NODES_SWITCH = VERSION < (5, 0, 0)


def set_principled_specular(bsdf, value):
    """Sets the specular amount of a Principled BSDF node (0.5 = the default
    dielectric reflectance in every version)."""
    bsdf.inputs[PRINCIPLED_SPECULAR].default_value = value


def set_triangle_topology(mesh, triangles, triangle_count):
    """Fills an empty mesh's loops and polygons with `triangle_count` triangles
    (`triangles`: a flat int32 buffer of vertex indices, 3 per triangle).
    The vertices must have been added already; the caller sets the rest."""
    from array import array
    mesh.loops.add(3 * triangle_count)
    mesh.polygons.add(triangle_count)
    mesh.loops.foreach_set("vertex_index", triangles)
    mesh.polygons.foreach_set("loop_start", array("i", range(0, 3 * triangle_count, 3)))
    if _LOOP_TOTAL_WRITABLE:
        mesh.polygons.foreach_set("loop_total", array("i", [3]) * triangle_count)


def use_node_tree(id_data):
    """Makes the material or world `id_data` render with its shader node tree
    and returns the tree."""
    if _USE_NODES_SWITCH:
        id_data.use_nodes = True
    return id_data.node_tree


def has_node_tree(id_data):
    """Whether the material or world `id_data` renders with a shader node tree."""
    if _USE_NODES_SWITCH:
        return id_data.use_nodes
    return id_data.node_tree is not None


def calc_loop_normals(mesh):
    """Makes `mesh.loops[i].normal` hold the (custom) corner normals."""
    if VERSION < (4, 1, 0):
        mesh.calc_normals_split()


def action_fcurves(id_data):
    """The F-curves of the action animating `id_data` (an ID), [] without one."""
    anim = id_data.animation_data
    if anim is None or anim.action is None:
        return []
    if VERSION < (4, 4, 0):
        return list(anim.action.fcurves)
    from bpy_extras import anim_utils
    channelbag = anim_utils.action_get_channelbag_for_slot(anim.action, anim.action_slot)
    return list(channelbag.fcurves) if channelbag is not None else []


def eevee_engine():
    """The `scene.render.engine` id of EEVEE in this Blender."""
    return "BLENDER_EEVEE_NEXT" if (4, 2, 0) <= VERSION < (5, 0, 0) else "BLENDER_EEVEE"


def render_engine(name):
    """Maps a version-independent engine name ("CYCLES", "BLENDER_EEVEE",
    "BLENDER_WORKBENCH") to this Blender's id."""
    return eevee_engine() if name in ("BLENDER_EEVEE", "BLENDER_EEVEE_NEXT") else name


def update_after_load():
    """Call first in a load_post handler that reads object matrices: evaluates
    the view layer so `matrix_world` is valid (a cheap no-op in 3.4)."""
    view_layer = bpy.context.view_layer
    if view_layer is not None:
        view_layer.update()


def user_cache_dir(subdir=""):
    """A folder the add-on owns for files it can rebuild (created on demand):
    <extension user folder>/cache[/subdir] for an extension (Blender keeps it
    across updates of the extension), else <user config>/planet_lod/cache."""
    path = None
    if IS_EXTENSION and hasattr(bpy.utils, "extension_path_user"):
        path = bpy.utils.extension_path_user(PACKAGE, path="cache", create=True)
    if not path:
        path = bpy.utils.user_resource('CONFIG', path=os.path.join("planet_lod", "cache"),
                                       create=True)
    if subdir:
        path = os.path.join(path, subdir)
    os.makedirs(path, exist_ok=True)
    return path
