"""Operators.  Each one reports errors (self.report) and returns CANCELLED; none
lets a traceback reach the user, and none leaves a half-built object behind."""
import os
import threading

import bpy
from bl_operators.presets import AddPresetBase
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

from . import atmosphere, core, framing, live, materials, navigation
from .core import planets, presets


def _report_missing(op):
    if core.load_native() is None:
        op.report({'ERROR'}, core.native_error)
        return True
    return False


def _planet(context):
    obj = context.object
    if obj is None or obj.type != 'MESH' or not obj.planet_lod.enabled:
        return None
    return obj


def _refuses(op, trial, failure):
    """Builds the native planet for `trial` (a settings dict) before anything in
    the scene changes; when it cannot be built, reports "<failure>: <why>" and
    returns True."""
    try:
        planets.build_planet(trial)
    except core.REPORTED_ERRORS as exc:
        op.report({'ERROR'}, f"{failure}: {exc}")
        return True
    return False


class PLOD_OT_planet_add(bpy.types.Operator):
    """Add a Planet LOD planet"""
    bl_idname = "mesh.planet_add"
    bl_label = "Planet"
    bl_options = {'REGISTER', 'UNDO'}

    preset: EnumProperty(name="Planet", items=presets.PLANET_ITEMS, default="EARTH")
    quality: EnumProperty(name="Quality", items=presets.QUALITY_ITEMS, default="PREVIEW")
    heightmap: StringProperty(name="Height map", subtype='FILE_PATH',
                              description="Override the preset's height map")
    color_map: StringProperty(name="Colour map", subtype='FILE_PATH',
                              description="Override the preset's colour map")
    frame: BoolProperty(name="Frame", default=True,
                        description="Point the views at the new planet and move a camera "
                                    "that would be inside it out of it")
    add_sun: BoolProperty(name="Add Sun", default=True,
                          description="Add a sun when the scene has none and hide lights "
                                      "that would be inside the planet")

    def execute(self, context):
        if _report_missing(self):
            return {'CANCELLED'}
        values = presets.planet_settings(self.preset, core.data_path)
        values.update(presets.quality_settings(self.quality))
        if self.heightmap:
            values["heightmap"] = bpy.path.abspath(self.heightmap)
        if self.color_map:
            values["color_map"] = bpy.path.abspath(self.color_map)
        mesh = obj = None
        undo = []  # puts back what framing changed when the planet is not added
        try:
            if values["color_map"] and not os.path.isfile(values["color_map"]):
                raise core.FileError(f"colour map not found: {values['color_map']}")
            mesh = bpy.data.meshes.new(presets.PLANETS[self.preset]["label"].split(" ")[0])
            obj = bpy.data.objects.new(mesh.name, mesh)
            settings = obj.planet_lod
            settings.assign(values)
            settings.enabled = True
            settings.gpu_preview = True  # also sets the object's viewport display
            settings.preset = self.preset
            settings.quality = self.quality
            planet = planets.build_planet(settings.as_dict())  # raises on bad input
            context.collection.objects.link(obj)
            obj.location = context.scene.cursor.location
            context.view_layer.update()
            messages = self._frame(context, obj, planet, undo)
            context.view_layer.update()  # the camera's new matrix_world
            if live.lod_camera_params(obj, context.scene, for_render=True) is not None:
                live.refresh(obj, context.scene, build_mesh=True, for_render=True)
            else:
                materials.ensure(obj)
            # the planet's sky becomes the scene's world
            atmosphere.ensure_world(obj, context.scene, assign=True)
        except core.REPORTED_ERRORS as exc:
            for step in reversed(undo):
                step()
            if obj is not None:
                bpy.data.objects.remove(obj)
            if mesh is not None:
                bpy.data.meshes.remove(mesh)
            self.report({'ERROR'}, f"Planet not added: {exc}")
            return {'CANCELLED'}
        # the frame-change handlers write the planet's mesh from the render thread
        # in UI animation renders: Blender requires Lock Interface for that
        context.scene.render.use_lock_interface = True
        for other in context.selected_objects:
            other.select_set(False)
        obj.select_set(True)
        context.view_layer.objects.active = obj
        if self.frame:
            framing.frame_views(context.screen, obj, self._top(obj))
        if not bpy.app.background:  # the clip ranges and the preview at once
            try:
                live.fit_view_clips(context.scene)
                live.refresh(obj, context.scene)
            except core.REPORTED_ERRORS as exc:
                live.state(obj).error = str(exc)
        for message in messages:
            self.report({'INFO'}, message)
        return {'FINISHED'}

    @staticmethod
    def _top(obj, planet=None):
        """Radius of the ball holding the planet's highest peak, in scene units."""
        planet = planet or planets.build_planet(obj.planet_lod.as_dict())
        return ((obj.planet_lod.radius + max(planet.height_range()[1], 0.0))
                * max(obj.matrix_world.to_scale()))

    def _frame(self, context, obj, planet, undo):
        """Camera, views and a sun outside the new planet (see framing.py)."""
        top = self._top(obj, planet)
        messages = []
        if self.frame:
            message = framing.place_camera(context.scene, obj, top, undo)
            if message:
                messages.append(message)
        if self.add_sun:
            messages += framing.add_sun(context.scene, obj, top, undo)
        if self.frame:
            messages += framing.hide_inside(context.scene, obj, top, undo)
        return messages


