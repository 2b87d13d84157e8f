"""Flybys: the camera path, frame-by-frame rendering with stats CSV and a contact sheet.

The flyby camera carries custom properties (planet name, path length, skim
height); the frame_change_pre handler places it with flyby.flyby_pose(), a pure
function of the frame number, so any sub-range renders exactly the frames of
the full path (render-farm splits).
"""
import math
import os
import sys
import threading
import time

import bpy
from bpy.app.handlers import persistent
from bpy.props import IntProperty, StringProperty, FloatProperty

from . import core, placement, runtime
from .core import report as flyby_report  # `report` is the progress callback here

def _log(message):
    print(message, flush=True)
    sys.stdout.flush()


# ---- batch renders: a frame whose planet could not be built is not written -----

def batch_failure(scene):
    """The message for a frame of `scene` that cannot be right (a planet that
    could not be built: a missing or bad map, bad settings), else ""."""
    bad = [f"{obj.name}: {runtime.state(obj).error}" for obj in runtime.planet_objects(scene)
           if not obj.hide_render and runtime.state(obj).error]
    cam = scene.camera
    if cam is not None and cam.get(placement.FLYBY_KEY) and cam.get(placement.PATH_KEY):
        try:
            path = core.waypoints.saved_path(cam[placement.PATH_KEY])
        except core.REPORTED_ERRORS as exc:
            bad.append(f"{cam.name}: {exc}")
        else:
            if not path.first <= scene.frame_current <= path.last:
                bad.append(f"{cam.name}: frame {scene.frame_current} is outside its path "
                           f"(frames {path.first}-{path.last})")
    if not bad:
        return ""
    return f"planet_lod: cannot render frame {scene.frame_current}: " + "; ".join(bad)


def fail_batch_render(message):
    """Ends a headless Blender at once with exit status 1, before the frame is
    written: a handler's exception would only be printed, and Blender would
    go on to save the wrong picture and exit 0."""
    print(message, file=sys.stderr, flush=True)
    sys.stdout.flush()
    os._exit(1)


def _headless_main_thread():
    return bpy.app.background and threading.current_thread() is threading.main_thread()


# When the frame being rendered headless started rendering (for its render_s).
_frame_started = {}


@persistent
def on_render_pre_check(scene, depsgraph=None):
    """Runs after the render_pre refresh (handlers.py): in a headless render (`blender -b
    file.blend -a`, scripts, farm tasks) a planet in error stops the render;
    the interactive UI reports the error in the panel and renders on."""
    if not _headless_main_thread():
        return
    message = batch_failure(scene)
    if message:
        fail_batch_render(message)
    _frame_started[scene.name] = time.perf_counter()


def geo_camera_planet(scene):
    """The planet that the scene camera is placed on by its planet_lod_geo
    settings, or None."""
    cam = scene.camera
    geo = cam.planet_lod_geo if cam is not None else None
    if geo is None or not geo.enabled or geo.planet is None or not geo.planet.planet_lod.enabled:
        return None
    return geo.planet


@persistent
def on_render_write_stats(scene, depsgraph=None):
    """In a headless render through a planet_lod_geo camera (`blender -b
    file.blend -a`, farm tasks), each written frame gets its stats row in its
    own file beside the frames (chunks rendering at once write different
    files); merge_frame_stats() makes the stats.csv."""
    if not _headless_main_thread():
        return
    planet_obj = geo_camera_planet(scene)
    if planet_obj is None:
        return
    frame = scene.frame_current
    started = _frame_started.pop(scene.name, None)
    row = frame_stats(scene, planet_obj, frame,
                      time.perf_counter() - started if started is not None else 0.0)
    frames_folder = os.path.dirname(scene.render.frame_path(frame=frame))
    try:
        flyby_report.write_frame_stats(frames_folder, row)
    except core.REPORTED_ERRORS as exc:  # stats that cannot be written fail the render
        fail_batch_render(f"planet_lod: cannot write the stats of frame {frame}: {exc}")


