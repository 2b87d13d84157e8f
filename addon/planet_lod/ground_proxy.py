"""A coarse real mesh under each previewed planet's ground, for Blender's own
tools that read the viewport's depth buffer (Zoom Border, Auto Depth, Zoom
to Mouse Position, Set 3D Cursor) or cast rays at meshes (Walk's teleport):
the GPU preview feeds neither.

The mesh (planetlod.ground_proxy) is a child object of the planet, drawn
solid at or just below the ground so the preview draws over it; hidden from
renders, not selectable, rebuilt (in a thread) as the view the LOD follows
moves, and removed before a save, so a file holds no trace of it.

The proxy exists only near the ground (below NEAR_GROUND of the radius),
where those tools are used and a depth buffer resolves it; there the
planet object's own viewport geometry (the mesh built
for renders, drawn as its bounding box) is masked out by a viewport-only
Mask modifier: its box would cross the sky.  The modifier goes before a save
as the proxy does."""
import threading

import bpy
from bpy.app.handlers import persistent

from . import compat, core, runtime
from .core import ground_proxy as proxy_geometry
from .core import planets as planet_settings

PROXY_KEY = "planet_lod_ground_of"  # ID property: the planet a proxy stands under
REBUILD_FRACTION = 0.05  # of the altitude: the eye's move that rebuilds the proxy
# of the radius: below this the planet's bounding box is hidden and the proxy
# exists.  Farther out a depth buffer's step grows past the proxy's sink (the
# proxy would show through the preview in dots), and the preview is the planet
# Home and Frame Selected find.
NEAR_GROUND = 0.05
BOX_MASK = "Planet Viewport Box Off"  # the Mask modifier's and its vertex group's name

_built = {}   # proxy name -> (what it was built from, eye, altitude)
_jobs = {}    # planet name -> ProxyJob


def is_proxy(obj):
    return obj is not None and obj.get(PROXY_KEY) is not None


def proxy_of(planet):
    for child in planet.children:
        if child.get(PROXY_KEY) == planet:
            return child
    return None


class ProxyJob(threading.Thread):
    """Samples the ground for a proxy off the main thread (0.1 s near the
    ground).  Not a daemon: the interpreter waits for it at exit instead of
    freeing the planet under it."""

    def __init__(self, planet, radius, eye, anchor, sea_level, key):
        super().__init__(name="planet_lod ground proxy")
        self.args = (planet.surface, radius, eye, anchor, sea_level)
        self.key, self.eye = key, eye
        self.result = self.error = None

    def run(self):
        try:
            surface, radius, eye, anchor, sea_level = self.args
            self.result = proxy_geometry.proxy_mesh(surface, radius, eye, anchor, sea_level)
        except BaseException as exc:  # noqa: BLE001 -- reported on the main thread
            self.error = exc


def _wanted(obj):
    s = obj.planet_lod
    return s.gpu_preview and not bpy.app.background and obj.visible_get()


def _new_proxy(planet):
    mesh = bpy.data.meshes.new(planet.name + " Viewport Ground")
    proxy = bpy.data.objects.new(mesh.name, mesh)
    for collection in planet.users_collection:
        collection.objects.link(proxy)
    proxy.parent = planet
    proxy.matrix_parent_inverse.identity()
    proxy[PROXY_KEY] = planet
    proxy.hide_render = True
    proxy.hide_select = True
    proxy.display_type = 'SOLID'
    return proxy


def _write(proxy, positions, triangles):
    if len(triangles) == 0 or triangles.min() < 0 or triangles.max() >= len(positions):
        return  # (Blender would crash on such indices)
    me = proxy.data
    if len(me.vertices) != len(positions) or len(me.polygons) != len(triangles):
        me.clear_geometry()
        me.vertices.add(len(positions))
        compat.set_triangle_topology(me, triangles.reshape(-1), len(triangles))
    me.vertices.foreach_set("co", positions.reshape(-1))
    me.update()


def remove(proxy):
    mesh = proxy.data
    _built.pop(proxy.name_full, None)
    bpy.data.objects.remove(proxy)
    if mesh is not None and mesh.users == 0:
        bpy.data.meshes.remove(mesh)


def remove_all():
    for obj in [o for o in bpy.data.objects if is_proxy(o)]:
        remove(obj)
    _built.clear()
    for obj in bpy.data.objects:
        show_box(obj, True)


