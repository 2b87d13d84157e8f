"""Finding a planet and flying down to it with Blender's own views: Frame
Planet (also on Home and Frame Selected when a planet is concerned), Go to
Surface by longitude and latitude, the altitude above the ground drawn in the
view, a zoom pivot kept on the ground (the wheel zooms towards the ground in
shrinking steps, never through it), the view's up levelled to the planet's
local up near the ground, and every view carried along when the floating
origin moves, so the planet does not jump on screen.

A planet is thousands of kilometres wide while Blender's navigation pivots
around a point that defaults to the planet's centre: without this, one wheel
notch from 500 km up lands inside the planet."""
import math
import threading

import bpy
from bpy.props import BoolProperty, FloatProperty
from mathutils import Matrix, Quaternion, Vector

from . import core, framing, live, runtime
from .core import flyby, planets, presets

# Below this altitude (as a fraction of the radius) the view's up follows the
# planet's local up and the altitude readout is drawn.
NEAR_GROUND = 0.05


# ---- the planet in world space ---------------------------------------------------

def active_planet(context):
    """The active planet, else the first planet of the scene, else None."""
    obj = getattr(context, "object", None)
    if obj is not None and obj.type == 'MESH' and obj.planet_lod.enabled:
        return obj
    scene = getattr(context, "scene", None)
    found = runtime.planet_objects(scene) if scene is not None else []
    return found[0] if found else None


def planet_centre(obj):
    """The planet's centre in world space (the anchor moves it off the object's origin)."""
    return obj.matrix_world @ -Vector(runtime.anchor(obj))


def planet_top(obj):
    """Radius of the ball holding the planet's highest peak, in scene units."""
    s = obj.planet_lod
    try:
        high = max(planets.build_planet(s.as_dict()).height_range()[1], 0.0)
    except core.REPORTED_ERRORS:
        high = 0.0
    return (s.radius + high) * max(obj.matrix_world.to_scale())


def to_world(obj, point):
    """A planet-space point (float64 tuple) in world space."""
    a = runtime.anchor(obj)
    return obj.matrix_world @ Vector([point[i] - a[i] for i in range(3)])


def ground_height(obj):
    """Height (m) of the ground under a unit planet-space direction (the sea
    over land below it); 0 everywhere when the planet cannot be built."""
    s = obj.planet_lod
    try:
        planet = planets.build_planet(s.as_dict())
    except core.REPORTED_ERRORS:
        return lambda d: 0.0
    if s.use_sea_level:
        sea = float(s.sea_level)
        return lambda d: max(planet.height(*d), sea)
    return lambda d: planet.height(*d)


def eye_of(r3d):
    """The view's eye in world space (a perspective view's camera position)."""
    return live.view_to_world(r3d).translation


def altitude(obj, world_point):
    """Metres above the ground of a world-space point (negative: underground)."""
    local = live.to_planet_space(obj, Matrix.Translation(world_point))
    p = Vector([local[i][3] for i in range(3)])
    distance = p.length
    if distance < 1e-9:
        return -obj.planet_lod.radius
    return distance - obj.planet_lod.radius - ground_height(obj)(tuple(p / distance))


# ---- framing ---------------------------------------------------------------------

def frame_view(area, obj):
    """Points a 3D view at the whole planet from outside (a camera view leaves
    the camera's view first)."""
    space = area.spaces.active
    r3d = space.region_3d
    if r3d is None:
        return
    region = next((r for r in area.regions if r.type == 'WINDOW'), None)
    aspect = region.width / max(region.height, 1) if region is not None else 16 / 9
    if r3d.view_perspective == 'CAMERA':
        r3d.view_perspective = 'PERSP'
    r3d.view_location = planet_centre(obj)
    # the viewport's lens is measured on a 72 mm sensor
    tan_large = 72.0 / 2.0 / space.lens
    half_fov = math.atan(tan_large / max(aspect, 1.0 / aspect))
    r3d.view_distance = framing.framing_distance(planet_top(obj), half_fov)
    area.tag_redraw()


def frame_all_views(screen, obj):
    for area in screen.areas if screen is not None else ():
        if area.type == 'VIEW_3D':
            frame_view(area, obj)


