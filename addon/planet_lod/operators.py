"""The planet's operators: add a planet, apply a preset.  Each one reports
errors (self.report) and returns CANCELLED; none lets a traceback reach the
user, and none leaves a half-built object behind.  (Refresh and Apply as Mesh: mesh_jobs.py; height map and inset
files: map_files.py; preset menus: preset_menus.py.)"""
import os

import bpy
from bpy.props import BoolProperty, EnumProperty, StringProperty

from . import atmosphere, cameras, core, framing, mappaths, materials, navigation, refresh, runtime
from .core import planets, presets


def report_missing(op):
    if core.load_native() is None:
        op.report({'ERROR'}, core.native_error)
        return True
    return False


def active_planet(context):
    obj = context.object
    if obj is None or obj.type != 'MESH' or not obj.planet_lod.enabled:
        return None
    return obj


def refuses(op, trial, failure):
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

    # shown in the status bar while the planet's first mesh is built (seconds)
    BUILDING = "Building planet…"
    _wait_ticks = 3  # timer ticks before the build: the status bar drawn first

    def invoke(self, context, event):
        wm = context.window_manager
        if context.window is None or context.workspace is None:
            return self.execute(context)
        context.workspace.status_text_set(self.BUILDING)
        self._ticks = 0
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {'RUNNING_MODAL'}

    def modal(self, context, event):
        if event.type != 'TIMER':
            return {'RUNNING_MODAL'}  # the build is about to start: nothing else meanwhile
        self._ticks += 1
        if self._ticks < self._wait_ticks:
            return {'RUNNING_MODAL'}
        context.window_manager.event_timer_remove(self._timer)
        try:
            return self.execute(context)
        finally:
            context.workspace.status_text_set(None)

    def execute(self, context):
        if report_missing(self):
            return {'CANCELLED'}
        values = presets.planet_settings(self.preset, mappaths.bundled)
        values.update(presets.quality_settings(self.quality))
        if self.heightmap:
            values["heightmap"] = bpy.path.abspath(self.heightmap)
        if self.color_map:
            values["color_map"] = bpy.path.abspath(self.color_map)
        mesh = obj = None
        undo = []  # puts back what framing changed when the planet is not added
        try:
            if values["color_map"] and not os.path.isfile(mappaths.resolve(values["color_map"])):
                raise core.FileError("colour map not found: "
                                     + mappaths.resolve(values["color_map"]))
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
            if cameras.lod_camera_params(obj, context.scene, for_render=True) is not None:
                refresh.refresh(obj, context.scene, build_mesh=True, for_render=True)
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
                cameras.fit_view_clips(context.scene)
                refresh.refresh(obj, context.scene)
            except core.REPORTED_ERRORS as exc:
                runtime.state(obj).error = str(exc)
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
        return active_planet(context) is not None

    def execute(self, context):
        if report_missing(self):
            return {'CANCELLED'}
        obj = active_planet(context)
        values = {}
        if self.planet != "NONE":
            values.update(presets.planet_settings(self.planet, mappaths.bundled))
        if self.quality != "NONE":
            values.update(presets.quality_settings(self.quality))
        trial = obj.planet_lod.as_dict()
        trial.update({k: mappaths.resolve(v) if k == "heightmap" else v
                      for k, v in values.items() if k in trial})
        if refuses(self, trial, "Preset not applied"):
            return {'CANCELLED'}
        obj.planet_lod.assign(values)
        if self.planet != "NONE":
            navigation.planet_preset_applied(context, obj, self.planet)
        if self.quality != "NONE":
            obj.planet_lod.quality = self.quality
            obj.planet_lod["active_quality_preset"] = presets.QUALITY[self.quality]["label"]
        runtime.mark_dirty(obj, geometry=True, material=True)
        return {'FINISHED'}



def menu_func(self, context):
    self.layout.operator(PLOD_OT_planet_add.bl_idname, text="Planet", icon='WORLD')
