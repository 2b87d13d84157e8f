"""Refreshing planets: LOD cameras, refinement, mesh (re)build, timers, handlers.

Runtime state lives in runtime.py.

Threads: the viewport refresh (the `tick` timer) and most handlers run on
Blender's main thread, but an animation render started from the UI (Ctrl F12)
calls the frame_change handlers from the render job's thread.  So:
  * one refresh runs at a time, process-wide: refresh() holds `_lock` (an RLock)
    from refine to the written mesh, so a render thread never emits the LOD a
    viewport refine made between its refine and its mesh() call; render-side
    callers wait for the lock, the timer only tries it and retries next tick;
  * the timer does no refresh while a render is in progress (`_renders`,
    counted from render_init to render_complete / render_cancel), so the
    viewport never rewrites a mesh the render is reading;
  * `_local.busy` marks *this thread* as inside refresh(), to ignore handlers
    fired by our own mesh writes (re-entry), never another thread's refresh;
  * the native Planet has its own lock as well (planetlod), so direct calls
    from other threads cannot corrupt its refiner either;
  * planet_add turns on Render > Lock Interface, which Blender requires for
    handlers that write data from the render thread;
  * with the GPU preview the timer runs a planet's refresh (refine and the
    preview's surface, no bpy) in a SurfaceJob thread that holds `_lock`, and
    applies its result at a later tick; while a job runs the timer touches no
    planet (a native call would wait for the job), and a refresh made since the
    job started (an operator, a render) makes its result stale: dropped, the
    planet refreshes again.
"""
import hashlib
import threading
import time
from array import array

import bpy
import numpy
from bpy.app.handlers import persistent
from mathutils import Matrix

from . import atmosphere, compat, core, materials, placement
from .core import flyby, surface
from .core import planets as planet_settings  # live.planets is the scene's planet objects
from .runtime import (ANCHOR_KEY, RUNTIME, PlanetState, anchor, existing_state,  # noqa: F401
                      forget_removed, mark_dirty, planet_objects, set_anchor, state,
                      to_planet_space)

# The farm's job type (farm/flamenco/planet_lod.js) calls live.planets(scene).
planets = planet_objects

REFRESH_INTERVAL_S = 0.1   # during navigation the detail follows at this rate
TICK_S = 0.05
BUSY_TICK_S = 0.01           # while a viewport job runs or its refinement goes on
_lock = threading.RLock()   # one refresh at a time, across threads
_local = threading.local()  # .busy: this thread is inside refresh()
_renders = 0                # renders in progress (render_init .. complete/cancel)


def _in_refresh():
    return getattr(_local, "busy", False)


def check_settings(obj):
    """Checks what can be checked at once when a setting changes (a height map
    or inset path that is missing, a folder or empty), so the panel shows the
    reason right away; the refresh reports everything else."""
    st = state(obj)
    settings = obj.planet_lod.as_dict()
    try:
        planet_settings.check_heightmap(settings.get("heightmap"))
        planet_settings.check_insets(planet_settings.inset_paths(settings))
    except core.FileError as exc:
        st.error = str(exc)
    else:
        if st.error.startswith(("height map", "inset")):
            st.error = ""


# ---- cameras ----------------------------------------------------------------