def planet_preset_applied(context, obj, key):
    """After a planet preset: the object named after the new planet (when it
    still had the old preset's name), the scene camera out of it, every view
    framing it."""
    s = obj.planet_lod
    old = presets.PLANETS.get(s.preset, {}).get("label", "").split(" ")[0]
    new = presets.PLANETS[key]["label"].split(" ")[0]
    if old and old != new and (obj.name == old or obj.name.startswith(old + ".")):
        before = obj.name_full
        obj.name = new
        st = runtime.RUNTIME.pop(before, None)  # the state goes with the object
        if st is not None:
            runtime.RUNTIME[obj.name_full] = st
        if obj.data is not None and obj.data.users == 1:
            obj.data.name = new
    s.preset = key
    s["active_planet_preset"] = presets.PLANETS[key]["label"].split(" (")[0]
    context.view_layer.update()
    framing.place_camera(context.scene, obj, planet_top(obj), [])
    frame_all_views(context.screen, obj)


class PLOD_OT_frame_planet(bpy.types.Operator):
    """Show the whole planet in this view"""
    bl_idname = "view3d.planet_frame"
    bl_label = "Frame Planet"
    bl_options = {'REGISTER'}

    selected_only: BoolProperty(
        name="Selected Only", default=False, options={'SKIP_SAVE'},
        description="Only when the active object is a selected planet (Frame Selected)")

    @classmethod
    def poll(cls, context):
        return context.area is not None and context.area.type == 'VIEW_3D' \
            and active_planet(context) is not None

    def invoke(self, context, event):
        # on Frame Selected / Home: a planet among other things, or none at all,
        # leaves the key to Blender's own operator
        obj = active_planet(context)
        if self.selected_only and (context.object is not obj or not obj.select_get()):
            return {'PASS_THROUGH'}
        return self.execute(context)

    def execute(self, context):
        obj = active_planet(context)
        frame_view(context.area, obj)
        live.mark_dirty(obj)
        return {'FINISHED'}


# ---- Go to Surface -----------------------------------------------------------------

def surface_view(obj, longitude, latitude, height, heading, pitch):
    """(eye, rotation) in world space of a view `height` metres above the ground
    at longitude/latitude, looking along `heading`, `pitch` degrees above the horizon."""
    s = obj.planet_lod
    pose = flyby.geo_pose(s.radius, longitude, latitude, altitude=height, heading=heading,
                          pitch=pitch, base_height=ground_height(obj))
    eye = to_world(obj, [row[3] for row in pose[:3]])
    basis = obj.matrix_world.to_3x3().normalized() @ Matrix([row[:3] for row in pose[:3]])
    return eye, basis.to_quaternion()


def set_view(r3d, eye, rotation, pivot_distance):
    """Puts a 3D view's eye at `eye` looking along `rotation`, orbiting around a
    point `pivot_distance` ahead."""
    if r3d.view_perspective != 'PERSP':
        r3d.view_perspective = 'PERSP'
    forward = rotation @ Vector((0.0, 0.0, -1.0))
    r3d.view_rotation = rotation
    r3d.view_distance = pivot_distance
    r3d.view_location = eye + forward * pivot_distance


class PLOD_OT_go_to_surface(bpy.types.Operator):
    """Put this view above a point of the planet, by longitude and latitude"""
    bl_idname = "view3d.planet_go_to_surface"
    bl_label = "Go to Surface"
    bl_options = {'REGISTER'}

    longitude: FloatProperty(name="Longitude", default=0.0, min=-180.0, max=180.0,
                             description="Degrees east of the prime meridian")
    latitude: FloatProperty(name="Latitude", default=0.0, min=-90.0, max=90.0,
                            description="Degrees north of the equator")
    altitude: FloatProperty(name="Altitude", default=2000.0, min=1.0, max=1.0e8,
                            subtype='DISTANCE', unit='LENGTH',
                            description="Height of the view above the ground")
    heading: FloatProperty(name="Heading", default=0.0, min=-360.0, max=360.0,
                           description="Degrees from north towards east")
    pitch: FloatProperty(name="Pitch", default=-10.0, min=-90.0, max=90.0,
                         description="Degrees above the horizon (negative: looking down)")

    @classmethod
    def poll(cls, context):
        return context.area is not None and context.area.type == 'VIEW_3D' \
            and active_planet(context) is not None

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        obj = active_planet(context)
        r3d = context.area.spaces.active.region_3d
        eye, rotation = surface_view(obj, self.longitude, self.latitude, self.altitude,
                                     self.heading, self.pitch)
        set_view(r3d, eye, rotation, max(self.altitude, 1.0))
        live.mark_dirty(obj)
        live.fit_view_clips(context.scene)
        context.area.tag_redraw()
        return {'FINISHED'}


# ---- keeping the views on the planet ----------------------------------------------

def _ray_hits_sphere(origin, direction, centre, radius):
    """Distance along the unit `direction` to the sphere, or None."""
    oc = origin - centre
    b = oc.dot(direction)
    c = oc.length_squared - radius * radius
    disc = b * b - c
    if disc < 0.0:
        return None
    t = -b - math.sqrt(disc)
    return t if t > 0.0 else None


