"""Planet Fly: flying a 3D view over a planet at a pace that follows the
altitude above the ground, never through it (planetlod/flight.py).

Blender's own Fly and Walk keep one speed the whole way down (Walk reads its
speed once, when it starts; Fly has no speed setting at all): a pace that
crosses a continent from orbit crawls through a valley, and either passes
through the ground.  Shift-` starts Planet Fly instead of them in a
perspective view near a planet.

The eye is kept in float64 planet space for the whole flight: the view's own
float32 location is half a metre coarse at a planet's radius, which would
swallow the centimetre steps of a flight near the ground."""
import math
import time

import bpy
from mathutils import Matrix, Vector

from . import cameras, runtime
from .core import flight
from .navigation import NEAR_GROUND, ground_height, ground_hit, to_world

# Below this clearance (m) above the ground the eye is lifted (the views'
# own lift, view_follow.MIN_CLEARANCE, uses the same).
CLEARANCE = 2.0
# Planet Fly starts below this altitude (a fraction of the radius); higher
# up, Blender's own navigation.
HIGHEST = 10.0 * NEAR_GROUND

KEYS = {
    'W': ("ahead", 1), 'UP_ARROW': ("ahead", 1), 'S': ("ahead", -1), 'DOWN_ARROW': ("ahead", -1),
    'D': ("aside", 1), 'RIGHT_ARROW': ("aside", 1), 'A': ("aside", -1),
    'LEFT_ARROW': ("aside", -1), 'E': ("rise", 1), 'Q': ("rise", -1),
}
HELP = ("W/S/A/D or arrows: move  ·  E/Q: up/down  ·  mouse: look  ·  wheel: speed  ·  "
        "Shift: fast  ·  Alt: slow  ·  LMB/Enter: done  ·  RMB/Esc: cancel")


class FlightLog:
    """What the running (or last) flight did: shown in the view's altitude
    readout while it runs."""

    def __init__(self, height):
        self.running = True
        # metres of the planet (its object's scale aside)
        self.height = height  # above the ground now
        self.lowest = height  # the lowest the eye has been
        self.speed = 0.0  # m/s of the last tick (0 when standing)
        self.moving_s = 0.0  # seconds spent moving
        self.distance = 0.0  # metres flown


_flight = {"log": None}


def flight_log():
    """The running flight's FlightLog, else the last one, else None."""
    return _flight["log"]


def flying():
    log = _flight["log"]
    return log is not None and log.running


def _planet_near(context):
    """(planet, eye altitude) when this view may fly over a planet, else (None, reason)."""
    r3d = context.region_data
    if r3d is None or r3d.view_perspective != 'PERSP':
        return None, "a perspective view"
    best = None
    eye = cameras.view_to_world(r3d).translation
    for obj in runtime.planet_objects(context.scene):
        height = _altitude_of(obj.planet_lod.radius, ground_height(obj), _to_planet(obj, eye))
        if 0.0 <= height < HIGHEST * obj.planet_lod.radius and (best is None or height < best[1]):
            best = (obj, height)
    return best if best is not None else (None, "near a planet")


def _to_planet(obj, world_point):
    local = runtime.to_planet_space(obj, Matrix.Translation(world_point))
    return tuple(float(local[i][3]) for i in range(3))


def _altitude_of(radius, ground, point):
    """Metres above the ground (`ground`: navigation.ground_height) of a planet-space point."""
    r = math.sqrt(sum(c * c for c in point))
    if r < 1e-9:
        return -radius
    return r - radius - ground((point[0] / r, point[1] / r, point[2] / r))


