"""Per-planet runtime state, and the floating origin (the anchor).

RUNTIME holds one PlanetState per planet object, keyed by the object's name
(never a bpy reference, so undo/redo and file loads cannot leave dangling
pointers).  Refreshes (refresh.py) create and update it; panels and draw
callbacks read it through existing_state(), which never creates one.
"""
import math
import time

import bpy

RUNTIME = {}


class PlanetState:
    def __init__(self):
        self.dirty = True
        self.geometry_dirty = True
        self.material_dirty = True
        self.signature = None
        self.changed_at = 0.0
        self.stats = {}
        self.error = ""
        self.warning = ""          # the viewport's camera is inside the planet
        self.render_warning = ""   # the render camera is inside the planet
        self.refreshed_at = time.monotonic()  # of the last viewport refresh
        self.preview = None        # surface.PreviewData the GPU preview draws
        self.preview_key = None    # what it was emitted from
        self.gpu_version = 0       # bumped when the preview changes
        self.frozen_camera = None  # (matrix_world planet space, params) while frozen
        self.mesh_hash = ""
        self.render_key = None     # camera + settings of the last render refresh
        self.job = None            # refresh.SurfaceJob: the viewport refresh in flight
        self.serial = 0            # counts refreshes (a job's result is applied if last)
        self.progressive = None    # planetlod.refresh.ProgressiveSplits of the viewport jobs
        self.pending = False       # the last job's split limit cut its refinement short

    def settled(self):
        """Refreshed for the current view, with no refresh in flight."""
        return not self.dirty and self.job is None


def state(obj):
    """The planet's runtime state, created on first use."""
    st = RUNTIME.get(obj.name_full)
    if st is None:
        st = RUNTIME[obj.name_full] = PlanetState()
    return st


def mark_dirty(obj, geometry=False, material=False):
    if obj is None:
        return
    st = state(obj)
    st.dirty = True
    st.geometry_dirty |= geometry
    st.material_dirty |= material


def existing_state(obj):
    """The planet's runtime state, or None before its first refresh."""
    return RUNTIME.get(obj.name_full)


def forget_removed():
    """Drops the runtime state of planets deleted since (a scheduled refresh of a
    deleted planet then finds nothing to do)."""
    alive = {obj.name_full for obj in bpy.data.objects}
    for name in [n for n in RUNTIME if n not in alive]:
        del RUNTIME[name]


def planet_objects(scene):
    return [o for o in scene.objects if o.type == 'MESH' and o.planet_lod.enabled]


# ---- floating origin ------------------------------------------------------------
# The planet object's local space is planet space shifted by the *anchor*, a
# float64 planet-space point kept as an ID property (ID properties are double;
# Blender's transforms, vertices and float properties are float32).  The
# add-on moves the anchor to the render camera (flyby, geo-placed cameras), so
# the camera sits at the world origin and the surface around it is written
# with small float32 coordinates: millimetres stay millimetres in the space
# Cycles and EEVEE render.  Without an anchor (0, 0, 0) local space is planet
# space.

ANCHOR_KEY = "planet_lod_anchor"


def anchor(obj):
    """The planet-space point at the planet object's local origin (float64)."""
    value = obj.get(ANCHOR_KEY)
    try:
        point = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        return (0.0, 0.0, 0.0)
    if len(point) != 3 or not all(math.isfinite(v) for v in point):
        return (0.0, 0.0, 0.0)
    return point


# Called as listener(obj, old, new) when an anchor moves (the views follow it).
ANCHOR_LISTENERS = []


def set_anchor(obj, point):
    """Moves the anchor; True when it changed (the mesh must then be rewritten)."""
    point = [float(v) for v in point]
    old = anchor(obj)
    if list(old) == point:
        return False
    obj[ANCHOR_KEY] = point
    for listener in ANCHOR_LISTENERS:
        listener(obj, old, point)
    return True


def to_planet_space(obj, matrix_world):
    """Row-major 4x4 (lists of float64) of a world matrix in planet space: the
    float32 product stays small near the anchor, the anchor is added in float64."""
    local = obj.matrix_world.inverted_safe() @ matrix_world
    rows = [list(row) for row in local]
    for i, a in enumerate(anchor(obj)):
        rows[i][3] += a
    return rows


DETAIL_PERIOD = 50000.0  # metres: detail texture coordinates wrap here (4 mm float32 steps)


def detail_offset(anchor):
    """The anchor modulo DETAIL_PERIOD: object coordinates plus this are planet
    coordinates shifted by a whole number of periods, small and precise near
    the camera, so the ground's detail texture stays put as the anchor moves."""
    return tuple(a - DETAIL_PERIOD * math.floor(a / DETAIL_PERIOD) for a in anchor)