def _views():
    wm = bpy.context.window_manager
    for window in wm.windows if wm else ():
        for area in window.screen.areas:
            if area.type == 'VIEW_3D':
                r3d = area.spaces.active.region_3d
                if r3d is not None:
                    yield area, r3d


def keep_pivot_on_ground(obj, area, r3d):
    """Moves a perspective view's pivot (the point it zooms towards and orbits)
    out of the planet onto the ground ahead, the eye unchanged; near the
    ground, levels the view's horizon to the planet's local up.  True when
    the view changed."""
    if r3d.view_perspective != 'PERSP' or not area.spaces.active.planet_lod_follow_ground:
        return False
    centre = planet_centre(obj)
    scale = max(obj.matrix_world.to_scale())
    radius = obj.planet_lod.radius * scale
    eye = eye_of(r3d)
    height = altitude(obj, eye) * scale
    if height <= 0.0:
        return False
    changed = False
    pivot = Vector(r3d.view_location)
    if (pivot - centre).length < radius - 0.01 * height:
        forward = r3d.view_rotation @ Vector((0.0, 0.0, -1.0))
        hit = _ray_hits_sphere(eye, forward, centre, radius)
        distance = hit if hit is not None else max(height, 1.0)
        r3d.view_distance = distance
        r3d.view_location = eye + forward * distance
        changed = True
    if height < NEAR_GROUND * radius:
        changed |= level_horizon(r3d, eye, (eye - centre).normalized())
    return changed


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
        if scene is None or core.native is None or live.render_job_running():
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
    return f"Altitude {text} above the ground of {obj.name}"


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
    blf.size(font, int(12 * scale)) if bpy.app.version >= (3, 4, 0) else \
        blf.size(font, int(12 * scale), 72)
    blf.color(font, 1.0, 1.0, 1.0, 0.9)
    blf.enable(font, blf.SHADOW)
    blf.shadow(font, 3, 0.0, 0.0, 0.0, 0.8)
    width = blf.dimensions(font, text)[0]
    blf.position(font, region.width - width - 20 * scale, 20 * scale, 0)
    blf.draw(font, text)
    blf.disable(font, blf.SHADOW)


# ---- registration ---------------------------------------------------------------------

classes = (PLOD_OT_frame_planet, PLOD_OT_go_to_surface)
_keymaps = []
_handles = {}


def view_menu(self, context):
    layout = self.layout
    layout.separator()
    layout.operator(PLOD_OT_frame_planet.bl_idname, icon='WORLD')
    layout.operator(PLOD_OT_go_to_surface.bl_idname, icon='VIEW_CAMERA')
    layout.prop(context.space_data, "planet_lod_follow_ground")


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    runtime.ANCHOR_LISTENERS.append(anchor_moved)
    bpy.types.SpaceView3D.planet_lod_follow_ground = BoolProperty(
        name="Follow the Planet's Ground", default=True,
        description="Keep the view's zoom and orbit point on the planet's ground (the wheel "
                    "zooms towards the ground, never through it) and, near the ground, the "
                    "horizon level with the planet's local up")
    bpy.types.VIEW3D_MT_view.append(view_menu)
    _handles["readout"] = bpy.types.SpaceView3D.draw_handler_add(draw_readout, (), 'WINDOW',
                                                                 'POST_PIXEL')
    if not bpy.app.timers.is_registered(follow_views):
        bpy.app.timers.register(follow_views, first_interval=0.5, persistent=True)
    kc = bpy.context.window_manager.keyconfigs.addon
    if kc is not None:
        # Object Mode's keymap comes before the 3D View's (modes override the view)
        km = kc.keymaps.new(name="Object Mode", space_type='EMPTY')
        for key in ('HOME', 'NUMPAD_PERIOD'):
            item = km.keymap_items.new(PLOD_OT_frame_planet.bl_idname, key, 'PRESS')
            item.properties.selected_only = key == 'NUMPAD_PERIOD'
            _keymaps.append((km, item))


def unregister():
    if anchor_moved in runtime.ANCHOR_LISTENERS:
        runtime.ANCHOR_LISTENERS.remove(anchor_moved)
    for km, item in _keymaps:
        km.keymap_items.remove(item)
    _keymaps.clear()
    if bpy.app.timers.is_registered(follow_views):
        bpy.app.timers.unregister(follow_views)
    handle = _handles.pop("readout", None)
    if handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(handle, 'WINDOW')
    bpy.types.VIEW3D_MT_view.remove(view_menu)
    del bpy.types.SpaceView3D.planet_lod_follow_ground
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