def _render_resolution(scene):
    r = scene.render
    return (max(1, r.resolution_x * r.resolution_percentage // 100),
            max(1, r.resolution_y * r.resolution_percentage // 100),
            r.pixel_aspect_x, r.pixel_aspect_y)


def camera_object(obj, scene):
    """The camera object the viewport's detail is made for when the planet asks
    for a camera (Scene Camera, Chosen Camera); None: the viewport itself."""
    s = obj.planet_lod
    if s.lod_camera == 'CAMERA' and s.camera is not None and s.camera.name in scene.objects:
        return s.camera
    if s.lod_camera in ('CAMERA', 'SCENE') and scene.camera is not None:
        return scene.camera
    return None


def render_camera(scene):
    """The camera renders see (F12, animations, flybys): always the scene camera."""
    return scene.camera


def _evaluated(obj, depsgraph):
    """The evaluated object: during `-a` renders animation is evaluated in the
    render depsgraph only, the original objects keep frame-1 transforms."""
    if depsgraph is None:
        return obj
    try:
        return obj.evaluated_get(depsgraph)
    except (ReferenceError, RuntimeError):
        return obj


def camera_params_from_object(obj, cam, scene, depsgraph=None, cam_matrix=None):
    """planetlod.Camera keyword arguments for a camera object at render resolution
    (cam_matrix: its world matrix, when known better than cam.matrix_world)."""
    cam = _evaluated(cam, depsgraph)
    data = cam.data
    res_x, res_y, asp_x, asp_y = _render_resolution(scene)
    evaluated = _evaluated(obj, depsgraph)
    local = evaluated.matrix_world.inverted_safe() @ (
        cam_matrix if cam_matrix is not None else cam.matrix_world)
    matrix = [list(row) for row in local]
    for i, a in enumerate(anchor(obj)):
        matrix[i][3] += a
    return dict(matrix_world=matrix,
                type='ORTHO' if data.type == 'ORTHO' else 'PERSP', lens=data.lens,
                sensor_width=data.sensor_width, sensor_height=data.sensor_height,
                sensor_fit=data.sensor_fit, ortho_scale=data.ortho_scale,
                shift_x=data.shift_x, shift_y=data.shift_y, clip_start=data.clip_start,
                clip_end=data.clip_end, resolution_x=res_x, resolution_y=res_y,
                pixel_aspect_x=asp_x, pixel_aspect_y=asp_y)


def viewport():
    """(space, region, region_3d) of the largest 3D viewport, or None."""
    best = None
    wm = bpy.context.window_manager
    for window in wm.windows if wm else ():
        for area in window.screen.areas:
            if area.type != 'VIEW_3D':
                continue
            for region in area.regions:
                if region.type == 'WINDOW' and (best is None or
                                                region.width * region.height > best[1].width * best[1].height):
                    best = (area.spaces.active, region, area.spaces.active.region_3d)
    return best


def view_to_world(r3d):
    """The view's camera matrix from its location, rotation and distance: current
    as soon as they are set (view_matrix is only updated when the view redraws)."""
    return (Matrix.Translation(r3d.view_location) @ r3d.view_rotation.to_matrix().to_4x4()
            @ Matrix.Translation((0.0, 0.0, r3d.view_distance)))


def camera_params_from_view(obj, view):
    space, region, r3d = view
    matrix = to_planet_space(obj, view_to_world(r3d))
    ortho = r3d.view_perspective == 'ORTHO'
    return dict(matrix_world=matrix, type='ORTHO' if ortho else 'PERSP',
                lens=space.lens, sensor_width=72.0, sensor_height=72.0, sensor_fit='AUTO',
                ortho_scale=max(r3d.view_distance * 72.0 / space.lens, 1e-6),
                clip_start=space.clip_start, clip_end=space.clip_end,
                resolution_x=max(region.width, 1), resolution_y=max(region.height, 1))


def lod_camera_params(obj, scene, for_render=False, depsgraph=None):
    """Keyword arguments for planetlod.Camera, or None when there is no camera at all.

    Renders (for_render) always refine for the render camera, whatever the
    viewport shows, so a render never gets the viewport's detail.  The viewport
    refines for itself (or, looking through the camera, for that camera), or for
    the camera the planet names; without a viewport (background) it falls back
    to the scene camera."""
    if for_render:
        cam = render_camera(scene)
        return None if cam is None else camera_params_from_object(obj, cam, scene, depsgraph)
    s = obj.planet_lod
    cam = camera_object(obj, scene)
    if (s.lod_camera == 'VIEWPORT' or cam is None) and not bpy.app.background:
        view = viewport()
        if view is not None:
            if view[2].view_perspective == 'CAMERA' and scene.camera is not None:
                return camera_params_from_object(obj, scene.camera, scene)
            return camera_params_from_view(obj, view)
    cam = cam or render_camera(scene)
    if cam is None:
        return None
    return camera_params_from_object(obj, cam, scene, depsgraph)


# ---- clip ranges ------------------------------------------------------------------
# The horizon-distance correction (K. Gasiński's HRTMR, master's thesis,
# Gdańsk University of Technology, 2010): the nearest
# terrain cannot be closer than the camera's height above the highest peak and
# nothing beyond the horizon plus the distance at which the highest peak still
# rises over it can be seen.  Clipping there keeps depth precision where the
# terrain is and cuts the far hemisphere away.

def _scale(obj):
    return max(obj.matrix_world.to_scale()) or 1.0


def view_clip(obj, planet, params):
    """(clip_start, clip_end) in scene units for a viewport camera: Gasiński's
    range, with a clip start of a tenth of the height above the ground below the
    camera where the camera is lower than the highest peak (his clip
    start is then ~0) and at most a million times shorter than the clip end."""
    near, far = planet.recommended_clip(planet_settings.make_camera(params))
    eye = [row[3] for row in params["matrix_world"][:3]]
    distance = sum(c * c for c in eye) ** 0.5
    if distance > 0.0:
        ground = planet.radius + planet.height(*(c / distance for c in eye))
        near = max(near, 0.1 * (distance - ground))
    near = _depth_safe_near(near, far)
    scale = _scale(obj)
    return near * scale, far * scale


def _depth_safe_near(near, far):
    """A clip start no more than a million times shorter than the clip end (and
    at least 1 mm): below the highest peak Gasiński's clip start is ~0, and a
    rasterizer's depth buffer (the viewport, EEVEE) then cannot order surfaces
    kilometres away -- the far side beyond the horizon shows through the
    ground in front of it."""
    return max(near, far * 1e-6, 1e-3)


def fit_view_clips(scene):
    """Fits each 3D view's clip range to the planets it shows (those with Viewport
    Clip to Horizon on); views looking through the camera use its clip range."""
    targets = []
    for obj in planet_objects(scene):
        if obj.planet_lod.view_clip_from_horizon and obj.visible_get():
            try:
                targets.append((obj, planet_settings.build_planet(obj.planet_lod.as_dict())))
            except core.REPORTED_ERRORS:
                continue
    if not targets:
        return
    wm = bpy.context.window_manager
    for window in wm.windows if wm else ():
        for area in window.screen.areas:
            if area.type != 'VIEW_3D':
                continue
            space = area.spaces.active
            region = next((r for r in area.regions if r.type == 'WINDOW'), None)
            r3d = space.region_3d
            if region is None or r3d is None or r3d.view_perspective == 'CAMERA':
                continue
            near = far = None
            for obj, planet in targets:
                try:
                    n, f = view_clip(obj, planet, camera_params_from_view(obj, (space, region, r3d)))
                except core.REPORTED_ERRORS:
                    continue
                near = n if near is None else min(near, n)
                far = f if far is None else max(far, f)
            if near is None:
                continue
            if not (0.97 < space.clip_start / near < 1.03 and 0.97 < space.clip_end / far < 1.03):
                space.clip_start, space.clip_end = near, far
                area.tag_redraw()


def keyframed_matrix(obj, frame):
    """obj's world matrix at `frame` from its keyframed location, rotation and
    scale, before the depsgraph has evaluated that frame (frame_change_pre);
    None for objects with a parent or constraints (the depsgraph's job)."""
    anim = obj.animation_data
    if anim is None or anim.action is None or obj.parent is not None or obj.constraints:
        return None
    loc, rot, scale = obj.location.copy(), obj.rotation_euler.copy(), obj.scale.copy()
    if obj.rotation_mode not in ('XYZ', 'XZY', 'YXZ', 'YZX', 'ZXY', 'ZYX'):
        return None
    targets = {"location": loc, "rotation_euler": rot, "scale": scale}
    for fcurve in compat.action_fcurves(obj):
        target = targets.get(fcurve.data_path)
        if target is not None and 0 <= fcurve.array_index < 3 and not fcurve.mute:
            target[fcurve.array_index] = fcurve.evaluate(frame)
    return Matrix.LocRotScale(loc, rot, scale)


def apply_camera_clip(scene, depsgraph=None, cam_matrix=None):
    """Sets the render camera's clip range from the horizon of the planets that
    ask for it (Camera Clip to Horizon): the union of their ranges.  Returns it
    (None: nothing set)."""
    cam = render_camera(scene)
    if cam is None or cam.type != 'CAMERA':
        return None
    near = far = None
    for obj in planet_objects(scene):
        if not obj.planet_lod.clip_from_horizon:
            continue
        try:
            planet = planet_settings.build_planet(obj.planet_lod.as_dict())
            params = camera_params_from_object(obj, cam, scene, depsgraph, cam_matrix)
            n, f = planet.recommended_clip(planet_settings.make_camera(params))
        except core.REPORTED_ERRORS:
            continue
        n, f = _depth_safe_near(n, f) * _scale(obj), f * _scale(obj)
        near = n if near is None else min(near, n)
        far = f if far is None else max(far, f)
    if near is None:
        return None
    data = cam.data
    if abs(data.clip_start - near) > 1e-6 * near or abs(data.clip_end - far) > 1e-6 * far:
        data.clip_start, data.clip_end = near, far
        data.update_tag()
    return near, far


def _with_clip(params, clip):
    """Camera params with the clip range just set on the camera: an evaluated
    camera (animation renders) still has the old one."""
    if params is not None and clip is not None:
        params = dict(params, clip_start=clip[0], clip_end=clip[1])
    return params


# ---- refresh ------------------------------------------------------------------

NO_CAMERA = "no LOD camera: add a camera to the scene or use the viewport"
INSIDE_VIEW = ("the view is inside the planet (below the terrain): zoom out or press "
               "Home to see it")
INSIDE_RENDER = ("the render camera is inside the planet (below the terrain): move it out "
                 "to render the planet")


def refresh(obj, scene, params=None, build_mesh=False, for_render=False):
    """Refines `obj` for its LOD camera; optionally rebuilds its mesh.  Raises
    core.REPORTED_ERRORS on bad input (callers report them)."""
    with _lock:
        return _refresh_locked(obj, scene, params, build_mesh, for_render)


def _refresh_locked(obj, scene, params, build_mesh, for_render):
    st = state(obj)
    settings = obj.planet_lod.as_dict()
    planet = planet_settings.build_planet(settings)
    if params is None:
        # the render camera's frustum ends at its clip end: fit that first
        clip = apply_camera_clip(scene) if for_render else None
        params = _with_clip(lod_camera_params(obj, scene, for_render=for_render), clip)
    if params is None:
        raise core.PlanetLODError(NO_CAMERA)
    # the preview draws the surface the render gets (heights with the detail,
    # morphing, the sea, the core's normals, relative to the anchor), of the
    # viewport's LOD only: a render's never leaks in
    preview = obj.planet_lod.gpu_preview and not bpy.app.background and not for_render
    was_busy, _local.busy = _in_refresh(), True
    st.serial += 1  # a viewport job started before this refresh is out of date
    try:
        work = _work_for(obj, st, planet, settings, params, for_render,
                         check_size=build_mesh or preview, preview=preview)
        work.run()
        _apply(st, work)
        st.pending = False  # refined in full
        if build_mesh:
            t0 = time.perf_counter()
            mesh = planet.mesh(template_level=settings["template_level"],
                               morph=obj.planet_lod.morph)
            st.stats["vertices"] = mesh.vertex_count
            st.stats["triangles"] = mesh.triangle_count
            write_mesh(obj, mesh)
            if not for_render:
                st.render_key = None  # the mesh no longer matches the render camera
            st.stats["mesh_ms"] = round((time.perf_counter() - t0) * 1000.0, 3)
            st.mesh_hash = mesh_digest(mesh)
            st.stats["mesh_hash"] = st.mesh_hash
        _finish(obj, scene, st, params, build_mesh)
        st.dirty = False
        return st.stats
    finally:
        _local.busy = was_busy


class SurfaceWork:
    """A refresh's work in the core -- refine for the LOD camera, then the
    preview's surface when the sectors in view changed -- touching nothing of
    bpy, so the viewport timer can run it on a worker thread (SurfaceJob)
    while Blender's UI goes on; the main thread applies the result (_apply)."""

    def __init__(self, planet, settings, params, refine, for_render, check_size, preview,
                 max_splits=0):
        self.planet, self.settings, self.params = planet, settings, params
        self.refine, self.for_render, self.check_size = refine, for_render, check_size
        self.max_splits = max_splits  # > 0: a progressive refresh, later ones carry on
        self.ms = 0.0                 # the time run() took
        self.preview = preview  # None, or (anchor, radius, sea_level, morph, key, data)
        self.stats = None       # the refine's stats (None when frozen)
        self.inside = False     # the LOD camera is below the terrain
        self.preview_key = None
        self.preview_data = None  # a new surface.PreviewData, or None when unchanged
        self.preview_serial = None  # unchanged: the mesh-cache emission it stays current at

    def run(self):
        t0 = time.perf_counter()
        try:
            self._run()
        finally:
            self.ms = (time.perf_counter() - t0) * 1000.0

    def _run(self):
        planet, settings = self.planet, self.settings
        if self.refine:
            camera = planet_settings.make_camera(self.params)
            # without hysteresis (renders) the sector set and the order meshes
            # are emitted in depend on this camera only, never on earlier frames
            stats = planet_settings.refine(planet, camera, settings,
                                           hysteresis=not self.for_render,
                                           max_splits=self.max_splits)
            if self.check_size:  # refuse before the mesh (or anything in bpy) is touched
                planet_settings.check_mesh_size(stats, settings["template_level"])
            self.stats = stats
            self.inside = planet_settings.camera_inside(planet, self.params["matrix_world"])
        if self.preview is None:
            return
        # the sectors in view (without morphing, which follows the eye) are
        # kept from refresh to refresh: a view that moves without a change
        # of what it sees keeps its preview, and one that changes some
        # sectors replaces those.  (Drawing every leaf instead, for turns
        # without a refresh, doubled the vertices to emit:
        # bench_viewport_detail.py)
        origin, radius, sea_level, morph, old_key, old_data = self.preview
        level = settings["template_level"]
        ids = numpy.frombuffer(planet.sector_ids(visible_only=True), numpy.uint64)
        self.preview_key = (planet, level, origin, radius, sea_level, morph)
        if morph:  # the morph moves every vertex with the eye
            visible = planet.mesh(template_level=level, morph=True)
            self.preview_data = surface.preview_data(visible, origin, radius, sea_level)
        elif (self.preview_key == old_key and old_data is not None and
              old_data.serial == planet.mesh_cache_info["emissions"]):
            # the planet's last mesh was this preview's: only what changed
            # since (new sectors, corner normals of another band) is
            # emitted, and replaced in a copy of the preview
            changed = planet.mesh(template_level=level, changed_only=True)
            serial = planet.mesh_cache_info["emissions"]
            if changed.sector_count or len(ids) != old_data.sectors:
                self.preview_data = surface.preview_update(old_data, changed, ids, origin,
                                                           radius, sea_level)
                self.preview_data.serial = serial
            else:  # (applied on the main thread: the viewport may be drawing it)
                self.preview_serial = serial
        else:
            visible = planet.mesh(template_level=level)
            self.preview_data = surface.preview_data(visible, origin, radius, sea_level)
            self.preview_data.serial = planet.mesh_cache_info["emissions"]


def _work_for(obj, st, planet, settings, params, for_render, check_size, preview,
              max_splits=0):
    s = obj.planet_lod
    frozen = s.freeze_lod and st.frozen_camera is not None and not for_render
    request = None
    if preview:
        sea_level = s.sea_level if s.use_sea_level else None
        request = (anchor(obj), s.radius, sea_level, s.morph, st.preview_key, st.preview)
    return SurfaceWork(planet, settings, params, refine=not frozen, for_render=for_render,
                       check_size=check_size, preview=request, max_splits=max_splits)


def _apply(st, work):
    """The work's results into the planet's state (main thread)."""
    if work.stats is not None:
        st.stats = work.stats
        if work.for_render:
            st.render_warning = (INSIDE_RENDER if work.inside else "")
        else:
            st.frozen_camera = work.params
            st.warning = (INSIDE_VIEW if work.inside else "")
    if work.preview_key is not None:
        if work.preview_data is not None:
            st.preview_key, st.preview = work.preview_key, work.preview_data
            st.gpu_version += 1
        elif work.preview_serial is not None:
            st.preview.serial = work.preview_serial
        st.stats["preview_vertices"] = st.preview.vertex_count


def _finish(obj, scene, st, params, build_mesh):
    if st.material_dirty or build_mesh:
        materials.ensure(obj)
        st.material_dirty = False
    atmosphere.update(obj, scene, params["matrix_world"])  # sky and haze from this camera
    st.geometry_dirty = False
    st.error = ""


class SurfaceJob(threading.Thread):
    """The viewport's refresh of one planet drawn by the GPU preview, run off
    Blender's main thread: a refresh emits its new sectors' detail, which
    would stall the UI (a jump to a new place: 100-200 ms near the ground,
    spread by the progressive refinement over refreshes of ~12 ms).  The job
    holds the refresh lock while it works, so no render refines that planet
    in between; the timer applies its result when it has finished.  Not a
    daemon: the interpreter waits for it at exit instead of freeing the planet
    under it."""

    def __init__(self, name, serial, work, params):
        super().__init__(name="planet_lod surface " + name)
        self.serial, self.work, self.params = serial, work, params
        self.error = None

    def run(self):
        try:
            with _lock:
                self.work.run()
        except BaseException as exc:  # noqa: BLE001 -- the timer reports or re-raises it
            self.error = exc


def _start_job(obj, st, params):
    settings = obj.planet_lod.as_dict()
    planet = planet_settings.build_planet(settings)
    # progressive: a jump to a new place fills in over a few bounded refreshes
    key = (settings["template_level"], settings["budget"])
    if st.progressive is None or st.progressive.key != key:
        st.progressive = planet_settings.ProgressiveSplits(*key)
    work = _work_for(obj, st, planet, settings, params, for_render=False, check_size=True,
                     preview=True, max_splits=st.progressive.splits)
    st.serial += 1
    st.job = SurfaceJob(obj.name_full, st.serial, work, params)
    st.dirty = False  # a change while the job runs marks the planet dirty again
    st.job.start()


def _finished_jobs(scene):
    """Applies the results of finished viewport jobs; True while one still runs."""
    running = False
    objects = {obj.name_full: obj for obj in planet_objects(scene)}
    for name, st in list(RUNTIME.items()):
        job = st.job
        if job is None:
            continue
        if job.is_alive():
            running = True
            continue
        st.job = None
        obj = objects.get(name)
        if obj is None:
            continue  # the planet went away meanwhile
        if job.serial != st.serial:  # refreshed since (an operator, a render)
            st.dirty = True
            continue
        if job.error is not None:
            if not isinstance(job.error, core.REPORTED_ERRORS):
                raise job.error
            st.error = str(job.error)
            continue
        _apply(st, job.work)
        _finish(obj, scene, st, job.params, build_mesh=False)
        st.pending = bool(job.work.stats and job.work.stats.get("pending"))
        if st.pending:  # the progressive refinement carries on at the next tick
            st.dirty = True
            if st.progressive is not None:
                st.progressive.measured(job.work.stats, job.work.ms)
        _redraw_views()
    return running


def wait_for_jobs():
    """Waits for the viewport jobs in flight (their results are dropped)."""
    for st in list(RUNTIME.values()):
        job = st.job
        if job is not None:
            job.join()
            st.job = None


def mesh_digest(mesh):
    h = hashlib.sha1()
    for part in (mesh.positions, mesh.triangles, mesh.sector_level):
        h.update(bytes(memoryview(part).cast("B")))
    h.update(repr(tuple(mesh.origin)).encode())
    return h.hexdigest()[:16]


def write_mesh(obj, mesh):
    """Replaces obj's mesh geometry from planetlod buffers via foreach_set.  The
    topology is kept (only coordinates and attributes rewritten) when the vertex
    and triangle counts did not change: emission uses one template, so equal
    counts mean equal triangle lists.

    Vertices are written relative to the anchor (floating origin), below-sea
    ground lifted to the sea surface, with the per-vertex attributes the
    materials shade with (planetlod/surface.py), among them the core's normals
    (`planet_normal`: both sides of a sector border get the same normal).
    The normals go in as an attribute, not as custom split normals: those
    cost a Python sequence per vertex and a split-normal evaluation per
    update, seconds for a quarter of a million triangles; Blender's own
    face-averaged normals stay for everything but the planet's shading."""
    me = obj.data
    nv, nt = mesh.vertex_count, mesh.triangle_count
    if len(me.vertices) != nv or len(me.polygons) != nt or me.has_custom_normals:
        me.clear_geometry()  # (custom normals of an older file go with it)
        me.vertices.add(nv)
        compat.set_triangle_topology(me, mesh.triangles, nt)
        me.polygons.foreach_set("use_smooth", array("i", [1]) * nt)
    s = obj.planet_lod
    sea_level = s.sea_level if s.use_sea_level else None
    data = surface.vertex_data(mesh, anchor(obj), s.radius, sea_level)
    me.vertices.foreach_set("co", data.positions)
    _set_attribute(me, surface.NORMAL_ATTRIBUTE, 'FLOAT_VECTOR', 'POINT', "vector", data.normals)
    _set_attribute(me, "planet_uv", 'FLOAT2', 'POINT', "vector", mesh.uv)
    _set_attribute(me, "sector_level", 'INT', 'FACE', "value", mesh.sector_level)
    for name, values in data.attributes.items():
        _set_attribute(me, name, 'FLOAT', 'POINT', "value", values)
    me.update()



def _set_attribute(me, name, data_type, domain, field, values):
    attr = me.attributes.get(name)
    if attr is not None and (attr.data_type != data_type or attr.domain != domain):
        me.attributes.remove(attr)
        attr = None
    if attr is None:
        attr = me.attributes.new(name, data_type, domain)
    attr.data.foreach_set(field, values)


def refresh_for_render(scene, depsgraph=None, clip=True):
    """Every planet in `scene`: refine for the render camera at render resolution and
    rebuild its mesh.  Returns {name: stats}; errors are printed and kept in state."""
    results = {}
    if clip is True:  # also when the LOD is cached (a setting was toggled)
        clip = apply_camera_clip(scene, depsgraph)
    for obj in planet_objects(scene):
        try:
            params = _with_clip(lod_camera_params(obj, scene, for_render=True,
                                                  depsgraph=depsgraph), clip)
            st = state(obj)
            key = _render_key(obj, params)
            if key is not None and key == st.render_key and not st.dirty:
                results[obj.name] = st.stats  # frame_set then render: refined already
                continue
            results[obj.name] = refresh(obj, scene, params=params, build_mesh=True,
                                        for_render=True)
            st.render_key = key
        except core.REPORTED_ERRORS as exc:
            state(obj).error = str(exc)
            print(f"planet_lod: {obj.name}: {exc}")
    return results


# ---- objects placed by longitude / latitude ------------------------------------

def _geo_objects(scene):
    return [o for o in scene.objects if o.planet_lod_geo.enabled and o.planet_lod_geo.planet
            and o.planet_lod_geo.planet.planet_lod.enabled]


def place_geo_objects(scene, depsgraph=None):
    """Places every geo-placed object of `scene` (floating-origin ones first, so
    the others land relative to the moved anchor).  Property values come from
    the evaluated object: during `-a` renders animation is evaluated there."""
    objects = sorted(_geo_objects(scene), key=lambda o: not o.planet_lod_geo.floating_origin)
    for obj in objects:
        place_geo_object(obj, scene, depsgraph)


def place_geo_object(obj, scene=None, depsgraph=None):
    geo = _evaluated(obj, depsgraph).planet_lod_geo
    planet_obj = obj.planet_lod_geo.planet
    if not geo.enabled or planet_obj is None or not planet_obj.planet_lod.enabled:
        return
    s = planet_obj.planet_lod
    base = None
    try:
        if geo.altitude_reference == 'GROUND':
            planet = planet_settings.build_planet(s.as_dict())
            sea = s.sea_level if s.use_sea_level else None
            base = ((lambda d: max(planet.height(*d), sea)) if sea is not None
                    else (lambda d: planet.height(*d)))
        elif geo.altitude_reference == 'SEA' and s.use_sea_level:
            base = (lambda d: s.sea_level)
    except core.REPORTED_ERRORS as exc:
        state(planet_obj).error = str(exc)
        return
    pose = flyby.geo_pose(s.radius, geo.longitude, geo.latitude, east=geo.east,
                         north=geo.north, altitude=geo.altitude, heading=geo.heading,
                         pitch=geo.pitch, roll=geo.roll, base_height=base)
    placement.place_in_planet_space(obj, planet_obj, pose, floating_origin=geo.floating_origin)
    if geo.floating_origin:
        for other in _geo_objects(scene) if scene is not None else ():
            if other is not obj and other.planet_lod_geo.planet == planet_obj \
                    and not other.planet_lod_geo.floating_origin:
                place_geo_object(other, None, depsgraph)


# ---- live update (viewport) -------------------------------------------------------

def _render_key(obj, params):
    if params is None:
        return None
    return (repr(params), repr(sorted(obj.planet_lod.as_dict().items())), obj.planet_lod.morph,
            obj.planet_lod.show_levels, len(obj.data.polygons), tuple(obj.matrix_world.col[3]),
            anchor(obj))


def _signature(obj, scene):
    params = lod_camera_params(obj, scene)
    if params is None:
        return None, None
    m = params["matrix_world"]
    sig = (tuple(round(v, 6) for row in m for v in row), params["lens"],
           params["resolution_x"], params["resolution_y"], params["type"])
    return sig, params


def tick():
    """bpy.app.timers callback: refreshes planets whose view changed, at most every
    REFRESH_INTERVAL_S each, and fits the clip ranges to the horizon."""
    if _in_refresh() or _render_running() or core.native is None:
        return TICK_S
    if not _lock.acquire(blocking=False):  # a render thread is refreshing: retry
        return TICK_S
    try:
        _tick_locked()
    finally:
        _lock.release()
    # a job in flight or a progressive refinement to carry on: come back soon
    busy = any(st.job is not None or (st.dirty and st.pending) for st in RUNTIME.values())
    return BUSY_TICK_S if busy else TICK_S


def _tick_locked():
    context = bpy.context
    scene = getattr(context, "scene", None)
    if scene is None:
        return
    now = time.monotonic()
    forget_removed()
    if _finished_jobs(scene):
        return  # the planet is busy in a job: nothing here may wait for it
    try:  # before the refresh: the viewport's frustum ends at its clip end
        fit_view_clips(scene)
        apply_camera_clip(scene)
    except (ReferenceError, AttributeError):
        pass
    for obj in planet_objects(scene):
        s = obj.planet_lod
        if not s.live_update:
            continue
        st = state(obj)
        try:
            sig, params = _signature(obj, scene)
        except (ReferenceError, AttributeError):
            continue
        if sig is None:  # the camera went away (deleted before the refresh ran)
            if st.dirty:
                st.error = NO_CAMERA
            continue
        if sig != st.signature:
            st.signature, st.changed_at, st.dirty = sig, now, True
        # a refresh at most every REFRESH_INTERVAL_S, also while the view keeps
        # moving (navigation), so the detail follows instead of popping at the
        # end; a progressive refinement cut short carries on at once
        if not st.dirty or (not st.pending and now - st.refreshed_at < REFRESH_INTERVAL_S):
            continue
        st.refreshed_at = now
        try:
            if s.gpu_preview and not bpy.app.background:  # the preview is drawn
                _start_job(obj, st, params)
            else:
                refresh(obj, scene, params=params, build_mesh=not s.gpu_preview)
                _redraw_views()
        except core.REPORTED_ERRORS as exc:
            st.error, st.dirty = str(exc), False
            _redraw_views()
        break  # one planet per tick keeps the UI responsive


def _redraw_views():
    wm = bpy.context.window_manager
    for window in wm.windows if wm else ():
        for area in window.screen.areas:
            if area.type == 'VIEW_3D':
                area.tag_redraw()


# ---- handlers ------------------------------------------------------------------

@persistent
def on_frame_change_pre(scene, depsgraph=None):
    placement.place_flyby_cameras(scene)
    # the clip range before the frame is evaluated: set after (frame_change_post),
    # an animation render (-a) would render this frame with the previous one's
    if not _in_refresh() and core.native is not None:
        fit_render_clip(scene, keyframed_only=True)


def fit_render_clip(scene, keyframed_only=False):
    """Camera Clip to Horizon for the current frame, from the render camera's
    keyframes where it has them (the original object still holds another
    frame's transform during animation renders).  Returns the range or None."""
    cam = render_camera(scene)
    if cam is None:
        return None
    matrix = keyframed_matrix(cam, scene.frame_current + scene.frame_subframe)
    if matrix is None and keyframed_only:
        return None
    return apply_camera_clip(scene, cam_matrix=matrix)


@persistent
def on_frame_change_post(scene, depsgraph=None):
    if not _in_refresh() and core.native is not None:
        place_geo_objects(scene, depsgraph)
        refresh_for_render(scene, depsgraph)


@persistent
def on_render_pre(scene, depsgraph=None):
    """render_init / render_pre: refine for the render camera at render resolution.
    F12 runs render_pre in the render job's thread, where bpy data must not be
    written; there the main-thread render_init call has already done the work."""
    if _in_refresh() or core.native is None:
        return
    if threading.current_thread() is not threading.main_thread():
        return
    refresh_for_render(scene, clip=fit_render_clip(scene))


def _render_running():
    """A render is in progress.  The counter is reset when no render job runs:
    a render that failed between render_init and complete/cancel must not stop
    the viewport refresh for good (the timer only runs in the UI, where renders
    that can overlap it are jobs)."""
    global _renders
    if _renders and not render_job_running():
        _renders = 0
    return _renders > 0


def render_job_running():
    return bpy.app.is_job_running('RENDER')


@persistent
def on_render_started(*_args):
    global _renders
    _renders += 1


@persistent
def on_render_finished(*_args):
    global _renders
    _renders = max(0, _renders - 1)


@persistent
def on_load_post(*_args):
    RUNTIME.clear()
    planet_settings.forget_planets()
    scene = bpy.context.scene
    if scene is None or core.native is None:
        return
    compat.update_after_load()
    for obj in planet_objects(scene):  # rebuild geometry for the saved camera
        try:
            refresh(obj, scene, build_mesh=True, for_render=True)
        except core.REPORTED_ERRORS as exc:
            state(obj).error = str(exc)
            print(f"planet_lod: {obj.name}: {exc}")


@persistent
def on_undo(*_args):
    for st in RUNTIME.values():
        st.dirty = True


@persistent
def on_depsgraph_update(scene, depsgraph=None):
    if depsgraph is None or _in_refresh():
        return
    for update in depsgraph.updates:
        if isinstance(update.id, bpy.types.Object) and update.is_updated_transform:
            for obj in planet_objects(scene):
                if update.id.original in (obj, camera_object(obj, scene),
                                          render_camera(scene)):
                    state(obj).dirty = True


HANDLERS = (
    (bpy.app.handlers.frame_change_pre, on_frame_change_pre),
    (bpy.app.handlers.frame_change_post, on_frame_change_post),
    (bpy.app.handlers.render_init, on_render_started),
    (bpy.app.handlers.render_init, on_render_pre),
    (bpy.app.handlers.render_complete, on_render_finished),
    (bpy.app.handlers.render_cancel, on_render_finished),
    (bpy.app.handlers.render_pre, on_render_pre),
    (bpy.app.handlers.load_post, on_load_post),
    (bpy.app.handlers.undo_post, on_undo),
    (bpy.app.handlers.redo_post, on_undo),
    (bpy.app.handlers.depsgraph_update_post, on_depsgraph_update),
)


def add_handlers():
    for handler_list, fn in HANDLERS:
        if fn not in handler_list:
            handler_list.append(fn)
    if not bpy.app.background and not bpy.app.timers.is_registered(tick):
        bpy.app.timers.register(tick, first_interval=TICK_S, persistent=True)


def remove_handlers():
    if bpy.app.timers.is_registered(tick):
        bpy.app.timers.unregister(tick)
    wait_for_jobs()
    for handler_list, fn in HANDLERS:
        while fn in handler_list:
            handler_list.remove(fn)
    RUNTIME.clear()
