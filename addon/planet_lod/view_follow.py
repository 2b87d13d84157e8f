"""The 3D views kept on the planet: the altitude above the ground drawn in
the view, a zoom pivot kept on the ground (the wheel zooms towards the ground
in shrinking steps, never through it), the view's up levelled to the planet's
local up near the ground, and every view carried along when the floating
origin moves, so the planet does not jump on screen."""
import threading

import bpy
from mathutils import Vector

from . import core, handlers, planet_fly, runtime
from .navigation import NEAR_GROUND, altitude, eye_of, ground_hit, planet_centre

# ---- keeping the views on the planet ----------------------------------------------

# Below this height (m) the eye is lifted back above the ground: a Walk
# teleport lands on the depth proxy (ground_proxy.py), a little below it.
MIN_CLEARANCE = 2.0
# Deeper than this fraction of the radius under the ground the eye is left
# where it is (it was put inside on purpose).
LIFT_DEPTH = 0.01


def _views():
    wm = bpy.context.window_manager
    for window in wm.windows if wm else ():
        for area in window.screen.areas:
            if area.type == 'VIEW_3D':
                r3d = area.spaces.active.region_3d
                if r3d is not None:
                    yield area, r3d


def keep_pivot_on_ground(obj, area, r3d):
    """Keeps a perspective view out of the ground: an eye just below it is
    lifted above it, and a pivot (the point Blender's wheel zooms towards and
    its orbit turns around) under the ground is moved onto the ground ahead,
    the eye unchanged, so each wheel notch covers a fixed share of the
    distance left to the ground and never passes through it.  Near the
    ground, levels the view's horizon to the planet's local up.  True when
    the view changed."""
    if r3d.view_perspective != 'PERSP' or not area.spaces.active.planet_lod_follow_ground:
        return False
    centre = planet_centre(obj)
    scale = max(obj.matrix_world.to_scale())
    radius = obj.planet_lod.radius * scale
    eye = eye_of(r3d)
    height = altitude(obj, eye) * scale
    changed = False
    if -LIFT_DEPTH * radius < height < MIN_CLEARANCE:
        lift = _way_out(obj, eye, r3d.view_rotation @ Vector((0.0, 0.0, -1.0)),
                        (eye - centre).normalized(), height, scale)
        r3d.view_location = Vector(r3d.view_location) + lift
        eye, changed = eye + lift, True
        height = altitude(obj, eye) * scale
    if height <= 0.0:
        return changed
    pivot = Vector(r3d.view_location)
    if altitude(obj, pivot) * scale < -max(0.01 * height, 0.5):
        forward = r3d.view_rotation @ Vector((0.0, 0.0, -1.0))
        hit = ground_hit(obj, eye, forward)
        distance = (hit - eye).length if hit is not None else max(height, 1.0)
        r3d.view_distance = distance
        r3d.view_location = eye + forward * distance
        changed = True
    if height < NEAR_GROUND * radius:
        changed |= level_horizon(r3d, eye, (eye - centre).normalized())
    return changed


def _way_out(obj, eye, forward, up, height, scale):
    """The move that takes an eye `height` m above the ground (less than
    MIN_CLEARANCE) back above it: back along its view when it looks down (it
    came that way: a Walk teleport or a zoom overshooting the ground), to
    where the view crosses MIN_CLEARANCE; else straight up."""
    if -forward.dot(up) > 0.1:
        def above(back):
            return altitude(obj, eye - forward * back) * scale
        low, low_height = 0.0, height
        for _ in range(64):  # steps of the depth left: never past a crossing by much
            high = low + max(MIN_CLEARANCE - low_height, 1.0)
            if above(high) >= MIN_CLEARANCE:
                for _ in range(24):
                    mid = 0.5 * (low + high)
                    low, high = (low, mid) if above(mid) >= MIN_CLEARANCE else (mid, high)
                return -forward * high
            low, low_height = high, above(high)
    return up * (MIN_CLEARANCE - height)


def level_horizon(r3d, eye, up):
    """Rolls the view about its own axis so its up lies in the plane of the
    planet's local up (the horizon level); True when it turned."""
    rotation = r3d.view_rotation
    forward = rotation @ Vector((0.0, 0.0, -1.0))
    if abs(forward.dot(up)) > 0.999:  # looking straight down or up: no horizon
        return False
    view_up = rotation @ Vector((0.0, 1.0, 0.0))
    wanted = (up - up.project(forward)).normalized()
    angle = view_up.angle(wanted, 0.0)
    if angle < 1e-4:
        return False
    roll = view_up.rotation_difference(wanted)
    pivot_distance = r3d.view_distance
    r3d.view_rotation = (roll @ rotation).normalized()
    r3d.view_location = eye + (r3d.view_rotation @ Vector((0.0, 0.0, -1.0))) * pivot_distance
    return True


