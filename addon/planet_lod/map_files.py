"""Operators on the planet's height files: load a height map, add and remove
insets (each checked before anything changes), and write a large map's tile
file (on a worker thread in the UI, with progress and Esc to cancel)."""
import os
import threading

import bpy
from bpy.props import BoolProperty, FloatProperty, IntProperty, StringProperty

from . import core, mappaths, refresh, runtime
from .core import planets
from .operators import active_planet, refuses, report_missing


class PLOD_OT_write_tiles(bpy.types.Operator):
    """Write the Large Map's tile file next to the height map (as big as the map;
    minutes for a global map).  The planet reads the map through it"""
    bl_idname = "object.planet_write_tiles"
    bl_label = "Write Tile File"
    bl_options = {'REGISTER'}

    @classmethod
    def poll(cls, context):
        obj = active_planet(context)
        return obj is not None and bool(obj.planet_lod.heightmap)

    def _settings(self, context):
        obj = active_planet(context)
        return obj, obj.planet_lod.as_dict()

    def _done(self, obj, written, error):
        if obj is None:  # deleted while its tile file was written
            return {'FINISHED'} if written and error is None else {'CANCELLED'}
        if error is not None:
            runtime.state(obj).error = str(error)
            self.report({'ERROR'}, f"{obj.name}: {error}")
            return {'CANCELLED'}
        if not written:
            self.report({'WARNING'}, f"{obj.name}: writing the tile file was cancelled")
            return {'CANCELLED'}
        runtime.mark_dirty(obj, geometry=True)
        self.report({'INFO'}, f"{obj.name}: tile file written")
        return {'FINISHED'}

    running = False  # a tile file is being written (one at a time)

    def _end(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace:
            context.workspace.status_text_set(None)
        type(self).running = False

    def cancel(self, context):  # Blender ends the job (a file loaded, the window closed)
        self._cancel = True
        self._thread.join()  # (stops at its next progress step)
        self._end(context)

    def execute(self, context):  # scripts and background: blocking
        if report_missing(self):
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
        if bpy.app.background or context.window is None:
            return self.execute(context)
        if report_missing(self):
            return {'CANCELLED'}
        if type(self).running:
            self.report({'ERROR'}, "Write Tile File: a tile file is being written already "
                                   "(Esc stops it)")
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
        type(self).running = True
        return {'RUNNING_MODAL'}

    def modal(self, context, event):
        if event.type == 'ESC' and event.value == 'PRESS':
            self._cancel = True
            return {'RUNNING_MODAL'}
        if event.type != 'TIMER':
            return {'PASS_THROUGH'}  # the interface stays usable while it writes
        wm = context.window_manager
        wm.progress_update(int(100 * self._fraction))
        if context.workspace:
            context.workspace.status_text_set(
                f"Writing the tile file: {100 * self._fraction:.0f} % (Esc to cancel)")
        if self._thread.is_alive():
            return {'RUNNING_MODAL'}
        self._end(context)
        written, error = self._result or (False, None)
        return self._done(bpy.data.objects.get(self._name), written, error)



class PLOD_OT_set_heightmap(bpy.types.Operator):
    """Load a height map into the active planet (checked before anything changes)"""
    bl_idname = "object.planet_set_heightmap"
    bl_label = "Load Height Map"
    bl_options = {'REGISTER', 'UNDO'}

    filepath: StringProperty(subtype='FILE_PATH')
    filter_image: BoolProperty(default=True, options={'HIDDEN'})

    @classmethod
    def poll(cls, context):
        return active_planet(context) is not None

    @classmethod
    def description(cls, context, properties):
        obj = active_planet(context)
        path = obj.planet_lod.heightmap if obj is not None else ""
        if not path:
            return "Load a height map into the active planet"
        return f"{bpy.path.abspath(path)}\nClick to load another height map"

    def invoke(self, context, event):
        obj = active_planet(context)
        if obj is not None and obj.planet_lod.heightmap and not self.filepath:
            self.filepath = bpy.path.abspath(obj.planet_lod.heightmap)
        context.window_manager.fileselect_add(self)
        return {'RUNNING_MODAL'}

    def execute(self, context):
        if report_missing(self):
            return {'CANCELLED'}
        obj = active_planet(context)
        trial = obj.planet_lod.as_dict()
        trial["heightmap"] = bpy.path.abspath(self.filepath)
        if refuses(self, trial, "Height map not loaded"):
            return {'CANCELLED'}
        obj.planet_lod.heightmap = self.filepath
        return {'FINISHED'}


class PLOD_OT_set_color_map(bpy.types.Operator):
    """Load a colour map into the active planet, or clear it"""
    bl_idname = "object.planet_set_color_map"
    bl_label = "Load Colour Map"
    bl_options = {'REGISTER', 'UNDO'}

    filepath: StringProperty(subtype='FILE_PATH')
    filter_image: BoolProperty(default=True, options={'HIDDEN'})
    clear: BoolProperty(name="Clear", default=False, options={'SKIP_SAVE'},
                        description="No colour map: colours by height")

    @classmethod
    def poll(cls, context):
        return active_planet(context) is not None

    @classmethod
    def description(cls, context, properties):
        if properties is not None and properties.clear:
            return "No colour map: colour the planet by height"
        obj = active_planet(context)
        path = obj.planet_lod.color_map if obj is not None else ""
        if not path:
            return "Load a colour map (a 2:1 world map or a 4:3 cube cross) into the active planet"
        return f"{mappaths.resolve(path)}\nClick to load another colour map"

    def invoke(self, context, event):
        if self.clear:
            return self.execute(context)
        obj = active_planet(context)
        if obj is not None and obj.planet_lod.color_map and not self.filepath:
            self.filepath = mappaths.resolve(obj.planet_lod.color_map)
        context.window_manager.fileselect_add(self)
        return {'RUNNING_MODAL'}

    def execute(self, context):
        settings = active_planet(context).planet_lod
        if self.clear:
            settings.color_map = ""
            return {'FINISHED'}
        if not os.path.isfile(bpy.path.abspath(self.filepath)):
            self.report({'ERROR'}, f"Colour map not loaded: no such file ({self.filepath})")
            return {'CANCELLED'}
        settings.color_map = self.filepath
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
        return active_planet(context) is not None

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {'RUNNING_MODAL'}

    def execute(self, context):
        if report_missing(self):
            return {'CANCELLED'}
        obj = active_planet(context)
        trial = obj.planet_lod.as_dict()
        box = dict(west=self.west, south=self.south, east=self.east, north=self.north,
                   scale=self.scale)
        path = bpy.path.abspath(self.filepath)
        trial["insets"] = trial["insets"] + [dict(box, path=path) if self.use_box else path]
        if refuses(self, trial, "Inset not added"):
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
        obj = active_planet(context)
        return obj is not None and len(obj.planet_lod.insets) > 0

    def execute(self, context):
        settings = active_planet(context).planet_lod
        index = settings.inset_index if self.index < 0 else self.index
        if not 0 <= index < len(settings.insets):
            self.report({'ERROR'}, f"No inset {index + 1}: the planet has "
                                   f"{len(settings.insets)}")
            return {'CANCELLED'}
        settings.insets.remove(index)
        settings.inset_index = max(0, min(index, len(settings.insets) - 1))
        runtime.mark_dirty(active_planet(context), geometry=True, material=True)
        refresh.check_settings(active_planet(context))
        return {'FINISHED'}