def merge_frame_stats(frames_folder, frames=None):
    """frames_folder/stats.csv from the frames' own stats files (see
    on_render_write_stats); the number of rows (0: the render wrote none)."""
    return flyby_report.merge_frame_stats(bpy.path.abspath(frames_folder), frames)


def add_handlers():
    """After handlers.add_handlers(): the check runs after the render refresh."""
    if on_render_pre_check not in bpy.app.handlers.render_pre:
        bpy.app.handlers.render_pre.append(on_render_pre_check)
    if on_render_write_stats not in bpy.app.handlers.render_write:
        bpy.app.handlers.render_write.append(on_render_write_stats)


def remove_handlers():
    while on_render_pre_check in bpy.app.handlers.render_pre:
        bpy.app.handlers.render_pre.remove(on_render_pre_check)
    while on_render_write_stats in bpy.app.handlers.render_write:
        bpy.app.handlers.render_write.remove(on_render_write_stats)


def check_flyby_frames(first, last, path_frames, path=None):
    """Frames first..last must lie on the path: frames 1..path_frames of the
    default one, or the frames of `path` (a planetlod.waypoints.Path)."""
    lo, hi = (path.first, path.last) if path is not None else (1, path_frames)
    if first > last:
        raise core.PlanetLODError(f"frames {first}-{last}: the first comes after the last")
    if first < lo or last > hi:
        raise core.PlanetLODError(f"frames {first}-{last} are outside the path "
                                  f"(frames {lo}-{hi})")


def render_flyby(scene, planet_obj, first, last, out_dir, path_frames, report=_log, path=None):
    """Renders frames first..last of the flyby to out_dir/frame_####.png; writes
    stats.csv and contact_sheet.png.  Returns the list of per-frame stat dicts.
    `path` (a planetlod.waypoints.Path) replaces the orbit, descent and skim;
    path_frames is then its last frame."""
    if path is not None:
        path_frames = path.last
    check_flyby_frames(first, last, path_frames, path)
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as exc:  # the artist's output folder
        raise core.FileError(str(exc)) from exc
    saved = _SceneState(scene, planet_obj)
    try:
        saved.add_sun(planet_obj)
        rows = _render_frames(scene, planet_obj, first, last, out_dir, path_frames, report,
                              path)
    except BaseException:
        # cancelled (Esc, a failed frame, KeyboardInterrupt): put the scene back
        saved.restore()
        raise
    # done: the scene camera, frame and output settings as they were; the flyby
    # camera stays (not as the scene camera) to look at or render again
    saved.restore(keep_camera=True)
    return rows


class _SceneState:
    """What a flyby changes in the scene, to put it back afterwards."""

    def __init__(self, scene, planet_obj):
        self.scene = scene
        self.camera_name = scene.camera.name if scene.camera else None
        self.flyby_name = "Flyby " + planet_obj.name
        self.had_flyby = bpy.data.objects.get(self.flyby_name) is not None
        self.frame = scene.frame_current
        self.filepath = scene.render.filepath
        self.file_format = scene.render.image_settings.file_format
        self.planet_name = planet_obj.name
        anchor = planet_obj.get(runtime.ANCHOR_KEY)
        self.anchor = None if anchor is None else list(runtime.anchor(planet_obj))
        self.sun_name = None

    def add_sun(self, planet_obj):
        """A sun for the flyby's frames when the scene has none (removed after)."""
        scene = self.scene
        if any(o.type == 'LIGHT' and o.data.type == 'SUN' and not o.hide_render
               for o in scene.objects):
            return
        sun = bpy.data.objects.new("Flyby Sun", bpy.data.lights.new("Flyby Sun", 'SUN'))
        sun.data.energy = core.flyby.FLYBY_SUN_STRENGTH
        sun.rotation_euler = core.flyby.FLYBY_SUN_ROTATION
        scene.collection.objects.link(sun)
        self.sun_name = sun.name

    def restore(self, keep_camera=False):
        scene = self.scene
        sun = bpy.data.objects.get(self.sun_name) if self.sun_name else None
        if sun is not None:
            data = sun.data
            bpy.data.objects.remove(sun)
            if data is not None and data.users == 0:
                bpy.data.lights.remove(data)
        if not self.had_flyby and not keep_camera:
            cam = bpy.data.objects.get(self.flyby_name)
            if cam is not None:
                data = cam.data
                bpy.data.objects.remove(cam)
                if data is not None and data.users == 0:
                    bpy.data.cameras.remove(data)
        scene.camera = bpy.data.objects.get(self.camera_name) if self.camera_name else None
        scene.render.filepath = self.filepath
        scene.render.image_settings.file_format = self.file_format
        planet_obj = bpy.data.objects.get(self.planet_name)
        if planet_obj is not None:  # the floating origin where it was
            if self.anchor is None:
                planet_obj.pop(runtime.ANCHOR_KEY, None)
            else:
                runtime.set_anchor(planet_obj, self.anchor)
            runtime.mark_dirty(planet_obj)
        scene.frame_set(self.frame)  # handlers rebuild the LOD for the restored camera


