"""Finding a planet and flying down to it with Blender's own views: Frame
Planet (also on Home and Frame Selected when a planet is concerned), Go to
Surface by longitude and latitude (view_follow.py keeps the views on the
planet afterwards).

A planet is thousands of kilometres wide while Blender's navigation pivots
around a point that defaults to the planet's centre: without this, one wheel
notch from 500 km up lands inside the planet."""
import math

import bpy
from bpy.props import BoolProperty, FloatProperty
from mathutils import Matrix, Vector

from . import cameras, core, framing, ground_proxy, runtime
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
    return cameras.view_to_world(r3d).translation


def altitude(obj, world_point):
    """Metres above the ground of a world-space point (negative: underground)."""
    local = runtime.to_planet_space(obj, Matrix.Translation(world_point))
    # float64 from here: a mathutils Vector at a planet's radius is half a metre coarse
    p = [local[i][3] for i in range(3)]
    distance = math.sqrt(sum(c * c for c in p))
    if distance < 1e-9:
        return -obj.planet_lod.radius
    return distance - obj.planet_lod.radius - ground_height(obj)(tuple(c / distance for c in p))


def ground_hit(obj, origin, direction):
    """Where a world-space ray first meets the planet's ground (the sea over
    land below it), or None.  Marches the ray in planet space by a fraction
    of its height above the ground (slopes steeper than that fraction allows
    are rare at the scale a click resolves), then bisects the last step; in
    float64 (mathutils is float32: half a metre at a planet's radius)."""
    to_planet = obj.matrix_world.inverted_safe()
    anchor = runtime.anchor(obj)
    m = [[float(to_planet[i][j]) for j in range(4)] for i in range(3)]
    o = [sum(m[i][j] * float(origin[j]) for j in range(3)) + m[i][3] + anchor[i]
         for i in range(3)]
    d = [sum(m[i][j] * float(direction[j]) for j in range(3)) for i in range(3)]
    length = math.sqrt(sum(c * c for c in d))
    d = [c / length for c in d]
    radius = obj.planet_lod.radius
    ground = ground_height(obj)

    def point(t):
        return [o[i] + d[i] * t for i in range(3)]

    def above(t):
        p = point(t)
        r = math.sqrt(sum(c * c for c in p))
        return r - radius - ground((p[0] / r, p[1] / r, p[2] / r))
    top = planet_top(obj) / max(obj.matrix_world.to_scale())
    b = sum(o[i] * d[i] for i in range(3))
    disc = b * b - (sum(c * c for c in o) - top * top)
    if disc < 0.0 or -b + math.sqrt(disc) < 0.0:
        return None  # the ray passes above the highest peak
    t = max(-b - math.sqrt(disc), 0.0)
    far = -b + math.sqrt(disc)
    height = above(t)
    if height <= 0.0:
        return None  # starts underground
    for _ in range(4000):
        step = max(0.5 * height, 1e-3 * (t + 1.0), 0.01)
        if t + step > far:
            return None
        next_height = above(t + step)
        if next_height <= 0.0:
            low, high = t, t + step
            for _ in range(48):
                mid = 0.5 * (low + high)
                low, high = (mid, high) if above(mid) > 0.0 else (low, mid)
            return to_world(obj, point(high))
        t, height = t + step, next_height
    return None


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
        runtime.mark_dirty(obj)
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
        # the pivot on the ground ahead: the wheel then zooms towards the ground
        hit = ground_hit(obj, eye, rotation @ Vector((0.0, 0.0, -1.0)))
        set_view(r3d, eye, rotation, (hit - eye).length if hit is not None
                 else max(self.altitude, 1.0))
        runtime.mark_dirty(obj)
        cameras.fit_view_clips(context.scene)
        context.area.tag_redraw()
        return {'FINISHED'}


# ---- the 3D cursor on the ground -------------------------------------------------------

