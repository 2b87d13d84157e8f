"""Refreshing planets: refine for the LOD camera, write the mesh, apply the
GPU preview's surface; the viewport's refresh jobs; the render refresh.

The work in the core (refine, the preview's surface) is planetlod.refresh,
free of bpy; here it is run and its results applied to Blender.

Threads: the viewport refresh (handlers.tick) and most handlers run on
Blender's main thread, but an animation render started from the UI (Ctrl F12)
calls the frame_change handlers from the render job's thread.  So:
  * one refresh runs at a time, process-wide: refresh() holds `LOCK` (an RLock)
    from refine to the written mesh, so a render thread never emits the LOD a
    viewport refine made between its refine and its mesh() call; render-side
    callers wait for the lock, the timer only tries it and retries next tick;
  * the timer does no refresh while a render is in progress (handlers.py
    counts them from render_init to render_complete / render_cancel), so the
    viewport never rewrites a mesh the render is reading;
  * `in_refresh()` marks *this thread* as inside refresh(), to ignore handlers
    fired by our own mesh writes (re-entry), never another thread's refresh;
  * the native Planet has its own lock as well (planetlod), so direct calls
    from other threads cannot corrupt its refiner either;
  * planet_add turns on Render > Lock Interface, which Blender requires for
    handlers that write data from the render thread;
  * with the GPU preview the timer runs a planet's refresh (refine and the
    preview's surface, no bpy) in a SurfaceJob thread that holds `LOCK`, and
    applies its result at a later tick; while a job runs the timer touches no
    planet (a native call would wait for the job), and a refresh made since the
    job started (an operator, a render) makes its result stale: dropped, the
    planet refreshes again.
"""
import contextlib
import threading
import time
from array import array

import bpy

from . import atmosphere, cameras, compat, core, materials, runtime
from .core import planets as planet_settings
from .core import refresh as core_refresh
from .core import surface

LOCK = threading.RLock()    # one refresh at a time, across threads
_local = threading.local()  # .busy: this thread is inside refresh()


def in_refresh():
    """This thread is inside refresh() (handlers fired by its own writes)."""
    return getattr(_local, "busy", False)


def check_settings(obj):
    """Checks what can be checked at once when a setting changes (a height map
    or inset path that is missing, a folder or empty), so the panel shows the
    reason right away; the refresh reports everything else."""
    st = runtime.state(obj)
    settings = obj.planet_lod.as_dict()
    try:
        planet_settings.check_heightmap(settings.get("heightmap"))
        planet_settings.check_insets(planet_settings.inset_paths(settings))
    except (core.FileError, core.ImageError) as exc:
        st.error = str(exc)
    else:
        if st.error.startswith(("height map", "inset", "not an image file")):
            st.error = ""



NO_CAMERA = "no LOD camera: add a camera to the scene or use the viewport"
INSIDE_VIEW = ("the view is inside the planet (below the terrain): zoom out or press "
               "Home to see it")
INSIDE_RENDER = ("the render camera is inside the planet (below the terrain): move it out "
                 "to render the planet")


@contextlib.contextmanager
def refreshing():
    """Holds LOCK with this thread marked as inside a refresh (its own writes
    to Blender then fire no refresh of their own)."""
    with LOCK:
        was_busy, _local.busy = in_refresh(), True
        try:
            yield
        finally:
            _local.busy = was_busy


def refresh(obj, scene, params=None, build_mesh=False, for_render=False):
    """Refines `obj` for its LOD camera; optionally rebuilds its mesh.  Raises
    core.REPORTED_ERRORS on bad input (callers report them)."""
    with refreshing():
        step = Refresh(obj, scene, params, build_mesh, for_render)
        step.compute()
        return step.apply(obj, scene)


