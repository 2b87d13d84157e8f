"""Add-on preferences: where to look for planet maps on this machine.

Map search folders: a map that is not at its saved path is looked for by its
file name in these folders.  Path mappings: a saved path starting with
"From" is also tried with that prefix replaced by "To", for workers that
mount the artist's storage elsewhere (/mnt/projects -> //server/projects).
Render workers without saved preferences can set the same through the
environment (planetlod.mappaths: PLANET_LOD_MAP_FOLDERS, PLANET_LOD_PATH_MAP).
"""
import bpy
from bpy.props import CollectionProperty, IntProperty, StringProperty

from . import compat


class PLOD_PG_map_folder(bpy.types.PropertyGroup):
    path: StringProperty(name="Folder", subtype='DIR_PATH',
                         description="A folder searched for planet maps by file name")


class PLOD_PG_path_mapping(bpy.types.PropertyGroup):
    source: StringProperty(name="From", description="Start of a saved map path, "
                                                    "as the artist's machine sees it")
    target: StringProperty(name="To", description="What that start is on this machine")


class PLOD_AP_preferences(bpy.types.AddonPreferences):
    bl_idname = compat.PACKAGE

    map_folders: CollectionProperty(type=PLOD_PG_map_folder)
    path_mappings: CollectionProperty(type=PLOD_PG_path_mapping)
    active_folder: IntProperty()

    def draw(self, context):
        layout = self.layout
        box = layout.box()
        box.label(text="Map search folders (a missing map is looked for here by file name)")
        for index, folder in enumerate(self.map_folders):
            row = box.row(align=True)
            row.prop(folder, "path", text="")
            row.operator("preferences.planet_lod_list_remove", text="", icon='X').where = \
                f"map_folders:{index}"
        box.operator("preferences.planet_lod_list_add", icon='ADD').where = "map_folders"
        box = layout.box()
        box.label(text="Path mapping (a saved path's start, and what it is on this machine)")
        for index, mapping in enumerate(self.path_mappings):
            row = box.row(align=True)
            row.prop(mapping, "source")
            row.prop(mapping, "target")
            row.operator("preferences.planet_lod_list_remove", text="", icon='X').where = \
                f"path_mappings:{index}"
        box.operator("preferences.planet_lod_list_add", icon='ADD').where = "path_mappings"


class PLOD_OT_prefs_list_add(bpy.types.Operator):
    """Add an entry"""
    bl_idname = "preferences.planet_lod_list_add"
    bl_label = "Add"
    bl_options = {'INTERNAL'}
    where: StringProperty()

    def execute(self, context):
        getattr(preferences(context), self.where).add()
        return {'FINISHED'}


class PLOD_OT_prefs_list_remove(bpy.types.Operator):
    """Remove this entry"""
    bl_idname = "preferences.planet_lod_list_remove"
    bl_label = "Remove"
    bl_options = {'INTERNAL'}
    where: StringProperty()

    def execute(self, context):
        name, index = self.where.split(":")
        getattr(preferences(context), name).remove(int(index))
        return {'FINISHED'}


def preferences(context=None):
    """The add-on's preferences, or None (not registered, e.g. while loading)."""
    addon = (context or bpy.context).preferences.addons.get(compat.PACKAGE)
    return addon.preferences if addon is not None else None


def map_settings():
    """(path mappings, search folders) from the preferences."""
    prefs = preferences()
    if prefs is None:
        return [], []
    mappings = [(m.source, m.target) for m in prefs.path_mappings if m.source and m.target]
    folders = [bpy.path.abspath(f.path) for f in prefs.map_folders if f.path]
    return mappings, folders


classes = (PLOD_PG_map_folder, PLOD_PG_path_mapping, PLOD_AP_preferences,
           PLOD_OT_prefs_list_add, PLOD_OT_prefs_list_remove)
register, unregister = bpy.utils.register_classes_factory(classes)
