"""Planet map paths in Blender: where a saved map reference is on this machine,
and keeping references portable in saved files (planetlod.mappaths has the
rules: bundled maps by token, // relative paths, path mappings, search folders).

* resolve() turns a planet's map property into a file path; every reader of
  a map goes through it.
* Loading a file rewrites absolute paths of bundled maps (older files) into
  the token; saving writes the token for Image datablocks of bundled maps
  (the colour and height images of planet materials) and puts the real path
  back after, so no per-user path of the add-on goes into a .blend.
* Blender's path tools (Make Paths Relative/Absolute, Find Missing Files,
  packing) only visit Blender's own datablocks: File > External Data gets the
  same three for planet maps, and Save As to another folder (Blender 4.x,
  whose save handlers receive the new path) rebases `//` map paths as Blender
  rebases its own.
"""
import os

import bpy
from bpy.app.handlers import persistent
from bpy.props import BoolProperty, StringProperty

from . import core, prefs

paths = core.mappaths  # the bpy-free rules

_restore_images = {}  # image name -> filepath_raw, between save_pre and save_post


def bundled_names():
    """File names of the bundled maps (the add-on's data/ folders)."""
    names = set()
    for folder in core.resource_dirs("data"):
        if os.path.isdir(folder):
            names.update(os.listdir(folder))
    return names


def bundled(name):
    """The saved reference of bundled map `name`: its token."""
    return paths.bundled(name)


def search_settings():
    """(path mappings, search folders): the preferences', then the environment's."""
    try:
        env_mappings, env_folders = paths.env_settings()
    except ValueError as exc:
        raise core.FileError(str(exc)) from exc
    mappings, folders = prefs.map_settings()
    return mappings + env_mappings, folders + env_folders


def resolve(path):
    """The file a map property names on this machine ("" for none)."""
    if not path:
        return ""
    mappings, folders = search_settings()
    return paths.resolve(path, core.data_path, bpy.path.abspath, bundled_names(),
                         mappings, folders)


def map_properties(obj):
    """(owner, property name) of each map path a planet object holds."""
    s = obj.planet_lod
    yield s, "heightmap"
    yield s, "color_map"
    for inset in s.insets:
        yield inset, "filepath"


def planets():
    return [o for o in bpy.data.objects if o.type == 'MESH' and o.planet_lod.enabled]


def _set_quietly(owner, name, value):
    """Sets a map path without its update callback (no rebuild for a rename)."""
    owner[name] = value


def _bundled_real_paths():
    found = {}
    for folder in core.resource_dirs("data"):
        if os.path.isdir(folder):
            for name in os.listdir(folder):
                found[os.path.realpath(os.path.join(folder, name))] = name
    return found


def portable(path):
    """A resolved map path as a .blend may keep it: a bundled map's token."""
    if not path:
        return path
    name = _bundled_real_paths().get(os.path.realpath(path))
    return bundled(name) if name is not None else path


def _saved_token_name(raw):
    """The bundled map an image's saved path names: the token, also after
    Blender made it relative on save (//../../<planet_lod>/name)."""
    at = raw.find(paths.TOKEN)
    return raw[at + len(paths.TOKEN):] if at >= 0 else None


def tokenise_planets():
    """Absolute paths of bundled maps (older files, typed by hand) -> tokens."""
    names, real = bundled_names(), _bundled_real_paths()
    changed = 0
    for obj in planets():
        for owner, name in map_properties(obj):
            value = getattr(owner, name)
            if not value or paths.token_name(value):
                continue
            bundled_name = paths.legacy_bundled(value.replace("\\", "/"), names)
            if bundled_name is None:
                bundled_name = real.get(os.path.realpath(bpy.path.abspath(value)))
            if bundled_name is not None:
                _set_quietly(owner, name, bundled(bundled_name))
                changed += 1
    return changed


def relink_images():
    """Images saved with a bundled map's token (or an older file's absolute path
    of one that is not here) point at this machine's bundled map."""
    names = bundled_names()
    for image in bpy.data.images:
        if image.packed_file is not None or image.source != 'FILE':
            continue
        raw = image.filepath_raw
        name = _saved_token_name(raw)
        if name is None and not os.path.exists(bpy.path.abspath(raw)):
            name = paths.legacy_bundled(bpy.path.abspath(raw), names)
        if name is not None:
            image.filepath = core.data_path(name)


@persistent
def on_load_post(*_args):
    if tokenise_planets():
        print("planet_lod: bundled maps now referenced by the add-on's data folder")
    relink_images()


@persistent
def on_save_pre(filepath=None, *_args):
    tokenise_planets()
    if isinstance(filepath, str) and filepath and bpy.data.filepath:
        rebase_relative(os.path.dirname(bpy.data.filepath), os.path.dirname(filepath))
    real = _bundled_real_paths()
    _restore_images.clear()
    for image in bpy.data.images:
        if image.packed_file is not None or image.source != 'FILE' or not image.filepath_raw:
            continue
        name = real.get(os.path.realpath(bpy.path.abspath(image.filepath_raw)))
        if name is not None:
            _restore_images[image.name] = image.filepath_raw
            # no reload (the pixels stay); the long string first overwrites the
            # old path's bytes, which the fixed-size field would otherwise keep
            image.filepath_raw = "_" * 1000
            image.filepath_raw = bundled(name)