class Refresh:
    """One refresh of a planet in three steps: prepared on the main thread
    (the planet, the LOD camera, the settings read from Blender), computed in
    the core (no bpy: the refine, the mesh and its vertex data, so it may run
    on a worker thread holding LOCK), applied on the main thread (the results
    into the planet's state and its Blender mesh)."""

    def __init__(self, obj, scene, params=None, build_mesh=False, for_render=False):
        st = runtime.state(obj)
        self.settings = settings = obj.planet_lod.as_dict()
        self.planet = planet = planet_settings.build_planet(settings)
        if params is None:
            # the render camera's frustum ends at its clip end: fit that first
            clip = cameras.apply_camera_clip(scene) if for_render else None
            params = cameras.with_clip(
                cameras.lod_camera_params(obj, scene, for_render=for_render), clip)
        if params is None:
            raise core.PlanetLODError(NO_CAMERA)
        self.params, self.build_mesh, self.for_render = params, build_mesh, for_render
        self.morph = obj.planet_lod.morph
        s = obj.planet_lod
        self.surface_args = (runtime.anchor(obj), s.radius,
                             s.sea_level if s.use_sea_level else None)
        # the preview draws the surface the render gets (heights with the detail,
        # morphing, the sea, the core's normals, relative to the anchor), of the
        # viewport's LOD only: a render's never leaks in
        preview = s.gpu_preview and not bpy.app.background and not for_render
        st.serial += 1  # a viewport job started before this refresh is out of date
        self.serial = st.serial
        self.work = _work_for(obj, st, planet, settings, params, for_render,
                              check_size=build_mesh or preview, preview=preview)
        self.mesh = self.vertex_data = None
        self.mesh_ms = 0.0

    STEPS = ("refining", "building the mesh", "shading data")

    def compute(self, cancelled=lambda: False, step=lambda index: None):
        """The core's part (no bpy); returns False when `cancelled()` stopped it
        between steps; `step(i)` is told of each step started (STEPS)."""
        step(0)
        self.work.run()
        if not self.build_mesh:
            return True
        if cancelled():
            return False
        step(1)
        t0 = time.perf_counter()
        self.mesh = self.planet.mesh(template_level=self.settings["template_level"],
                                     morph=self.morph)
        if cancelled():
            return False
        step(2)
        self.vertex_data = surface.vertex_data(self.mesh, *self.surface_args)
        self.mesh_ms = (time.perf_counter() - t0) * 1000.0
        return not cancelled()

    def apply(self, obj, scene):
        """The results into `obj` (main thread); returns the planet's stats."""
        st = runtime.state(obj)
        _apply(st, self.work)
        st.pending = False  # refined in full
        if self.build_mesh:
            t0 = time.perf_counter()
            mesh = self.mesh
            st.stats["vertices"] = mesh.vertex_count
            st.stats["triangles"] = mesh.triangle_count
            write_mesh(obj, mesh, self.vertex_data)
            if not self.for_render:
                st.render_key = None  # the mesh no longer matches the render camera
            ms = self.mesh_ms + (time.perf_counter() - t0) * 1000.0
            st.stats["mesh_ms"] = round(ms, 3)
            st.mesh_hash = core_refresh.mesh_digest(mesh)
            st.stats["mesh_hash"] = st.mesh_hash
        _finish(obj, scene, st, self.params, self.build_mesh)
        st.dirty = False
        return st.stats


