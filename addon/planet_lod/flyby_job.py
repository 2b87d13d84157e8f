"""Render Flyby from the interface: a dialog first (frames, resolution,
samples, engine, output folder; a warning when the file is not saved), then a
job that renders one frame per timer step, shows its progress in the status
bar and stops on Esc between frames.  The frames rendered stay on disk; the
scene (camera, frame, render settings, floating origin) is put back either way.

Scripts and render farms use render.planet_flyby (render.py), which renders
the frames in one blocking call."""
import math
import os
import tempfile
import time

import bpy
from bpy.props import EnumProperty, IntProperty, StringProperty

from . import core, placement, render, runtime
from .core import report as flyby_report

ENGINES = [("BLENDER_EEVEE", "EEVEE", "Fast, rasterised"),
           ("CYCLES", "Cycles", "Path traced, slower")]


def default_directory():
    """Next to the .blend file, or a temporary folder for an unsaved file
    (Blender's working directory is no place for frames)."""
    if bpy.data.is_saved:
        return "//flyby/"
    return os.path.join(tempfile.gettempdir(), "planet_lod_flyby") + os.sep


class _RenderSettings:
    """The render settings the dialog overrides, to put back afterwards."""

    def __init__(self, scene):
        r = scene.render
        self.values = dict(engine=r.engine, resolution_x=r.resolution_x,
                           resolution_y=r.resolution_y,
                           resolution_percentage=r.resolution_percentage)
        self.eevee_samples = scene.eevee.taa_render_samples
        self.cycles_samples = scene.cycles.samples if hasattr(scene, "cycles") else None

    def restore(self, scene):
        for name, value in self.values.items():
            setattr(scene.render, name, value)
        scene.eevee.taa_render_samples = self.eevee_samples
        if self.cycles_samples is not None:
            scene.cycles.samples = self.cycles_samples