def follow_views():
    """bpy.app.timers callback: keeps every view's pivot on the ground and its
    horizon level (see keep_pivot_on_ground)."""
    try:
        context = bpy.context
        scene = getattr(context, "scene", None)
        if scene is None or core.native is None or handlers.render_job_running() \
                or planet_fly.flying():  # the flight holds the view
            return 0.1
        found = runtime.planet_objects(scene)
        if not found:
            return 0.5
        while _pending_shifts:
            shift_views(_pending_shifts.pop(0))
        obj = found[0]
        for area, r3d in _views():
            if keep_pivot_on_ground(obj, area, r3d):
                area.tag_redraw()
    except (ReferenceError, AttributeError):
        pass
    return 0.1


_pending_shifts = []  # (planet name, world shift) from render threads


def anchor_moved(obj, old, new):
    """The floating origin moved from `old` to `new` (planet space): every 3D view
    moves with the planet, so nothing jumps on screen (from a render thread, at
    the next timer tick)."""
    if bpy.app.background:
        return
    shift = obj.matrix_world.to_3x3() @ (Vector(old) - Vector(new))
    if threading.current_thread() is not threading.main_thread():
        _pending_shifts.append(shift)
        return
    shift_views(shift)


def shift_views(shift):
    try:
        for area, r3d in _views():
            if r3d.view_perspective != 'CAMERA':
                r3d.view_location = Vector(r3d.view_location) + shift
            area.tag_redraw()
    except (ReferenceError, AttributeError):
        pass


# ---- altitude readout ---------------------------------------------------------------

def readout(context):
    """The line drawn in the view: altitude above the ground, or ""."""
    scene = context.scene
    region_data = context.region_data
    if scene is None or region_data is None or core.native is None:
        return ""
    found = runtime.planet_objects(scene)
    if not found:
        return ""
    obj = found[0]
    eye = region_data.view_matrix.inverted().translation
    if region_data.view_perspective == 'CAMERA' and scene.camera is not None:
        eye = scene.camera.matrix_world.translation
    height = altitude(obj, eye)
    if height > 10.0 * obj.planet_lod.radius:
        return ""
    if height < 0.0:
        return f"{obj.name}: below the ground"
    if height >= 10000.0:
        text = f"{height / 1000.0:,.0f} km"
    elif height >= 1000.0:
        text = f"{height / 1000.0:.2f} km"
    else:
        text = f"{height:.0f} m"
    return f"Altitude {text} above the ground of {obj.name}" + planet_fly.readout_suffix()


def draw_readout():
    import blf
    context = bpy.context
    try:
        text = readout(context)
    except (ReferenceError, AttributeError, ValueError):
        return
    if not text:
        return
    region = context.region
    scale = context.preferences.system.ui_scale
    font = 0
    blf.size(font, int(12 * scale))  # Blender 3.4 on: no dpi argument
    blf.color(font, 1.0, 1.0, 1.0, 0.9)
    blf.enable(font, blf.SHADOW)
    blf.shadow(font, 3, 0.0, 0.0, 0.0, 0.8)
    width = blf.dimensions(font, text)[0]
    blf.position(font, region.width - width - 20 * scale, 20 * scale, 0)
    blf.draw(font, text)
    blf.disable(font, blf.SHADOW)


# ---- registration ---------------------------------------------------------------------

_handles = {}


def register():
    runtime.ANCHOR_LISTENERS.append(anchor_moved)
    _handles["readout"] = bpy.types.SpaceView3D.draw_handler_add(draw_readout, (), 'WINDOW',
                                                                 'POST_PIXEL')
    if not bpy.app.timers.is_registered(follow_views):
        bpy.app.timers.register(follow_views, first_interval=0.5, persistent=True)


def unregister():
    if anchor_moved in runtime.ANCHOR_LISTENERS:
        runtime.ANCHOR_LISTENERS.remove(anchor_moved)
    if bpy.app.timers.is_registered(follow_views):
        bpy.app.timers.unregister(follow_views)
    handle = _handles.pop("readout", None)
    if handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(handle, 'WINDOW')