class PLOD_OT_planet_refresh(bpy.types.Operator):
    """Refine the active planet for its LOD camera now and rebuild its mesh"""
    bl_idname = "object.planet_refresh"
    bl_label = "Refresh Planet LOD"
    bl_options = {'REGISTER'}

    build_mesh: BoolProperty(name="Build mesh", default=True)
    for_render: BoolProperty(name="Render camera", default=True,
                             description="Use the render camera at render resolution")

    @classmethod
    def poll(cls, context):
        return _planet(context) is not None

    def execute(self, context):
        if _report_missing(self):
            return {'CANCELLED'}
        obj = _planet(context)
        try:
            stats = live.refresh(obj, context.scene, build_mesh=self.build_mesh,
                                 for_render=self.for_render)
        except core.REPORTED_ERRORS as exc:
            live.state(obj).error = str(exc)
            self.report({'ERROR'}, f"{obj.name}: {exc}")
            return {'CANCELLED'}
        st = live.state(obj)
        warning = st.render_warning if self.for_render else st.warning
        if warning:
            self.report({'WARNING'}, f"{obj.name}: {warning}")
        self.report({'INFO'}, f"{obj.name}: {stats.get('visible', 0)} sectors, "
                              f"{stats.get('triangles', 0)} triangles")
        return {'FINISHED'}


class PLOD_OT_write_tiles(bpy.types.Operator):
    """Write the Large Map's tile file next to the height map (as big as the map;
    minutes for a global map).  The planet reads the map through it"""
    bl_idname = "object.planet_write_tiles"
    bl_label = "Write Tile File"
    bl_options = {'REGISTER'}

    @classmethod
    def poll(cls, context):
        obj = _planet(context)
        return obj is not None and bool(obj.planet_lod.heightmap)

    def _settings(self, context):
        obj = _planet(context)
        return obj, obj.planet_lod.as_dict()

    def _done(self, obj, written, error):
        if obj is None:  # deleted while its tile file was written
            return {'FINISHED'} if written and error is None else {'CANCELLED'}
        if error is not None:
            live.state(obj).error = str(error)
            self.report({'ERROR'}, f"{obj.name}: {error}")
            return {'CANCELLED'}
        if not written:
            self.report({'WARNING'}, f"{obj.name}: writing the tile file was cancelled")
            return {'CANCELLED'}
        live.mark_dirty(obj, geometry=True)
        self.report({'INFO'}, f"{obj.name}: tile file written")
        return {'FINISHED'}

    def execute(self, context):  # scripts and background: blocking
        if _report_missing(self):
            return {'CANCELLED'}
        obj, settings = self._settings(context)
        try:
            written = planets.write_tiles(settings)
        except core.REPORTED_ERRORS as exc:
            return self._done(obj, False, exc)
        return self._done(obj, written, None)

    def invoke(self, context, event):
        """In the UI: the writing runs on a worker thread; the status bar shows its
        progress and Esc cancels it."""
        if _report_missing(self):
            return {'CANCELLED'}
        obj, settings = self._settings(context)
        self._name = obj.name_full
        self._fraction, self._cancel, self._result = 0.0, False, None

        def progress(fraction):
            self._fraction = fraction
            return self._cancel

        def work():
            try:
                self._result = (planets.write_tiles(settings, progress), None)
            except Exception as exc:  # noqa: BLE001 -- reported by modal(), not lost
                self._result = (False, exc)
        self._thread = threading.Thread(target=work, name="planet_lod tile file")
        self._thread.start()
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        return {'RUNNING_MODAL'}

    def modal(self, context, event):
        if event.type == 'ESC':
            self._cancel = True
        if event.type != 'TIMER':
            return {'RUNNING_MODAL'}
        wm = context.window_manager
        wm.progress_update(int(100 * self._fraction))
        if context.workspace:
            context.workspace.status_text_set(
                f"Writing the tile file: {100 * self._fraction:.0f} % (Esc to cancel)")
        if self._thread.is_alive():
            return {'RUNNING_MODAL'}
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace:
            context.workspace.status_text_set(None)
        written, error = self._result or (False, None)
        return self._done(bpy.data.objects.get(self._name), written, error)