class PLOD_OT_planet_fly(bpy.types.Operator):
    """Fly through the view over the planet at a pace that follows the altitude above the
    ground, never through it (W/S/A/D move, E/Q up and down, the mouse looks, the wheel
    sets the speed)"""
    bl_idname = "view3d.planet_fly"
    bl_label = "Planet Fly"
    bl_options = {'BLOCKING'}

    @classmethod
    def poll(cls, context):
        return context.area is not None and context.area.type == 'VIEW_3D' \
            and context.region_data is not None and bool(runtime.planet_objects(context.scene))

    def invoke(self, context, event):
        obj, height = _planet_near(context)
        if obj is None:
            return {'PASS_THROUGH'}  # Blender's own navigation (bound to the same key)
        if flying():
            return {'CANCELLED'}
        r3d = context.region_data
        self.planet = obj.name_full
        self.saved = (Vector(r3d.view_location), r3d.view_rotation.copy(), r3d.view_distance)
        self.ground = ground_height(obj)
        self.radius = obj.planet_lod.radius
        self.scale = max(obj.matrix_world.to_scale())
        self.basis = obj.matrix_world.to_3x3().normalized()
        eye_world = cameras.view_to_world(r3d).translation
        self.eye = _to_planet(obj, eye_world)
        forward_world = r3d.view_rotation @ Vector((0.0, 0.0, -1.0))
        up_world = r3d.view_rotation @ Vector((0.0, 1.0, 0.0))
        to_planet = self.basis.inverted()
        self.view_up = tuple(to_planet @ up_world)
        self.forward = flight.look(tuple(to_planet @ forward_world), flight.local_up(self.eye),
                                   0.0, 0.0, self.view_up)
        self.held = set()
        self.factor = 1.0
        self.fast = self.slow = False
        self.mouse = (event.mouse_x, event.mouse_y)
        self.last_tick = time.monotonic()
        _flight["log"] = FlightLog(height)
        wm = context.window_manager
        self.timer = wm.event_timer_add(1.0 / 60.0, window=context.window)
        wm.modal_handler_add(self)
        self._apply(context)  # the horizon level, the pivot close (float32 precision)
        return {'RUNNING_MODAL'}

    # ---- events ---------------------------------------------------------------------

    def modal(self, context, event):
        try:
            return self._event(context, event)
        except BaseException:
            self._end(context, cancel=True)  # the view back, the flight over
            raise

    def _event(self, context, event):
        obj = bpy.data.objects.get(self.planet)
        if obj is None or context.region_data is None:
            return self._end(context, cancel=False)
        kind, value = event.type, event.value
        if kind in {'ESC', 'RIGHTMOUSE'} and value == 'PRESS':
            return self._end(context, cancel=True)
        if kind in {'RET', 'NUMPAD_ENTER', 'LEFTMOUSE', 'SPACE'} and value == 'PRESS':
            return self._end(context, cancel=False)
        if kind in KEYS and value in {'PRESS', 'RELEASE'}:
            (self.held.add if value == 'PRESS' else self.held.discard)(kind)
        elif kind in {'LEFT_SHIFT', 'RIGHT_SHIFT'} and value in {'PRESS', 'RELEASE'}:
            self.fast = value == 'PRESS'
        elif kind in {'LEFT_ALT', 'RIGHT_ALT'} and value in {'PRESS', 'RELEASE'}:
            self.slow = value == 'PRESS'
        elif kind in {'WHEELUPMOUSE', 'NUMPAD_PLUS'} and value == 'PRESS':
            self.factor = flight.scaled_factor(self.factor, 1)
        elif kind in {'WHEELDOWNMOUSE', 'NUMPAD_MINUS'} and value == 'PRESS':
            self.factor = flight.scaled_factor(self.factor, -1)
        elif kind == 'MOUSEMOVE':
            self._look(context, event)
        elif kind == 'TIMER':  # ours or another's: a tick moves by the time since the last
            self._tick(context, obj)
        return {'RUNNING_MODAL'}

    def _look(self, context, event):
        dx, dy = event.mouse_x - self.mouse[0], event.mouse_y - self.mouse[1]
        self.mouse = (event.mouse_x, event.mouse_y)
        if dx == 0 and dy == 0:
            return
        self.forward = flight.look(self.forward, flight.local_up(self.eye),
                                   -dx * flight.TURN_PER_PIXEL, dy * flight.TURN_PER_PIXEL,
                                   self.view_up)
        # the pointer back to the view's middle before it leaves the view
        region = context.region
        mx, my = event.mouse_region_x, event.mouse_region_y
        if region is not None and not (region.width // 4 < mx < 3 * region.width // 4
                                       and region.height // 4 < my < 3 * region.height // 4):
            cx, cy = region.x + region.width // 2, region.y + region.height // 2
            context.window.cursor_warp(cx, cy)
            self.mouse = (cx, cy)
        self._apply(context)

    def _tick(self, context, obj):
        now = time.monotonic()
        dt = min(now - self.last_tick, flight.LONGEST_TICK_S)
        self.last_tick = now
        log = _flight["log"]
        up = flight.local_up(self.eye)
        ahead = sum(KEYS[k][1] for k in self.held if KEYS[k][0] == "ahead")
        aside = sum(KEYS[k][1] for k in self.held if KEYS[k][0] == "aside")
        rise = sum(KEYS[k][1] for k in self.held if KEYS[k][0] == "rise")
        way = flight.motion(self.forward, up, ahead, aside, rise)
        if way is None or dt <= 0.0:
            log.speed = 0.0
            return
        factor = self.factor * (flight.FAST if self.fast else 1.0) \
            * (flight.SLOW if self.slow else 1.0)
        height = self._height(self.eye)
        pace = flight.speed(height, factor, CLEARANCE)
        start = self.eye
        self.eye, height = flight.fly(self.eye, way, pace * dt, self._height, CLEARANCE)
        log.speed = pace
        log.moving_s += dt
        log.distance += math.dist(start, self.eye)
        log.height = height
        log.lowest = min(log.lowest, height)
        # the horizon stays level as the local up turns under the eye
        self.forward = flight.look(self.forward, flight.local_up(self.eye), 0.0, 0.0, self.view_up)
        self._apply(context)

    def _height(self, point):
        return _altitude_of(self.radius, self.ground, point)

    # ---- the view -------------------------------------------------------------------

    def _apply(self, context):
        obj = bpy.data.objects.get(self.planet)
        r3d = context.region_data
        if obj is None or r3d is None:
            return
        right, view_up, back = flight.view_basis(self.forward, flight.local_up(self.eye))
        self.view_up = view_up
        rotation = self.basis @ Matrix([right, view_up, back]).transposed()
        eye = to_world(obj, self.eye)
        r3d.view_rotation = rotation.to_quaternion()
        # the pivot close ahead: its float32 location keeps the eye's precision
        distance = max(_flight["log"].height, CLEARANCE) * self.scale
        r3d.view_distance = distance
        r3d.view_location = eye + rotation @ Vector((0.0, 0.0, -distance))
        runtime.mark_dirty(obj)
        self._show(context)
        context.area.tag_redraw()

    def _show(self, context):
        log = _flight["log"]
        context.area.header_text_set(
            f"Planet Fly  ·  {_speed_text(flight.speed(log.height, self.factor, CLEARANCE))}"
            f"  ·  {HELP}")

    def _end(self, context, cancel):
        if self.timer is None:
            return {'CANCELLED'}
        context.window_manager.event_timer_remove(self.timer)
        self.timer = None
        if context.area is not None:
            context.area.header_text_set(None)
        log = _flight["log"]
        if log is not None:
            log.running = False
        obj = bpy.data.objects.get(self.planet)
        r3d = context.region_data
        if r3d is not None:
            if cancel:
                r3d.view_location, r3d.view_rotation, r3d.view_distance = self.saved
            elif obj is not None:
                # the pivot on the ground ahead: the wheel then zooms towards the ground
                eye = to_world(obj, self.eye)
                forward = r3d.view_rotation @ Vector((0.0, 0.0, -1.0))
                hit = ground_hit(obj, eye, forward)
                if hit is not None:
                    r3d.view_distance = (hit - eye).length
                    r3d.view_location = hit
        if obj is not None:
            runtime.mark_dirty(obj)
        if context.area is not None:
            context.area.tag_redraw()
        return {'CANCELLED'} if cancel else {'FINISHED'}


def _speed_text(speed):
    if speed >= 1000.0:
        return f"{speed / 1000.0:.2f} km/s"
    if speed >= 10.0:
        return f"{speed:.0f} m/s"
    return f"{speed:.1f} m/s"


def readout_suffix():
    """What the altitude readout adds while a flight runs ("" otherwise)."""
    log = _flight["log"]
    if log is None or not log.running:
        return ""
    return f"  ·  flying {_speed_text(log.speed)}" if log.speed > 0.0 else "  ·  Planet Fly"


# ---- registration ---------------------------------------------------------------------

_keymaps = []


def register():
    bpy.utils.register_class(PLOD_OT_planet_fly)
    kc = bpy.context.window_manager.keyconfigs.addon
    if kc is not None:
        # Shift-` (Blender's Fly/Walk Navigation): Planet Fly near a planet, else
        # Blender's own (the operator passes the key through)
        km = kc.keymaps.new(name="3D View", space_type='VIEW_3D')
        _keymaps.append((km, km.keymap_items.new(PLOD_OT_planet_fly.bl_idname, 'ACCENT_GRAVE',
                                                 'PRESS', shift=True)))


def unregister():
    for km, item in _keymaps:
        km.keymap_items.remove(item)
    _keymaps.clear()
    _flight["log"] = None
    bpy.utils.unregister_class(PLOD_OT_planet_fly)