def _work_for(obj, st, planet, settings, params, for_render, check_size, preview,
              max_splits=0):
    s = obj.planet_lod
    frozen = s.freeze_lod and st.frozen_camera is not None and not for_render
    request = None
    if preview:
        sea_level = s.sea_level if s.use_sea_level else None
        request = (runtime.anchor(obj), s.radius, sea_level, s.morph, st.preview_key, st.preview)
    return core_refresh.SurfaceWork(planet, settings, params, refine=not frozen, for_render=for_render,
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
            with LOCK:
                self.work.run()
        except BaseException as exc:  # noqa: BLE001 -- the timer reports or re-raises it
            self.error = exc


def start_job(obj, st, params):
    """Starts the viewport's refresh of `obj` in a SurfaceJob (GPU preview)."""
    settings = obj.planet_lod.as_dict()
    planet = planet_settings.build_planet(settings)
    # progressive: a jump to a new place fills in over a few bounded refreshes
    key = (settings["template_level"], settings["budget"])
    if st.progressive is None or st.progressive.key != key:
        st.progressive = core_refresh.ProgressiveSplits(*key)
    work = _work_for(obj, st, planet, settings, params, for_render=False, check_size=True,
                     preview=True, max_splits=st.progressive.splits)
    st.serial += 1
    st.job = SurfaceJob(obj.name_full, st.serial, work, params)
    st.dirty = False  # a change while the job runs marks the planet dirty again
    st.job.start()


def finished_jobs(scene):
    """Applies the results of finished viewport jobs; True while one still runs."""
    running = False
    objects = {obj.name_full: obj for obj in runtime.planet_objects(scene)}
    for name, st in list(runtime.RUNTIME.items()):
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
        redraw_views()
    return running


def wait_for_jobs():
    """Waits for the viewport jobs in flight (their results are dropped)."""
    for st in list(runtime.RUNTIME.values()):
        job = st.job
        if job is not None:
            job.join()
            st.job = None


def write_mesh(obj, mesh, data=None):
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
    # (the other LOD methods' patches differ in their triangles at equal counts)
    if (len(me.vertices) != nv or len(me.polygons) != nt or me.has_custom_normals or
            obj.planet_lod.lod_method != 'HRTMR'):
        me.clear_geometry()  # (custom normals of an older file go with it)
        me.vertices.add(nv)
        compat.set_triangle_topology(me, mesh.triangles, nt)
        me.polygons.foreach_set("use_smooth", array("i", [1]) * nt)
    if data is None:
        s = obj.planet_lod
        sea_level = s.sea_level if s.use_sea_level else None
        data = surface.vertex_data(mesh, runtime.anchor(obj), s.radius, sea_level)
    me.vertices.foreach_set("co", data.positions)
    set_attribute(me, surface.NORMAL_ATTRIBUTE, 'FLOAT_VECTOR', 'POINT', "vector", data.normals)
    set_attribute(me, "planet_uv", 'FLOAT2', 'POINT', "vector", mesh.uv)
    set_attribute(me, "sector_level", 'INT', 'FACE', "value", mesh.sector_level)
    for name, values in data.attributes.items():
        set_attribute(me, name, 'FLOAT', 'POINT', "value", values)
    me.update()



def set_attribute(me, name, data_type, domain, field, values):
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
        clip = cameras.apply_camera_clip(scene, depsgraph)
    for obj in runtime.planet_objects(scene):
        try:
            params = cameras.with_clip(cameras.lod_camera_params(
                obj, scene, for_render=True, depsgraph=depsgraph), clip)
            st = runtime.state(obj)
            key = render_key(obj, params)
            if key is not None and key == st.render_key and not st.dirty:
                results[obj.name] = st.stats  # frame_set then render: refined already
                continue
            results[obj.name] = refresh(obj, scene, params=params, build_mesh=True,
                                        for_render=True)
            st.render_key = key
        except core.REPORTED_ERRORS as exc:
            runtime.state(obj).error = str(exc)
            print(f"planet_lod: {obj.name}: {exc}")
    return results



def render_key(obj, params):
    """What a render refresh depends on: the same key, the same mesh."""
    if params is None:
        return None
    return (repr(params), repr(sorted(obj.planet_lod.as_dict().items())), obj.planet_lod.morph,
            obj.planet_lod.show_levels, len(obj.data.polygons), tuple(obj.matrix_world.col[3]),
            runtime.anchor(obj))



def redraw_views():
    wm = bpy.context.window_manager
    for window in wm.windows if wm else ():
        for area in window.screen.areas:
            if area.type == 'VIEW_3D':
                area.tag_redraw()