class PLOD_OT_planet_apply_mesh(bpy.types.Operator):
    """Copy the planet's current LOD geometry into a plain mesh object"""
    bl_idname = "object.planet_apply_mesh"
    bl_label = "Apply as Mesh"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return _planet(context) is not None

    def execute(self, context):
        if _report_missing(self):
            return {'CANCELLED'}
        obj = _planet(context)
        wm = context.window_manager
        wm.progress_begin(0, 2)
        try:
            live.refresh(obj, context.scene, build_mesh=True, for_render=True)
            wm.progress_update(1)
            mesh = obj.data.copy()
            mesh.name = obj.name + " LOD mesh"
            copy = bpy.data.objects.new(mesh.name, mesh)
            copy.matrix_world = obj.matrix_world
            for collection in obj.users_collection:
                collection.objects.link(copy)
        except core.REPORTED_ERRORS as exc:
            self.report({'ERROR'}, f"{obj.name}: {exc}")
            return {'CANCELLED'}
        finally:
            wm.progress_end()
        self.report({'INFO'}, f"{copy.name}: {len(mesh.polygons)} triangles")
        return {'FINISHED'}


class PLOD_OT_planet_apply_preset(bpy.types.Operator):
    """Apply a planet or quality preset to the active planet"""
    bl_idname = "object.planet_apply_preset"
    bl_label = "Apply Planet Preset"
    bl_options = {'REGISTER', 'UNDO'}

    planet: EnumProperty(name="Planet", items=[("NONE", "Keep", "Keep the planet")]
                         + presets.PLANET_ITEMS, default="NONE")
    quality: EnumProperty(name="Quality", items=[("NONE", "Keep", "Keep the quality")]
                          + presets.QUALITY_ITEMS, default="NONE")

    @classmethod
    def poll(cls, context):
        return _planet(context) is not None

    def execute(self, context):
        if _report_missing(self):
            return {'CANCELLED'}
        obj = _planet(context)
        values = {}
        if self.planet != "NONE":
            values.update(presets.planet_settings(self.planet, core.data_path))
        if self.quality != "NONE":
            values.update(presets.quality_settings(self.quality))
        trial = obj.planet_lod.as_dict()
        trial.update({k: v for k, v in values.items() if k in trial})
        if _refuses(self, trial, "Preset not applied"):
            return {'CANCELLED'}
        obj.planet_lod.assign(values)
        if self.planet != "NONE":
            navigation.planet_preset_applied(context, obj, self.planet)
        if self.quality != "NONE":
            obj.planet_lod.quality = self.quality
            obj.planet_lod[PLOD_MT_quality_presets.active_key] = \
                presets.QUALITY[self.quality]["label"]
        live.mark_dirty(obj, geometry=True, material=True)
        return {'FINISHED'}


class PLOD_OT_set_heightmap(bpy.types.Operator):
    """Load a height map into the active planet (checked before anything changes)"""
    bl_idname = "object.planet_set_heightmap"
    bl_label = "Load Height Map"
    bl_options = {'REGISTER', 'UNDO'}

    filepath: StringProperty(subtype='FILE_PATH')
    filter_image: BoolProperty(default=True, options={'HIDDEN'})

    @classmethod
    def poll(cls, context):
        return _planet(context) is not None

    @classmethod
    def description(cls, context, properties):
        obj = _planet(context)
        path = obj.planet_lod.heightmap if obj is not None else ""
        if not path:
            return "Load a height map into the active planet"
        return f"{bpy.path.abspath(path)}\nClick to load another height map"

    def invoke(self, context, event):
        obj = _planet(context)
        if obj is not None and obj.planet_lod.heightmap and not self.filepath:
            self.filepath = bpy.path.abspath(obj.planet_lod.heightmap)
        context.window_manager.fileselect_add(self)
        return {'RUNNING_MODAL'}

    def execute(self, context):
        if _report_missing(self):
            return {'CANCELLED'}
        obj = _planet(context)
        trial = obj.planet_lod.as_dict()
        trial["heightmap"] = bpy.path.abspath(self.filepath)
        if _refuses(self, trial, "Height map not loaded"):
            return {'CANCELLED'}
        obj.planet_lod.heightmap = self.filepath
        return {'FINISHED'}


