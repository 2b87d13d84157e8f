"""Blender's preset menus and their Add Preset operators: the bundled presets/
and the user's own, for whole planets and for quality settings."""
import os

import bpy
from bl_operators.presets import AddPresetBase

from . import core


def preset_dirs(subdir):
    dirs = [os.path.join(d, subdir) for d in core.resource_dirs("presets")]
    dirs += bpy.utils.preset_paths(subdir)
    seen, out = set(), []
    for d in dirs:
        if os.path.isdir(d) and os.path.realpath(d) not in seen:
            seen.add(os.path.realpath(d))
            out.append(d)
    return out


class PLOD_MT_planet_presets(bpy.types.Menu):
    bl_label = "Planet Presets"
    preset_subdir = "planet_lod"
    preset_operator = "script.execute_preset"

    def draw(self, context):
        self.path_menu(preset_dirs(self.preset_subdir), self.preset_operator,
                       props_default={"menu_idname": self.bl_idname},
                       filter_ext=lambda ext: ext.lower() == ".py")


class PLOD_MT_quality_presets(PLOD_MT_planet_presets):
    bl_label = "Quality Presets"
    preset_subdir = "planet_lod_quality"


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
        "detail_fine_roughness", "detail_fine_below", "detail_seed")]


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