@persistent
def on_save_post(*_args):
    for name, raw in _restore_images.items():
        image = bpy.data.images.get(name)
        if image is not None:
            image.filepath_raw = raw
    _restore_images.clear()


def rebase_relative(old_dir, new_dir):
    """`//` map paths of a file saved from old_dir into new_dir, rebased to
    name the same files (what Blender's Save As does with Remap Relative)."""
    if os.path.normpath(old_dir) == os.path.normpath(new_dir):
        return
    for obj in planets():
        for owner, name in map_properties(obj):
            value = getattr(owner, name)
            if value.startswith("//"):
                absolute = os.path.normpath(os.path.join(old_dir, value[2:]))
                _set_quietly(owner, name, bpy.path.relpath(absolute, start=new_dir))


# ---- File > External Data ---------------------------------------------------------

def _user_maps():
    """(owner, name, value) of each map path that is not a bundled map."""
    for obj in planets():
        for owner, name in map_properties(obj):
            value = getattr(owner, name)
            if value and paths.token_name(value) is None:
                yield owner, name, value


class PLOD_OT_map_paths_relative(bpy.types.Operator):
    """Make the planets' map paths relative to the .blend (//), as Make Paths
    Relative does for Blender's own files"""
    bl_idname = "file.planet_lod_paths_relative"
    bl_label = "Make Planet Map Paths Relative"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        if not bpy.data.filepath:
            self.report({'ERROR'}, "Save the .blend first: relative paths start from its folder")
            return {'CANCELLED'}
        changed = 0
        for owner, name, value in _user_maps():
            if value.startswith("//"):
                continue
            try:
                relative = bpy.path.relpath(value)
            except ValueError:  # another drive (Windows)
                continue
            _set_quietly(owner, name, relative)
            changed += 1
        self.report({'INFO'}, f"{changed} planet map paths made relative")
        return {'FINISHED'}


class PLOD_OT_map_paths_absolute(bpy.types.Operator):
    """Make the planets' map paths absolute, as Make Paths Absolute does for
    Blender's own files"""
    bl_idname = "file.planet_lod_paths_absolute"
    bl_label = "Make Planet Map Paths Absolute"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        changed = 0
        for owner, name, value in _user_maps():
            if value.startswith("//"):
                _set_quietly(owner, name, os.path.normpath(bpy.path.abspath(value)))
                changed += 1
        self.report({'INFO'}, f"{changed} planet map paths made absolute")
        return {'FINISHED'}


def find_missing(directory, relative):
    """Missing planet maps looked for by file name under `directory`; returns
    (found, still missing)."""
    index = {}
    for root, _dirs, files in os.walk(directory):
        for filename in files:
            index.setdefault(filename, os.path.join(root, filename))
    found, missing = 0, 0
    for owner, name, value in list(_user_maps()):
        if os.path.exists(resolve(value)):
            continue
        match = index.get(os.path.basename(bpy.path.abspath(value).replace("\\", "/")))
        if match is None:
            missing += 1
            continue
        if relative and bpy.data.filepath:
            try:
                match = bpy.path.relpath(match)
            except ValueError:
                pass
        setattr(owner, name, match)  # with its update: the planet rebuilds
        found += 1
    return found, missing


class PLOD_OT_find_missing_maps(bpy.types.Operator):
    """Look for the planets' missing maps by file name in a folder and its
    subfolders, as Find Missing Files does for Blender's own files"""
    bl_idname = "file.planet_lod_find_missing"
    bl_label = "Find Missing Planet Maps"
    bl_options = {'REGISTER', 'UNDO'}

    directory: StringProperty(subtype='DIR_PATH')
    relative_path: BoolProperty(name="Relative Path", default=True,
                                description="Store the found paths relative to the .blend")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {'RUNNING_MODAL'}

    def execute(self, context):
        folder = bpy.path.abspath(self.directory)
        if not os.path.isdir(folder):
            self.report({'ERROR'}, f"not a folder: {folder}")
            return {'CANCELLED'}
        found, missing = find_missing(folder, self.relative_path)
        self.report({'WARNING'} if missing else {'INFO'},
                    f"{found} planet maps found, {missing} still missing")
        return {'FINISHED'}


def menu_external_data(self, context):
    layout = self.layout
    layout.separator()
    layout.operator(PLOD_OT_map_paths_relative.bl_idname)
    layout.operator(PLOD_OT_map_paths_absolute.bl_idname)
    layout.operator(PLOD_OT_find_missing_maps.bl_idname)


classes = (PLOD_OT_map_paths_relative, PLOD_OT_map_paths_absolute, PLOD_OT_find_missing_maps)
_register_classes, _unregister_classes = bpy.utils.register_classes_factory(classes)
HANDLERS = ((bpy.app.handlers.save_pre, on_save_pre), (bpy.app.handlers.save_post, on_save_post))


def register():
    _register_classes()
    bpy.types.TOPBAR_MT_file_external_data.append(menu_external_data)
    # before the handler that builds the planets from their maps
    if on_load_post not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.insert(0, on_load_post)
    for handler_list, fn in HANDLERS:
        if fn not in handler_list:
            handler_list.append(fn)


def unregister():
    for handler_list, fn in HANDLERS + ((bpy.app.handlers.load_post, on_load_post),):
        while fn in handler_list:
            handler_list.remove(fn)
    bpy.types.TOPBAR_MT_file_external_data.remove(menu_external_data)
    _unregister_classes()