class PLOD_OT_flyby_job(bpy.types.Operator):
    """Render a flyby of the active planet (orbit, descent, skim) to PNG frames,
    a statistics CSV and a contact sheet, one frame at a time: the status bar
    shows the progress and Esc stops after the current frame"""
    bl_idname = "render.planet_flyby_job"
    bl_label = "Render Flyby"
    bl_options = {'REGISTER'}

    frames: IntProperty(name="Frames", default=120, min=2, max=100000,
                        description="Frames of the flyby's path, all rendered")
    resolution_x: IntProperty(name="Width", default=1280, min=16, max=16384, subtype='PIXEL')
    resolution_y: IntProperty(name="Height", default=720, min=16, max=16384, subtype='PIXEL')
    samples: IntProperty(name="Samples", default=16, min=1, max=4096,
                         description="Render samples per pixel")
    engine: EnumProperty(name="Engine", items=ENGINES, default="BLENDER_EEVEE")
    directory: StringProperty(name="Output Folder", subtype='DIR_PATH',
                              description="Folder for the frames, stats.csv and the "
                                          "contact sheet")

    running = None  # the job in progress (one at a time)

    @classmethod
    def poll(cls, context):
        obj = context.object
        return (obj is not None and obj.type == 'MESH' and obj.planet_lod.enabled
                and cls.running is None)

    def invoke(self, context, event):
        if core.load_native() is None:
            self.report({'ERROR'}, core.native_error)
            return {'CANCELLED'}
        r = context.scene.render
        if not self.properties.is_property_set("resolution_x"):
            self.resolution_x, self.resolution_y = r.resolution_x, r.resolution_y
        if not self.directory:
            self.directory = default_directory()
        return context.window_manager.invoke_props_dialog(self, width=360)

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(self, "frames")
        col = layout.column(align=True)
        col.prop(self, "resolution_x", text="Resolution X")
        col.prop(self, "resolution_y", text="Y")
        layout.prop(self, "samples")
        layout.prop(self, "engine")
        layout.prop(self, "directory")
        if not bpy.data.is_saved:
            col = layout.column(align=True)
            col.alert = True
            col.label(text="The file is not saved: the frames go to", icon='ERROR')
            col.label(text=bpy.path.abspath(self.directory), icon='BLANK1')

    # ---- the job ------------------------------------------------------------------

    def execute(self, context):
        if core.load_native() is None:
            self.report({'ERROR'}, core.native_error)
            return {'CANCELLED'}
        scene, planet = context.scene, context.object
        self.out_dir = bpy.path.abspath(self.directory or default_directory())
        try:
            os.makedirs(self.out_dir, exist_ok=True)
            self.csv = open(os.path.join(self.out_dir, "stats.csv"), "w")
        except OSError as exc:
            self.report({'ERROR'}, f"Flyby not started: {exc}")
            return {'CANCELLED'}
        self.csv.write(",".join(flyby_report.CSV_FIELDS) + "\n")
        self.planet_name = planet.name_full
        self.scene_state = render._SceneState(scene, planet)
        self.render_settings = _RenderSettings(scene)
        r = scene.render
        r.engine = self.engine
        r.resolution_x, r.resolution_y = self.resolution_x, self.resolution_y
        r.resolution_percentage = 100
        if self.engine == 'CYCLES':
            scene.cycles.samples = self.samples
        else:
            scene.eevee.taa_render_samples = self.samples
        r.image_settings.file_format = 'PNG'
        self.scene_state.add_sun(planet)
        placement.ensure_flyby_camera(scene, planet, self.frames)
        self.todo = list(range(1, self.frames + 1))
        self.done = []
        self.started = time.perf_counter()
        self.cancelled = False
        wm = context.window_manager
        wm.progress_begin(0, len(self.todo))
        self.timer = wm.event_timer_add(0.05, window=context.window)
        wm.modal_handler_add(self)
        type(self).running = self
        self._status(context)
        return {'RUNNING_MODAL'}

    def _status(self, context):
        text = (f"Rendering the flyby: frame {len(self.done) + 1} of {self.frames} "
                f"(Esc to stop after this frame)")
        if context.workspace:
            context.workspace.status_text_set(text)

    def modal(self, context, event):
        if event.type == 'ESC' and event.value == 'PRESS':
            return self._finish(context, cancelled=True)
        if event.type != 'TIMER':
            return {'PASS_THROUGH'}  # the interface stays usable between frames
        planet = bpy.data.objects.get(self.planet_name)
        if planet is None:
            self.report({'ERROR'}, "Flyby stopped: its planet was deleted")
            return self._finish(context, cancelled=True)
        try:
            self._render_frame(context.scene, planet, self.todo[len(self.done)])
        except core.REPORTED_ERRORS as exc:
            self.report({'ERROR'}, f"Flyby failed: {exc}")
            return self._finish(context, cancelled=True)
        except Exception:
            self._finish(context, cancelled=True)  # the scene back before the traceback
            raise
        context.window_manager.progress_update(len(self.done))
        if len(self.done) == len(self.todo):
            return self._finish(context, cancelled=False)
        self._status(context)
        return {'RUNNING_MODAL'}

    def _render_frame(self, scene, planet, frame):
        scene.frame_set(frame)  # handlers: place the camera, refine, rebuild the mesh
        st = runtime.state(planet)
        if st.error:
            raise core.PlanetLODError(st.error)
        path = os.path.join(self.out_dir, f"frame_{frame:04d}.png")
        scene.render.filepath = path
        t0 = time.perf_counter()
        if 'CANCELLED' in bpy.ops.render.render(write_still=True):
            raise core.Cancelled(f"the render of frame {frame} was cancelled")
        row = dict(st.stats)
        row["frame"] = frame
        row["render_s"] = round(time.perf_counter() - t0, 3)
        local = runtime.to_planet_space(planet, scene.camera.matrix_world)
        distance = math.sqrt(sum(local[i][3] ** 2 for i in range(3)))
        row["camera_altitude_m"] = round(distance - planet.planet_lod.radius, 3)
        self.csv.write(flyby_report.csv_row(row) + "\n")
        self.csv.flush()
        self.done.append(frame)

    def cancel(self, context):  # Blender ends the job (a file loaded, the window closed)
        if type(self).running is self:
            self._finish(context, cancelled=True)

    def _finish(self, context, cancelled):
        wm = context.window_manager
        wm.event_timer_remove(self.timer)
        wm.progress_end()
        if context.workspace:
            context.workspace.status_text_set(None)
        self.csv.close()
        scene = context.scene
        self.render_settings.restore(scene)
        # the scene as it was; after a whole flyby the flyby camera stays to look at
        self.scene_state.restore(keep_camera=not cancelled)
        type(self).running = None
        frames = [os.path.join(self.out_dir, f"frame_{f:04d}.png") for f in self.done]
        if frames:
            render.contact_sheet(frames, os.path.join(self.out_dir, "contact_sheet.png"))
        if cancelled:
            self.report({'WARNING'}, f"Flyby stopped: {len(self.done)} of {self.frames} "
                                     f"frames in {self.out_dir}")
            return {'CANCELLED'}
        self.report({'INFO'}, f"Flyby: {len(self.done)} frames in {self.out_dir}")
        return {'FINISHED'}
