"""A new planet is seen at once: the views and the scene camera framed on it
from outside, a sun, lights that the planet would swallow hidden.

A planet is thousands of kilometres wide while a new scene's camera, light
and view sit a few metres from the origin, i.e. inside it.
"""
import math

import bpy
from mathutils import Vector

from . import ground_proxy

# The planet's disk fills this fraction of the smaller field of view.
FILL = 0.8
DEFAULT_DIRECTION = Vector((0.62, -0.58, 0.42)).normalized()


def _half_fov(lens, sensor, aspect):
    """Half field of view (radians) of the smaller image side: the sensor spans
    the larger side (sensor fit Auto), `aspect` = width / height."""
    tan_large = sensor / 2.0 / lens
    return math.atan(tan_large / max(aspect, 1.0 / aspect))


def framing_distance(top, half_fov):
    """Distance from the centre at which a ball of radius `top` fills FILL of
    a view with this half field of view."""
    return top / math.sin(FILL * half_fov)


def _look(location, target):
    direction = Vector(target) - Vector(location)
    return direction.to_track_quat('-Z', 'Y').to_euler()


def _render_aspect(scene):
    r = scene.render
    return (r.resolution_x * r.pixel_aspect_x) / max(r.resolution_y * r.pixel_aspect_y, 1e-6)


def _remove(obj):
    data = obj.data
    bpy.data.objects.remove(obj)
    if data is not None and data.users == 0:
        getattr(bpy.data, "cameras" if isinstance(data, bpy.types.Camera) else "lights").remove(data)


def place_camera(scene, obj, top, undo):
    """Puts the scene camera outside the planet, looking at its centre (or adds a
    camera when the scene has none).  A camera already outside is left alone.
    Appends to `undo` what puts things back.  Returns a message, or ""."""
    centre = obj.matrix_world.translation
    cam = scene.camera
    created = cam is None
    if created:
        data = bpy.data.cameras.new("Camera")
        cam = bpy.data.objects.new("Camera", data)
        scene.collection.objects.link(cam)
        scene.camera = cam
        name = cam.name
        undo.append(lambda: (setattr(scene, "camera", None), _remove(bpy.data.objects[name])))
    offset = cam.matrix_world.translation - centre
    if not created and (cam.type != 'CAMERA' or offset.length > 1.05 * top):
        return ""
    if not created:
        saved = (cam.parent, cam.matrix_world.copy(), cam.data.ortho_scale)

        def put_back(cam=cam, saved=saved):
            cam.parent = saved[0]
            cam.matrix_world = saved[1]
            cam.data.ortho_scale = saved[2]
        undo.append(put_back)
    direction = offset.normalized() if offset.length > 1e-9 else DEFAULT_DIRECTION
    data = cam.data
    if data.type == 'ORTHO':
        data.ortho_scale = 2.0 * top / FILL
        distance = 3.0 * top
    else:
        distance = framing_distance(top, _half_fov(data.lens, data.sensor_width,
                                                   _render_aspect(scene)))
    cam.parent = None
    cam.location = centre + direction * distance
    cam.rotation_mode = 'XYZ'
    cam.rotation_euler = _look(cam.location, centre)
    return (f"{cam.name} added outside the planet" if created
            else f"{cam.name} moved out of the planet")


def add_sun(scene, obj, top, undo):
    """Adds a sun when the scene has none, lighting the side the camera sees from
    over its shoulder; hides the lights inside the planet (they light nothing
    but its inside).  Appends to `undo` what puts things back.  Returns messages."""
    messages = []
    centre = obj.matrix_world.translation
    for light in scene.objects:
        if (light.type == 'LIGHT' and light.data.type != 'SUN' and not light.hide_render
                and (light.matrix_world.translation - centre).length < top):
            light.hide_render = light.hide_viewport = True
            undo.append(lambda light=light: (setattr(light, "hide_render", False),
                                             setattr(light, "hide_viewport", False)))
            messages.append(f"{light.name} was inside the planet: hidden")
    if any(o.type == 'LIGHT' and o.data.type == 'SUN' and not o.hide_render
           for o in scene.objects):
        return messages
    view = DEFAULT_DIRECTION
    if scene.camera is not None:
        offset = scene.camera.matrix_world.translation - centre
        if offset.length > 1e-9:
            view = offset.normalized()
    side = Vector((0.0, 0.0, 1.0)).cross(view)
    side = side.normalized() if side.length > 1e-6 else Vector((1.0, 0.0, 0.0))
    towards_sun = (view + 0.8 * side + Vector((0.0, 0.0, 0.5))).normalized()
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    sun.data.energy = 4.0
    sun.rotation_euler = towards_sun.to_track_quat('Z', 'Y').to_euler()
    sun.location = centre + towards_sun * (top * 1.5)
    scene.collection.objects.link(sun)
    name = sun.name
    undo.append(lambda: _remove(bpy.data.objects[name]))
    messages.append("Sun added")
    return messages


def hide_inside(scene, obj, top, undo):
    """Hides the objects inside the new planet (the factory Cube at the origin):
    unseen inside it, they would sit in front of any camera the floating origin
    brings to the world origin.  Lights are add_sun's.  Returns messages."""
    messages = []
    centre = obj.matrix_world.translation
    for other in scene.objects:
        if (other is obj or other.type in {'LIGHT', 'CAMERA'} or other.planet_lod.enabled
                or ground_proxy.is_proxy(other)
                or other.planet_lod_geo.enabled or other.hide_render
                or (other.matrix_world.translation - centre).length >= top):
            continue
        other.hide_render = other.hide_viewport = True
        undo.append(lambda other=other: (setattr(other, "hide_render", False),
                                         setattr(other, "hide_viewport", False)))
        messages.append(f"{other.name} was inside the planet: hidden")
    return messages


def frame_views(screen, obj, top):
    """Points every 3D view of `screen` at the planet from outside (views that
    look through the camera follow the camera)."""
    if screen is None:
        return
    centre = obj.matrix_world.translation
    for area in screen.areas:
        if area.type != 'VIEW_3D':
            continue
        space = area.spaces.active
        r3d = space.region_3d
        region = next((r for r in area.regions if r.type == 'WINDOW'), None)
        if r3d is None or r3d.view_perspective == 'CAMERA':
            continue
        aspect = region.width / max(region.height, 1) if region is not None else 16 / 9
        r3d.view_location = centre
        # the viewport's lens is measured on a 72 mm sensor
        r3d.view_distance = framing_distance(top, _half_fov(space.lens, 72.0, aspect))
        area.tag_redraw()
