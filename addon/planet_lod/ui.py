"""The "Planet" tab of the 3D viewport's sidebar, grouped the way a planet is
made: the planet itself, its surface, its level of detail, how the viewport
shows it, and how it renders; problems are shown at the top."""
import bpy

from . import core, draw, runtime
from .core import planets
from .preset_menus import PLOD_MT_planet_presets, PLOD_MT_quality_presets


def _planet(context):
    obj = context.object
    if obj is not None and obj.type == 'MESH' and obj.planet_lod.enabled:
        return obj
    return None


def _line_width(context):
    """Characters of interface text that fit on a line of the sidebar beside an
    icon (a character is ~7 px at resolution scale 1), so messages wrap instead
    of being cut with an ellipsis."""
    region = getattr(context, "region", None)
    if region is None or region.width <= 0:
        return 40
    scale = context.preferences.system.ui_scale or 1.0
    return max(16, int(region.width / (7.0 * scale)) - 6)


def _wrapped(layout, text, icon, width=40):
    """A message over several lines (the sidebar is narrow), first line with `icon`."""
    words, line, lines = text.split(), "", []
    for word in words:
        if line and len(line) + 1 + len(word) > width:
            lines.append(line)
            line = word
        else:
            line = f"{line} {word}" if line else word
    if line:
        lines.append(line)
    col = layout.column(align=True)
    for i, part in enumerate(lines[:8]):
        col.label(text=part, icon=icon if i == 0 else 'BLANK1')


def problems(obj):
    """(errors, warnings) the panel shows for a planet: what failed and what looks wrong."""
    errors, warnings = [], []
    st = runtime.existing_state(obj)
    if st is not None:
        if st.error:
            errors.append(st.error)
        if st.warning:
            warnings.append(st.warning)
        if st.render_warning:
            warnings.append(st.render_warning)
    if obj.planet_lod.gpu_preview and draw.shader_error():
        errors.append(draw.shader_error())
    return errors, warnings