class PLOD_OT_cursor_to_ground(bpy.types.Operator):
    """Place the 3D cursor where the mouse points on the planet's ground"""
    bl_idname = "view3d.planet_cursor"
    bl_label = "Cursor to Planet Ground"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return context.area is not None and context.area.type == 'VIEW_3D' \
            and context.region_data is not None and active_planet(context) is not None

    def invoke(self, context, event):
        # the previewed planet is drawn outside Blender's depth buffer, which
        # its own Set 3D Cursor reads: it gets the click whenever the mouse is
        # not on the planet's ground, or something else is in front of it
        from bpy_extras import view3d_utils
        region, r3d = context.region, context.region_data
        xy = (event.mouse_region_x, event.mouse_region_y)
        origin = view3d_utils.region_2d_to_origin_3d(region, r3d, xy)
        direction = view3d_utils.region_2d_to_vector_3d(region, r3d, xy).normalized()
        best = None
        for obj in runtime.planet_objects(context.scene):
            if not obj.planet_lod.gpu_preview or not obj.visible_get():
                continue
            hit = ground_hit(obj, origin, direction)
            if hit is not None and (best is None or (hit - origin).length < best):
                best, point = (hit - origin).length, hit
        if best is None:
            return {'PASS_THROUGH'}
        planets_here = set(runtime.planet_objects(context.scene))
        depsgraph = context.evaluated_depsgraph_get()
        start = origin
        for _ in range(16):  # anything else in front of the ground keeps the click
            found, location, _, _, obj, _ = context.scene.ray_cast(depsgraph, start, direction,
                                                                    distance=best)
            if not found:
                break
            if obj.original not in planets_here and not ground_proxy.is_proxy(obj.original):
                return {'PASS_THROUGH'}
            start = location + direction * 1e-3
        context.scene.cursor.location = point
        context.area.tag_redraw()
        return {'FINISHED'}


# ---- registration ---------------------------------------------------------------------

classes = (PLOD_OT_frame_planet, PLOD_OT_go_to_surface, PLOD_OT_cursor_to_ground)
_keymaps = []


def view_menu(self, context):
    layout = self.layout
    layout.separator()
    layout.operator(PLOD_OT_frame_planet.bl_idname, icon='WORLD')
    layout.operator(PLOD_OT_go_to_surface.bl_idname, icon='VIEW_CAMERA')
    layout.operator("view3d.planet_fly", icon='VIEW_PAN')
    layout.prop(context.space_data, "planet_lod_follow_ground")


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.SpaceView3D.planet_lod_follow_ground = BoolProperty(
        name="Follow the Planet's Ground", default=True,
        description="Keep the view's zoom and orbit point on the planet's ground (the wheel "
                    "zooms towards the ground, never through it) and, near the ground, the "
                    "horizon level with the planet's local up")
    bpy.types.VIEW3D_MT_view.append(view_menu)
    kc = bpy.context.window_manager.keyconfigs.addon
    if kc is not None:
        # Object Mode's keymap comes before the 3D View's (modes override the view)
        km = kc.keymaps.new(name="Object Mode", space_type='EMPTY')
        for key in ('HOME', 'NUMPAD_PERIOD'):
            item = km.keymap_items.new(PLOD_OT_frame_planet.bl_idname, key, 'PRESS')
            item.properties.selected_only = key == 'NUMPAD_PERIOD'
            _keymaps.append((km, item))
        km = kc.keymaps.new(name="3D View", space_type='VIEW_3D')
        item = km.keymap_items.new(PLOD_OT_cursor_to_ground.bl_idname, 'RIGHTMOUSE', 'PRESS',
                                   shift=True)
        _keymaps.append((km, item))


def unregister():
    for km, item in _keymaps:
        km.keymap_items.remove(item)
    _keymaps.clear()
    bpy.types.VIEW3D_MT_view.remove(view_menu)
    del bpy.types.SpaceView3D.planet_lod_follow_ground
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