class PLOD_OT_inset_add(bpy.types.Operator):
    """Add a detailed height tile (SRTM .hgt or GeoTIFF) to the active planet; it is
    placed by its file name or its tags and checked before anything changes"""
    bl_idname = "object.planet_inset_add"
    bl_label = "Add Inset"
    bl_options = {'REGISTER', 'UNDO'}

    filepath: StringProperty(subtype='FILE_PATH')
    filter_glob: StringProperty(default="*.hgt;*.tif;*.tiff;*.png;*.exr;*.raw;*.r16",
                                options={'HIDDEN'})
    use_box: BoolProperty(name="Place by Box", default=False,
                          description="Give the tile's longitude and latitude yourself (for "
                                      "images placed by neither their name nor their tags)")
    west: FloatProperty(name="West", default=0.0, min=-180.0, max=180.0)
    east: FloatProperty(name="East", default=1.0, min=-180.0, max=180.0)
    south: FloatProperty(name="South", default=0.0, min=-90.0, max=90.0)
    north: FloatProperty(name="North", default=1.0, min=-90.0, max=90.0)
    scale: FloatProperty(name="Height", default=1.0, min=0.0, max=1.0e6,
                         description="Metres for the brightest value of an 8/16-bit image")

    @classmethod
    def poll(cls, context):
        return _planet(context) is not None

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {'RUNNING_MODAL'}

    def execute(self, context):
        if _report_missing(self):
            return {'CANCELLED'}
        obj = _planet(context)
        trial = obj.planet_lod.as_dict()
        box = dict(west=self.west, south=self.south, east=self.east, north=self.north,
                   scale=self.scale)
        path = bpy.path.abspath(self.filepath)
        trial["insets"] = trial["insets"] + [dict(box, path=path) if self.use_box else path]
        if _refuses(self, trial, "Inset not added"):
            return {'CANCELLED'}
        settings = obj.planet_lod
        inset = settings.insets.add()
        if self.use_box:
            for name, value in box.items():
                setattr(inset, name, value)
            inset.use_box = True
        inset.filepath = self.filepath
        settings.inset_index = len(settings.insets) - 1
        return {'FINISHED'}


class PLOD_OT_inset_remove(bpy.types.Operator):
    """Remove the selected inset from the active planet"""
    bl_idname = "object.planet_inset_remove"
    bl_label = "Remove Inset"
    bl_options = {'REGISTER', 'UNDO'}

    index: IntProperty(name="Inset", default=-1,
                       description="Which inset to remove (-1: the selected one)")

    @classmethod
    def poll(cls, context):
        obj = _planet(context)
        return obj is not None and len(obj.planet_lod.insets) > 0

    def execute(self, context):
        settings = _planet(context).planet_lod
        index = settings.inset_index if self.index < 0 else self.index
        if not 0 <= index < len(settings.insets):
            self.report({'ERROR'}, f"No inset {index + 1}: the planet has "
                                   f"{len(settings.insets)}")
            return {'CANCELLED'}
        settings.insets.remove(index)
        settings.inset_index = max(0, min(index, len(settings.insets) - 1))
        live.mark_dirty(_planet(context), geometry=True, material=True)
        live.check_settings(_planet(context))
        return {'FINISHED'}


# ---- Blender preset menus (bundled presets/ + the user's presets) -------------------

def _preset_dirs(subdir):
    dirs = [os.path.join(d, subdir) for d in core.resource_dirs("presets")]
    dirs += bpy.utils.preset_paths(subdir)
    seen, out = set(), []
    for d in dirs:
        if os.path.isdir(d) and os.path.realpath(d) not in seen:
            seen.add(os.path.realpath(d))
            out.append(d)
    return out


class PresetMenu:
    """A menu of preset files (bundled and the user's), the active one ticked.

    Not a bpy.types.Menu itself: in Blender 3.4 a registered menu subclassing
    another registered menu leaves the parent without its Python class (it
    opens empty), so each menu derives from this mixin and Menu separately."""
    preset_subdir = ""
    preset_operator = "script.execute_preset"
    default_label = ""

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
        for folder in _preset_dirs(self.preset_subdir):
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
        "detail_plains", "detail_seed")]


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


def menu_func(self, context):
    self.layout.operator(PLOD_OT_planet_add.bl_idname, text="Planet", icon='WORLD')