def frame_stats(scene, planet_obj, frame, render_s):
    """The stats row of a rendered frame: the planet's refinement for the
    scene camera, the camera's altitude and the ground under it."""
    row = dict(runtime.state(planet_obj).stats)
    row["frame"] = frame
    row["render_s"] = round(render_s, 3)
    local = runtime.to_planet_space(planet_obj, scene.camera.matrix_world)
    distance = math.sqrt(sum(local[i][3] ** 2 for i in range(3)))
    row["camera_altitude_m"] = round(distance - planet_obj.planet_lod.radius, 3)
    ground = placement.terrain_height(planet_obj)
    if ground is not None:  # the terrain under the camera (the sea: <= sea level)
        row["camera_ground_m"] = round(ground(tuple(local[i][3] / distance for i in range(3))), 3)
    return row


def _render_frames(scene, planet_obj, first, last, out_dir, path_frames, report, path=None):
    cam = bpy.data.objects.get("Flyby " + planet_obj.name)
    if cam is not None:  # placed by the default path until this run's is set
        cam.pop(placement.PATH_KEY, None)
    cam = placement.ensure_flyby_camera(scene, planet_obj, path_frames)
    if path is not None:
        cam[placement.PATH_KEY] = core.waypoints.write_csv(path)
    wm = bpy.context.window_manager
    rows = []
    csv_path = os.path.join(out_dir, "stats.csv")
    frames = list(range(first, last + 1))
    scene.render.image_settings.file_format = 'PNG'
    if wm:
        wm.progress_begin(0, len(frames))
    t_start = time.perf_counter()
    try:
        try:
            csv = open(csv_path, "w")
        except OSError as exc:  # the artist's output folder
            raise core.FileError(str(exc)) from exc
        with csv:
            csv.write(",".join(flyby_report.CSV_FIELDS) + "\n")
            for index, frame in enumerate(frames):
                scene.frame_set(frame)  # handlers: place camera, refine, rebuild mesh
                st = runtime.state(planet_obj)
                if st.error:
                    raise core.PlanetLODError(st.error)
                path = os.path.join(out_dir, f"frame_{frame:04d}.png")
                scene.render.filepath = path
                t0 = time.perf_counter()
                if 'CANCELLED' in bpy.ops.render.render(write_still=True):
                    raise core.Cancelled(f"flyby cancelled at frame {frame}")
                drop_timings(path)
                row = frame_stats(scene, planet_obj, frame, time.perf_counter() - t0)
                rows.append(row)
                csv.write(flyby_report.csv_row(row) + "\n")
                csv.flush()
                if wm:
                    wm.progress_update(index + 1)
                elapsed = time.perf_counter() - t_start
                report(f"planet_lod flyby: frame {frame} ({index + 1}/{len(frames)}) "
                       f"sectors {row.get('visible', 0)} triangles {row.get('triangles', 0)} "
                       f"altitude {row['camera_altitude_m']:.1f} m render {row['render_s']:.2f} s "
                       f"elapsed {elapsed:.1f} s")
    finally:
        if wm:
            wm.progress_end()
    contact_sheet([os.path.join(out_dir, f"frame_{f:04d}.png") for f in frames],
                  os.path.join(out_dir, "contact_sheet.png"))
    return rows


