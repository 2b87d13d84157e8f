"""Blender's preset menus and their Add Preset operators: the bundled presets/
and the user's own, for whole planets and for quality settings."""
import os

import bpy
from bl_operators.presets import AddPresetBase

from . import core
from .core import presets


def preset_dirs(subdir):
    dirs = [os.path.join(d, subdir) for d in core.resource_dirs("presets")]
    dirs += bpy.utils.preset_paths(subdir)
    seen, out = set(), []
    for d in dirs:
        if os.path.isdir(d) and os.path.realpath(d) not in seen:
            seen.add(os.path.realpath(d))
            out.append(d)
    return out


def _planet(context):
    obj = context.object
    if obj is None or obj.type != 'MESH' or not obj.planet_lod.enabled:
        return None
    return obj


class PresetMenu:
    """A menu of preset files (bundled and the user's), the active one ticked.

    Not a bpy.types.Menu itself: in Blender 3.4 a registered menu subclassing
    another registered menu leaves the parent without its Python class (it
    opens empty), so each menu derives from this mixin and Menu separately."""
    preset_subdir = ""
    preset_operator = "script.execute_preset"
    default_label = ""
    active_key = ""

    @staticmethod
    def preset_name(settings):
        return ""

    @classmethod
    def active_name(cls, context):
        """Display name of the preset last applied to the active planet ("" when none)."""
        obj = _planet(context)
        if obj is None:
            return ""
        return obj.planet_lod.get(cls.active_key, "") or cls.preset_name(obj.planet_lod)

    @classmethod
    def post_cb(cls, context):
        """After script.execute_preset: remembers the preset on the planet (the
        operator has just set the menu's bl_label to the file's display name)."""
        obj = _planet(context)
        if obj is not None:
            obj.planet_lod[cls.active_key] = cls.bl_label

    @classmethod
    def button_text(cls, context):
        return cls.active_name(context) or cls.default_label

    def draw(self, context):
        layout = self.layout
        active = self.active_name(context)
        files = []
        for folder in preset_dirs(self.preset_subdir):
            for name in sorted(os.listdir(folder)):
                if name.lower().endswith(".py") and not name.startswith((".", "_")):
                    files.append(os.path.join(folder, name))
        if not files:
            layout.label(text="No presets")
            return
        shown = set()
        for path in files:
            name = bpy.path.display_name(os.path.basename(path), title_case=False)
            if name in shown:  # a user's preset of the same name overrides the bundled one
                continue
            shown.add(name)
            props = layout.operator(self.preset_operator, text=name,
                                    icon='CHECKMARK' if name == active else 'BLANK1')
            props.filepath = path
            props.menu_idname = self.bl_idname


class PLOD_MT_planet_presets(PresetMenu, bpy.types.Menu):
    bl_label = "Planet Presets"
    preset_subdir = "planet_lod"
    default_label = "Planet Presets"
    active_key = "active_planet_preset"

    @staticmethod
    def preset_name(settings):
        """The bundled preset file of the planet's preset ("Mars-like (procedural)": Mars-like)."""
        return presets.PLANETS.get(settings.preset, {}).get("label", "").split(" (")[0]


class PLOD_MT_quality_presets(PresetMenu, bpy.types.Menu):
    bl_label = "Quality Presets"
    preset_subdir = "planet_lod_quality"
    default_label = "Quality Presets"
    active_key = "active_quality_preset"

    @staticmethod
    def preset_name(settings):
        return presets.QUALITY.get(settings.quality, {}).get("label", "")


class PLOD_OT_preset_add(AddPresetBase, bpy.types.Operator):
    """Add or remove a Planet LOD settings preset"""
    bl_idname = "object.planet_preset_add"
    bl_label = "Add Planet Preset"
    preset_menu = "PLOD_MT_planet_presets"
    preset_subdir = "planet_lod"
    preset_defines = ["settings = bpy.context.object.planet_lod"]
    preset_values = ["settings." + name for name in (
        "projection", "radius", "heightmap", "heightmap_tiled", "height_scale", "height_offset", "height_signed",
        "use_sea_level", "sea_level",
        "ocean_sphere", "color_map", "criterion", "max_pixel_error", "split_border",
        "merge_border", "template_density", "budget", "max_level", "backface", "frustum",
        "morph", "atmosphere", "atmosphere_density", "use_detail", "detail_style",
        "detail_amplitude", "detail_roughness", "detail_smallest", "detail_craters",
        "detail_plains", "detail_relief", "detail_hills", "detail_highlands",
        "detail_fine_roughness", "detail_fine_below", "detail_hills_fine",
        "detail_hills_fine_below", "detail_hills_fine_to", "detail_seed")]


class PLOD_OT_quality_preset_add(AddPresetBase, bpy.types.Operator):
    """Add or remove a Planet LOD quality preset"""
    bl_idname = "object.planet_quality_preset_add"
    bl_label = "Add Quality Preset"
    preset_menu = "PLOD_MT_quality_presets"
    preset_subdir = "planet_lod_quality"
    preset_defines = ["settings = bpy.context.object.planet_lod"]
    preset_values = ["settings." + name for name in (
        "criterion", "max_pixel_error", "split_border", "merge_border", "template_density",
        "budget", "max_level", "backface", "frustum", "morph")]

