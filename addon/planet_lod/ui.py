"""The "Planet" tab of the 3D viewport sidebar."""
import bpy

from . import core, live


def _planet(context):
    obj = context.object
    if obj is not None and obj.type == 'MESH' and obj.planet_lod.enabled:
        return obj
    return None


class PLOD_PT_base:
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Planet"


class PLOD_PT_planet(PLOD_PT_base, bpy.types.Panel):
    bl_label = "Planet LOD"

    def draw(self, context):
        layout = self.layout
        if core.load_native() is None:
            box = layout.box()
            box.alert = True
            box.label(text="Native module missing", icon='ERROR')
            for chunk in (core.native_error[i:i + 48] for i in range(0, len(core.native_error), 48)):
                box.label(text=chunk)
            return
        obj = _planet(context)
        if obj is None:
            layout.operator("mesh.planet_add", icon='WORLD')
            return
        s = obj.planet_lod
        row = layout.row(align=True)
        row.menu("PLOD_MT_planet_presets", text=bpy.types.PLOD_MT_planet_presets.bl_label)
        row.operator("object.planet_preset_add", text="", icon='ADD')
        row.operator("object.planet_preset_add", text="", icon='REMOVE').remove_active = True
        row = layout.row(align=True)
        row.menu("PLOD_MT_quality_presets", text=bpy.types.PLOD_MT_quality_presets.bl_label)
        row.operator("object.planet_quality_preset_add", text="", icon='ADD')
        row.operator("object.planet_quality_preset_add", text="",
                     icon='REMOVE').remove_active = True
        row = layout.row(align=True)
        for key in ("DRAFT", "PREVIEW", "FINAL"):
            row.operator("object.planet_apply_preset", text=key.title()).quality = key
        col = layout.column()
        col.prop(s, "projection")
        col.prop(s, "radius")
        row = col.row(align=True)
        row.prop(s, "heightmap")
        row.operator("object.planet_set_heightmap", text="", icon='FILEBROWSER')
        col.prop(s, "height_scale")
        row = col.row(align=True)
        row.prop(s, "height_offset")
        row.prop(s, "height_signed", text="Signed")
        col.prop(s, "color_map")
        row = col.row(align=True)
        row.prop(s, "use_sea_level", text="")
        sub = row.row(align=True)
        sub.active = s.use_sea_level
        sub.prop(s, "sea_level")
        sub = col.row(align=True)
        sub.active = s.use_sea_level
        sub.prop(s, "ocean_sphere")
        sub.prop(s, "skip_sea")
        row = col.row(align=True)
        row.prop(s, "atmosphere")
        sub = row.row(align=True)
        sub.active = s.atmosphere != 'NONE'
        sub.prop(s, "atmosphere_density", text="Density")
        st = live.RUNTIME.get(obj.name_full)
        if st is not None and st.error:
            box = layout.box()
            box.alert = True
            box.label(text=st.error[:120], icon='ERROR')


class PLOD_PT_detail(PLOD_PT_base, bpy.types.Panel):
    bl_label = "Detail"
    bl_parent_id = "PLOD_PT_planet"

    @classmethod
    def poll(cls, context):
        return _planet(context) is not None and core.native is not None

    def draw_header(self, context):
        self.layout.prop(context.object.planet_lod, "use_detail", text="")

    def draw(self, context):
        s = context.object.planet_lod
        col = self.layout.column()
        col.active = s.use_detail
        col.prop(s, "detail_style")
        col.prop(s, "detail_amplitude")
        col.prop(s, "detail_roughness")
        col.prop(s, "detail_smallest")
        col.prop(s, "detail_craters")
        col.prop(s, "detail_plains")
        col.prop(s, "detail_seed")


class PLOD_PT_lod(PLOD_PT_base, bpy.types.Panel):
    bl_label = "Level of Detail"
    bl_parent_id = "PLOD_PT_planet"

    @classmethod
    def poll(cls, context):
        return _planet(context) is not None and core.native is not None

    def draw(self, context):
        s = context.object.planet_lod
        col = self.layout.column()
        col.prop(s, "criterion")
        if s.criterion == 'PIXEL':
            col.prop(s, "max_pixel_error")
        else:
            col.prop(s, "split_border")
            col.prop(s, "merge_border")
        col.prop(s, "template_density")
        col.prop(s, "budget")
        col.prop(s, "max_level")
        row = col.row(align=True)
        row.prop(s, "backface", toggle=True)
        row.prop(s, "frustum", toggle=True)
        col.prop(s, "lod_camera")
        if s.lod_camera == 'CAMERA':
            col.prop(s, "camera")
        row = col.row(align=True)
        row.prop(s, "freeze_lod", toggle=True, icon='FREEZE')
        row.prop(s, "show_levels", toggle=True)
        row.prop(s, "morph", toggle=True)
        row = col.row(align=True)
        row.prop(s, "live_update", toggle=True)
        row.prop(s, "gpu_preview", toggle=True)
        col.prop(s, "clip_from_horizon")
        row = col.row(align=True)
        row.operator("object.planet_refresh", icon='FILE_REFRESH')
        row.operator("object.planet_apply_mesh", icon='MESH_DATA')
        col.operator("render.planet_flyby", icon='RENDER_ANIMATION')


class PLOD_PT_stats(PLOD_PT_base, bpy.types.Panel):
    bl_label = "Statistics"
    bl_parent_id = "PLOD_PT_planet"

    @classmethod
    def poll(cls, context):
        return _planet(context) is not None and core.native is not None

    def draw(self, context):
        st = live.RUNTIME.get(context.object.name_full)
        col = self.layout.column(align=True)
        if st is None or not st.stats:
            col.label(text="Not refined yet")
            return
        s = st.stats
        for label, key in (("Sectors", "sectors_total"), ("After backface", "sectors_after_backface"),
                           ("After frustum", "sectors_after_frustum"),
                           ("After budget", "sectors_after_budget"), ("Triangles", "triangles"),
                           ("Splits", "splits"), ("Merges", "merges"), ("Max level", "max_level")):
            row = col.row()
            row.label(text=label)
            row.label(text=str(s.get(key, "-")))
        row = col.row()
        row.label(text="Refine + cull")
        row.label(text=f"{(s.get('refine_us', 0) + s.get('cull_us', 0)) / 1000.0:.2f} ms")
        if "mesh_ms" in s:
            row = col.row()
            row.label(text="Mesh update")
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


classes = (PLOD_PT_planet, PLOD_PT_detail, PLOD_PT_lod, PLOD_PT_stats, PLOD_PT_geo)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
