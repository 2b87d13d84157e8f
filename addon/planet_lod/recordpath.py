"""Record Path: the viewport's view sampled while the artist flies or walks
(View > Navigation > Fly / Walk Navigation, Shift+`), written as a waypoint
CSV (planetlod.waypoints) that tools/flyby.py --path and the flyby operator
fly.

Sampling runs on an application timer, not in the operator's modal loop:
fly and walk navigation are modal operators of their own and take every
event while they run.  One waypoint per frame at the scene's frame rate,
from the scene's start frame; altitudes above the sea level (the planet's,
or its radius without a sea), no minimum clearance: the path flies what was
flown.  Roll is not recorded (fly and walk keep the horizon level).
"""
import os

import bpy
from bpy.props import StringProperty

from . import core, runtime

RECORDING = {}  # "state": the recording in progress (one at a time)


def sample(planet_obj, view_matrix_world, frame):
    """The Waypoint of a view (its world matrix: the inverse of the view matrix)."""
    s = planet_obj.planet_lod
    local = runtime.to_planet_space(planet_obj, view_matrix_world)
    base = s.sea_level if s.use_sea_level else 0.0
    return core.waypoints.pose_to_waypoint(local, s.radius, frame, base)


def make_path(points):
    return core.waypoints.Path(points, "sea", min_clearance=0.0)


class _Recording:
    def __init__(self, planet_name, region_3d, frame, interval, filepath):
        self.planet_name, self.region_3d = planet_name, region_3d
        self.frame, self.interval, self.filepath = frame, interval, filepath
        self.points = []
        self.error = ""

    def tick(self):
        if RECORDING.get("state") is not self:
            return None
        planet_obj = bpy.data.objects.get(self.planet_name)
        try:
            view = self.region_3d.view_matrix.inverted()
        except ReferenceError:  # the 3D view was closed
            self.error = "the 3D view closed"
            return None
        if planet_obj is None:
            self.error = "the planet was removed"
            return None
        self.points.append(sample(planet_obj, view, self.frame + len(self.points)))
        return self.interval


def stop_recording():
    """Ends the recording; writes and returns (path file, waypoint count)."""
    rec = RECORDING.pop("state", None)
    if rec is None:
        raise core.PlanetLODError("no path is being recorded")
    if bpy.app.timers.is_registered(rec.tick):
        bpy.app.timers.unregister(rec.tick)
    if len(rec.points) < 2:
        raise core.PlanetLODError("the recording has fewer than 2 waypoints: fly a little "
                                  "longer" + (f" ({rec.error})" if rec.error else ""))
    folder = os.path.dirname(rec.filepath)
    try:
        if folder:
            os.makedirs(folder, exist_ok=True)
        core.waypoints.write_csv(make_path(rec.points), rec.filepath)
    except OSError as exc:
        raise core.FileError(str(exc)) from exc
    return rec.filepath, len(rec.points)


def _region_3d(context):
    """The 3D view's RegionView3D (also from its header's menus)."""
    space = context.space_data
    if space is not None and space.type == 'VIEW_3D':
        return space.region_3d
    return context.region_data


class PLOD_OT_record_path(bpy.types.Operator):
    """Start recording the view as a camera path for the active planet; fly or
    walk (Shift+`), then run Record Path again to stop and write the path file"""
    bl_idname = "view3d.planet_record_path"
    bl_label = "Record Planet Path"
    bl_options = {'REGISTER'}

    filepath: StringProperty(name="Path file", subtype='FILE_PATH', default="//path.csv",
                             description="CSV file the recorded waypoints go to")

    @classmethod
    def poll(cls, context):
        if RECORDING.get("state") is not None:
            return True  # stops the recording
        obj = context.object
        return (obj is not None and obj.type == 'MESH' and obj.planet_lod.enabled
                and _region_3d(context) is not None)

    def execute(self, context):
        if RECORDING.get("state") is not None:
            try:
                filepath, count = stop_recording()
            except core.REPORTED_ERRORS as exc:
                self.report({'ERROR'}, f"Path not recorded: {exc}")
                return {'CANCELLED'}
            self.report({'INFO'}, f"Recorded {count} waypoints to {filepath}")
            return {'FINISHED'}
        scene = context.scene
        fps = scene.render.fps / scene.render.fps_base
        filepath = bpy.path.abspath(self.filepath)
        rec = _Recording(context.object.name, _region_3d(context), scene.frame_start,
                         1.0 / fps, filepath)
        RECORDING["state"] = rec
        bpy.app.timers.register(rec.tick, first_interval=0.0)
        self.report({'INFO'}, "Recording the view: fly or walk (Shift+`), then Record "
                              "Planet Path again to stop")
        return {'FINISHED'}


def menu_view(self, context):
    label = "Stop Recording Planet Path" if RECORDING.get("state") else "Record Planet Path"
    self.layout.operator(PLOD_OT_record_path.bl_idname, text=label, icon='REC')


def register():
    bpy.utils.register_class(PLOD_OT_record_path)
    bpy.types.VIEW3D_MT_view.append(menu_view)


def unregister():
    RECORDING.pop("state", None)
    bpy.types.VIEW3D_MT_view.remove(menu_view)
    bpy.utils.unregister_class(PLOD_OT_record_path)