def drop_timings(png_path):
    """Removes the render's timings (Cycles' `...time` text chunks) from a PNG,
    so that a frame's file is the same from every run, machine and chunk."""
    import struct
    with open(png_path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        return
    kept, at = [data[:8]], 8
    while at + 8 <= len(data):
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        chunk = data[at:at + 12 + length]
        key = data[at + 8:at + 8 + length].split(b"\0", 1)[0] if kind == b"tEXt" else b""
        if not key.endswith(b"_time"):
            kept.append(chunk)
        at += 12 + length
    cleaned = b"".join(kept)
    if cleaned != data:
        with open(png_path, "wb") as f:
            f.write(cleaned)


def contact_sheet(paths, out_path, thumb_width=160):
    """Tiles the frames into one PNG with Blender's image API (no numpy)."""
    paths = [p for p in paths if os.path.isfile(p)]
    if not paths:
        return None
    first = bpy.data.images.load(paths[0])
    w0, h0 = first.size
    bpy.data.images.remove(first)
    tw = min(thumb_width, w0)
    th = max(1, round(h0 * tw / w0))
    sw, sh, places = flyby_report.contact_sheet_layout(len(paths), tw, th)
    pixels = [0.08, 0.08, 0.08, 1.0] * (sw * sh)
    for path, (x, y) in zip(paths, places):
        image = bpy.data.images.load(path)
        try:
            image.scale(tw, th)
            src = list(image.pixels)
        finally:
            bpy.data.images.remove(image)
        for row in range(th):
            dst = ((y + row) * sw + x) * 4
            pixels[dst:dst + tw * 4] = src[row * tw * 4:(row + 1) * tw * 4]
    sheet = bpy.data.images.new("planet_lod contact sheet", sw, sh, alpha=True)
    try:
        sheet.pixels.foreach_set(pixels)
        sheet.filepath_raw = out_path
        sheet.file_format = 'PNG'
        sheet.save()
    finally:
        bpy.data.images.remove(sheet)
    return out_path


class PLOD_OT_flyby(bpy.types.Operator):
    """Render a flyby of the active planet (orbit, descent, skim) to PNG frames,
    a per-frame statistics CSV and a contact sheet"""
    bl_idname = "render.planet_flyby"
    bl_label = "Render Planet Flyby"
    bl_options = {'REGISTER'}

    frames: StringProperty(name="Frames", default="1-120",
                           description="Range of frames of the path to render, e.g. 31-60")
    path_frames: IntProperty(name="Path length", default=120, min=2, max=100000,
                             description="Frames of the whole path (fixes the camera per frame)")
    directory: StringProperty(name="Output", subtype='DIR_PATH', default="//flyby/")
    skim_height: FloatProperty(name="Skim height", default=5.0, min=0.1, max=1e5)
    path_file: StringProperty(name="Path", subtype='FILE_PATH', default="",
                              description="Waypoints to fly instead of the orbit, descent "
                                          "and skim (.csv, .gpx or .kml; Record Path writes "
                                          "the .csv)")

    @classmethod
    def poll(cls, context):
        obj = context.object
        return obj is not None and obj.type == 'MESH' and obj.planet_lod.enabled

    def execute(self, context):
        if core.load_native() is None:
            self.report({'ERROR'}, core.native_error)
            return {'CANCELLED'}
        try:
            first, last = flyby_report.parse_frames(self.frames)
            out_dir = bpy.path.abspath(self.directory)
            path = (core.waypoints.read_path(bpy.path.abspath(self.path_file),
                                             path_frames=self.path_frames)
                    if self.path_file else None)
            rows = render_flyby(context.scene, context.object, first, last, out_dir,
                                self.path_frames, path=path)
        except core.REPORTED_ERRORS as exc:
            self.report({'ERROR'}, f"Flyby failed: {exc}")
            return {'CANCELLED'}
        self.report({'INFO'}, f"Flyby: {len(rows)} frames in {out_dir}")
        return {'FINISHED'}