class PLOD_UL_insets(bpy.types.UIList):
    """The planet's regional insets: one detailed height tile per row."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname,
                  index=0):
        layout.prop(item, "filepath", text="", emboss=False, icon='IMAGE_DATA')


class PLOD_PT_base:
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Planet"


class PLOD_PT_planet_sub(PLOD_PT_base):
    bl_parent_id = "PLOD_PT_planet"

    @classmethod
    def poll(cls, context):
        return _planet(context) is not None and core.native is not None


class PLOD_PT_planet(PLOD_PT_base, bpy.types.Panel):
    bl_label = "Planet LOD"

    def draw(self, context):
        layout = self.layout
        if core.load_native() is None:
            box = layout.box()
            box.alert = True
            _wrapped(box, "The add-on's native module did not load: " + core.native_error,
                     'ERROR', _line_width(context))
            return
        obj = _planet(context)
        if obj is None:
            layout.operator("mesh.planet_add", text="Add Planet", icon='WORLD')
            layout.label(text="or select a planet", icon='INFO')
            return
        s = obj.planet_lod
        errors, warnings = problems(obj)
        for message in errors:
            box = layout.box()
            box.alert = True
            _wrapped(box, message[0].upper() + message[1:], 'ERROR', _line_width(context))
        for message in warnings:
            _wrapped(layout.box(), message[0].upper() + message[1:], 'INFO',
                     _line_width(context))
        row = layout.row(align=True)
        row.menu("PLOD_MT_planet_presets", text=PLOD_MT_planet_presets.button_text(context))
        row.operator("object.planet_preset_add", text="", icon='ADD')
        row.operator("object.planet_preset_add", text="", icon='REMOVE').remove_active = True
        layout.use_property_split = True
        layout.use_property_decorate = False
        col = layout.column()
        col.prop(s, "radius")
        col.prop(s, "projection")


class PLOD_PT_surface(PLOD_PT_planet_sub, bpy.types.Panel):
    bl_label = "Surface"

    def draw(self, context):
        s = context.object.planet_lod
        layout = self.layout
        col = layout.column()
        col.label(text="Height Map")
        # one button: the map's file name (the full path in its tooltip) opens the browser
        col.operator("object.planet_set_heightmap",
                     text=bpy.path.basename(s.heightmap) or "Choose a height map",
                     icon='FILEBROWSER')
        row = col.row()
        row.active = bool(s.heightmap)
        row.prop(s, "heightmap_tiled")
        if s.heightmap_tiled and s.heightmap and core.native is not None and \
                not planets.tiles_written(s.as_dict()):
            col.operator("object.planet_write_tiles", icon='FILE_REFRESH')
        col.label(text="Insets")
        row = col.row()
        row.template_list("PLOD_UL_insets", "", s, "insets", s, "inset_index", rows=2)
        side = row.column(align=True)
        side.operator("object.planet_inset_add", text="", icon='ADD')
        side.operator("object.planet_inset_remove", text="", icon='REMOVE')
        if 0 <= s.inset_index < len(s.insets):
            inset = s.insets[s.inset_index]
            sub = col.column()
            sub.use_property_split = True
            sub.prop(inset, "use_box")
            if inset.use_box:
                box = sub.column(align=True)
                box.prop(inset, "west")
                box.prop(inset, "east")
                box.prop(inset, "south")
                box.prop(inset, "north")
                sub.prop(inset, "scale")
            sub.prop(s, "inset_feather", text="Blend")
        col.label(text="Colour Map")
        row = col.row(align=True)  # the file name; the full path in the tooltip
        row.operator("object.planet_set_color_map", icon='FILEBROWSER',
                     text=bpy.path.basename(s.color_map) or "Colours by height")
        if s.color_map:
            row.operator("object.planet_set_color_map", text="", icon='X').clear = True
        layout.use_property_split = True
        layout.use_property_decorate = False
        col = layout.column()
        col.prop(s, "height_scale", text="Height")
        col.prop(s, "height_offset", text="Offset")
        col.prop(s, "height_signed", text="Signed")
        col.prop(s, "use_sea_level", text="Sea")
        sub = col.column()
        sub.active = s.use_sea_level
        sub.prop(s, "sea_level", text="Level")
        sub.prop(s, "ocean_sphere", text="Water Sphere")
        sub.prop(s, "skip_sea", text="Hide Floor")
        col = layout.column()
        col.prop(s, "atmosphere", text="Sky")
        sub = col.column()
        sub.active = s.atmosphere != 'NONE'
        sub.prop(s, "atmosphere_density", text="Sky Density")


class PLOD_PT_detail(PLOD_PT_planet_sub, bpy.types.Panel):
    bl_label = "Detail"

    def draw_header(self, context):
        self.layout.prop(context.object.planet_lod, "use_detail", text="")

    def draw(self, context):
        s = context.object.planet_lod
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        col = layout.column()
        col.active = s.use_detail
        col.prop(s, "detail_style")
        col.prop(s, "detail_amplitude")
        col.prop(s, "detail_roughness")
        col.prop(s, "detail_fine_roughness")
        col.prop(s, "detail_fine_below")
        col.prop(s, "detail_smallest", text="Smallest")
        col.prop(s, "detail_craters")
        col.prop(s, "detail_plains")
        col.prop(s, "detail_hills")
        col.prop(s, "detail_relief")
        col.prop(s, "detail_highlands")
        col.prop(s, "detail_hills_fine")
        col.prop(s, "detail_hills_fine_below")
        col.prop(s, "detail_hills_fine_to")
        col.prop(s, "detail_seed")


class PLOD_PT_lod(PLOD_PT_planet_sub, bpy.types.Panel):
    bl_label = "Level of Detail"

    def draw(self, context):
        s = context.object.planet_lod
        layout = self.layout
        row = layout.row(align=True)
        row.menu("PLOD_MT_quality_presets", text=PLOD_MT_quality_presets.button_text(context))
        row.operator("object.planet_quality_preset_add", text="", icon='ADD')
        row.operator("object.planet_quality_preset_add", text="",
                     icon='REMOVE').remove_active = True
        row = layout.row(align=True)
        for key in ("DRAFT", "PREVIEW", "FINAL"):
            row.operator("object.planet_apply_preset", text=key.title(),
                         depress=s.quality == key).quality = key
        layout.use_property_split = True
        layout.use_property_decorate = False
        col = layout.column()
        col.prop(s, "lod_method")
        if s.lod_method == 'CHUNKED':
            col.prop(s, "chunk_cracks")
        elif s.lod_method == 'GEOMIPMAP':
            col.prop(s, "geomipmap_tiles")
        col.prop(s, "criterion")
        if s.criterion == 'PIXEL':
            col.prop(s, "max_pixel_error", text="Error")
        else:
            col.prop(s, "split_border", text="Split")
            col.prop(s, "merge_border", text="Merge")
        col.prop(s, "template_density", text="Patch Density")
        col.prop(s, "budget", text="Budget")
        col.prop(s, "max_level", text="Depth")
        if s.max_level == 0:
            col.label(text=f"Automatic: {planets.max_level(s.as_dict())} levels")
        col = layout.column(heading="Skip")
        col.prop(s, "backface", text="Far Side")
        col.prop(s, "frustum", text="Off-Screen")
        col = layout.column()
        col.prop(s, "lod_camera", text="Detail For")
        if s.lod_camera == 'CAMERA':
            col.prop(s, "camera")


class PLOD_PT_display(PLOD_PT_planet_sub, bpy.types.Panel):
    bl_label = "Display"

    def draw(self, context):
        s = context.object.planet_lod
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        col = layout.column(heading="Viewport")
        col.prop(s, "gpu_preview")
        col.prop(s, "live_update")
        col.prop(s, "view_clip_from_horizon", text="Horizon Clip")
        col = layout.column(heading="Inspect")
        col.prop(s, "show_levels")
        col.prop(s, "freeze_lod", text="Freeze")
        col.prop(s, "morph")


class PLOD_PT_render(PLOD_PT_planet_sub, bpy.types.Panel):
    bl_label = "Render"

    def draw(self, context):
        s = context.object.planet_lod
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(s, "clip_from_horizon", text="Horizon Clip")
        col = layout.column(align=True)
        col.use_property_split = False
        col.operator("object.planet_refresh", text="Update Render Mesh", icon='FILE_REFRESH')
        col.operator("object.planet_apply_mesh", icon='MESH_DATA')
        col.operator("render.planet_flyby_job", text="Render Flyby...", icon='RENDER_ANIMATION')


class PLOD_PT_stats(PLOD_PT_planet_sub, bpy.types.Panel):
    bl_label = "Statistics"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        st = runtime.existing_state(context.object)
        col = self.layout.column(align=True)
        if st is None or not st.stats:
            col.label(text="Not refined yet")
            return
        s = st.stats
        for label, key in (("Patches", "sectors_total"), ("Near Side", "sectors_after_backface"),
                           ("On Screen", "sectors_after_frustum"),
                           ("Drawn", "sectors_after_budget"), ("Triangles", "triangles"),
                           ("Splits", "splits"), ("Merges", "merges"), ("Depth", "max_level")):
            row = col.row()
            row.label(text=label)
            row.label(text=str(s.get(key, "-")))
        row = col.row()
        row.label(text="Update")
        row.label(text=f"{(s.get('refine_us', 0) + s.get('cull_us', 0)) / 1000.0:.2f} ms")
        if "mesh_ms" in s:
            row = col.row()
            row.label(text="Mesh")
            row.label(text=f"{s['mesh_ms']:.1f} ms")


class PLOD_PT_geo(bpy.types.Panel):
    """Properties editor > Object > Planet Placement: an object by longitude/latitude."""
    bl_label = "Planet Placement"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "object"
    bl_options = {'DEFAULT_CLOSED'}

    @classmethod
    def poll(cls, context):
        return context.object is not None and not context.object.planet_lod.enabled

    def draw_header(self, context):
        self.layout.prop(context.object.planet_lod_geo, "enabled", text="")

    def draw(self, context):
        geo = context.object.planet_lod_geo
        layout = self.layout
        layout.use_property_split = True
        layout.active = geo.enabled
        layout.prop(geo, "planet")
        col = layout.column(align=True)
        col.prop(geo, "longitude")
        col.prop(geo, "latitude")
        col = layout.column(align=True)
        col.prop(geo, "east")
        col.prop(geo, "north")
        col = layout.column(align=True)
        col.prop(geo, "altitude")
        col.prop(geo, "altitude_reference")
        col = layout.column(align=True)
        col.prop(geo, "heading")
        col.prop(geo, "pitch")
        col.prop(geo, "roll")
        layout.prop(geo, "floating_origin")