def show_box(obj, show):
    """Shows or hides (near the ground) the planet's bounding box in the
    viewport: a Mask modifier, on in viewports only, keeping the vertices of
    an empty vertex group (none: the mesh has no weights) empties its
    viewport geometry; renders are unchanged."""
    mod = obj.modifiers.get(BOX_MASK) if obj.type == 'MESH' else None
    if show:
        if mod is not None:
            obj.modifiers.remove(mod)
            group = obj.vertex_groups.get(BOX_MASK)
            if group is not None:
                obj.vertex_groups.remove(group)
        return
    if mod is None:
        if obj.vertex_groups.get(BOX_MASK) is None:
            obj.vertex_groups.new(name=BOX_MASK)
        mod = obj.modifiers.new(BOX_MASK, 'MASK')
        mod.mode = 'VERTEX_GROUP'
        mod.vertex_group = BOX_MASK
        mod.show_render = False
        mod.show_in_editmode = False


def update(scene):
    """Timer step (main thread, no render running): applies finished proxy
    jobs, starts one where the view the LOD follows moved far enough, removes
    proxies of planets gone, hidden or not previewed."""
    planets = runtime.planet_objects(scene)
    for obj in [o for o in scene.objects if is_proxy(o)]:
        owner = obj.get(PROXY_KEY)
        if not isinstance(owner, bpy.types.Object) or owner not in planets \
                or not _wanted(owner) or obj.parent != owner:
            remove(obj)
    for obj in planets:
        st = runtime.existing_state(obj)
        if not _wanted(obj) or st is None or not st.frozen_camera:
            show_box(obj, True)
            continue
        near = _altitude(obj, st) <= NEAR_GROUND * obj.planet_lod.radius
        show_box(obj, not near)
        if not near:
            proxy = proxy_of(obj)
            if proxy is not None:
                remove(proxy)
            continue
        job = _jobs.get(obj.name_full)
        if job is not None:
            if job.is_alive():
                continue
            del _jobs[obj.name_full]
            if job.error is not None:  # the preview reports the planet's errors
                if not isinstance(job.error, core.REPORTED_ERRORS):
                    print(f"planet_lod: {obj.name}: viewport ground: {job.error!r}")
                continue
            proxy = proxy_of(obj) or _new_proxy(obj)
            _write(proxy, *job.result)
            _built[proxy.name_full] = job.key
            continue
        if st.preview is None:
            continue
        key = _key_if_stale(obj, st)
        if key is not None:
            _start(obj, key)


def _altitude(obj, st):
    """Height of the LOD camera above the planet's radius (m)."""
    m = st.frozen_camera["matrix_world"]
    return sum(float(m[i][3]) ** 2 for i in range(3)) ** 0.5 - obj.planet_lod.radius


def _key_if_stale(obj, st):
    """What the planet's proxy would be built from now, or None while the one
    it has is close enough."""
    s = obj.planet_lod
    m = st.frozen_camera["matrix_world"]
    eye = tuple(float(m[i][3]) for i in range(3))
    base = (planet_settings.planet_key(s.as_dict()), runtime.anchor(obj), s.radius,
            s.sea_level if s.use_sea_level else None)
    proxy = proxy_of(obj)
    built = _built.get(proxy.name_full) if proxy is not None else None
    if built is not None and built[0] == base:
        old_eye, altitude = built[1], built[2]
        moved = sum((a - b) ** 2 for a, b in zip(eye, old_eye)) ** 0.5
        if moved < REBUILD_FRACTION * altitude:
            return None
    altitude = max(sum(c * c for c in eye) ** 0.5 - s.radius, 1.0)
    return (base, eye, altitude)


def _start(obj, key):
    s = obj.planet_lod
    try:
        planet = planet_settings.build_planet(s.as_dict())
    except core.REPORTED_ERRORS:
        return
    base, eye, _ = key
    job = ProxyJob(planet, s.radius, eye, base[1], base[3], key)
    _jobs[obj.name_full] = job
    job.start()


# ---- a file holds no proxy --------------------------------------------------------

@persistent
def on_save_pre(*_args):
    remove_all()


@persistent
def on_load_post(*_args):
    _jobs.clear()
    remove_all()  # an autosave or an older session's file


@persistent
def on_undo(*_args):
    _built.clear()  # the proxies came back as they were: rebuilt


HANDLERS = ((bpy.app.handlers.save_pre, on_save_pre),
            (bpy.app.handlers.load_post, on_load_post),
            (bpy.app.handlers.undo_post, on_undo),
            (bpy.app.handlers.redo_post, on_undo))


def register():
    for handler_list, fn in HANDLERS:
        if fn not in handler_list:
            handler_list.append(fn)


def unregister():
    for handler_list, fn in HANDLERS:
        while fn in handler_list:
            handler_list.remove(fn)
    for job in list(_jobs.values()):
        job.join()
    _jobs.clear()
    if bpy.data.objects is not None:
        try:
            remove_all()
        except (AttributeError, RuntimeError):
            pass
