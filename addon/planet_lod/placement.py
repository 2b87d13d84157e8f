"""Placing cameras and objects in planet space: the flyby camera (its path is
planetlod.flyby.flyby_pose, a pure function of the frame number, so any
sub-range renders exactly the frames of the full path), objects at a
planet-space pose, with the planet's floating origin moved to them, and
objects placed by longitude, latitude and altitude (Geo Placement)."""
import math

import bpy
from mathutils import Matrix

from . import cameras, core, runtime
from .core import flyby, planets, waypoints

FLYBY_KEY = "planet_lod_flyby"
PATH_KEY = "planet_lod_path"  # the flyby camera's own path of waypoints, when it has one


def ensure_flyby_camera(scene, planet_obj, path_frames, skim_height=5.0):
    name = "Flyby " + planet_obj.name
    cam = bpy.data.objects.get(name)
    if cam is None or cam.type != 'CAMERA':
        data = bpy.data.cameras.new(name)
        data.lens = 24.0
        cam = bpy.data.objects.new(name, data)
        scene.collection.objects.link(cam)
    cam[FLYBY_KEY] = planet_obj.name
    cam["planet_lod_path_frames"] = int(path_frames)
    cam["planet_lod_skim_height"] = float(skim_height)
    scene.camera = cam
    place_camera(cam, scene, scene.frame_current)
    return cam


def terrain_height(planet_obj):
    """Terrain height (m) under a unit direction, from the native planet (no heights: None);
    over the sea (land below it, e.g. detail on a low coast), the sea surface."""
    try:
        planet = planets.build_planet(planet_obj.planet_lod.as_dict())
    except core.REPORTED_ERRORS:
        return None
    s = planet_obj.planet_lod
    if s.use_sea_level:
        sea = float(s.sea_level)
        return lambda d: max(planet.height(*d), sea)
    return lambda d: planet.height(*d)


def place_camera(cam, scene, frame):
    planet_obj = bpy.data.objects.get(cam.get(FLYBY_KEY, ""))
    if planet_obj is None:
        return
    s = planet_obj.planet_lod
    ground_height = terrain_height(planet_obj)
    if cam.get(PATH_KEY):  # a path of waypoints (planetlod.waypoints CSV)
        try:
            pose = waypoints.saved_path(cam[PATH_KEY]).pose(
                frame, s.radius, ground_height, s.sea_level if s.use_sea_level else 0.0)
        except waypoints.PathError:  # a frame outside the path: renders refuse it
            return
    else:
        pose = flyby.flyby_pose(frame, cam["planet_lod_path_frames"], s.radius,
                               skim_height=cam["planet_lod_skim_height"],
                               ground_height=ground_height)
    place_in_planet_space(cam, planet_obj, pose)
    location = [row[3] for row in pose[:3]]
    distance = math.sqrt(sum(c * c for c in location))
    ground = ground_height(tuple(c / distance for c in location)) if ground_height else 0.0
    # clip start from the height above the *terrain* (not the radius; the
    # ocean sphere covers ground below sea level): the lowest ray of the frame
    # meets the ground about 1.5 heights away
    above_ground = max(distance - s.radius - max(ground, 0.0), 0.0)
    cam.data.clip_start = max(0.05, min(above_ground * 0.1, s.radius * 0.01))
    cam.data.clip_end = s.radius * 6.0


def place_in_planet_space(obj, planet_obj, pose, floating_origin=True):
    """Puts `obj` at `pose` (row-major 4x4, planet space, float64).  With
    floating_origin the planet's anchor moves to the pose's location first, so
    the object lands at the planet object's origin (the world origin for a
    planet at the origin) and everything near it keeps float32 precision."""
    location = [row[3] for row in pose[:3]]
    if floating_origin and runtime.set_anchor(planet_obj, location):
        runtime.mark_dirty(planet_obj)
    a = runtime.anchor(planet_obj)
    local = Matrix([list(row[:3]) + [row[3] - a[i]] for i, row in enumerate(pose[:3])]
                   + [[0.0, 0.0, 0.0, 1.0]])
    obj.matrix_world = planet_obj.matrix_world @ local


def place_flyby_cameras(scene):
    for obj in scene.objects:
        if obj.type == 'CAMERA' and obj.get(FLYBY_KEY):
            place_camera(obj, scene, scene.frame_current)


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
    geo = cameras.evaluated(obj, depsgraph).planet_lod_geo
    planet_obj = obj.planet_lod_geo.planet
    if not geo.enabled or planet_obj is None or not planet_obj.planet_lod.enabled:
        return
    s = planet_obj.planet_lod
    base = None
    try:
        if geo.altitude_reference == 'GROUND':
            planet = planets.build_planet(s.as_dict())
            sea = s.sea_level if s.use_sea_level else None
            base = ((lambda d: max(planet.height(*d), sea)) if sea is not None
                    else (lambda d: planet.height(*d)))
        elif geo.altitude_reference == 'SEA' and s.use_sea_level:
            base = (lambda d: s.sea_level)
    except core.REPORTED_ERRORS as exc:
        runtime.state(planet_obj).error = str(exc)
        return
    pose = flyby.geo_pose(s.radius, geo.longitude, geo.latitude, east=geo.east,
                         north=geo.north, altitude=geo.altitude, heading=geo.heading,
                         pitch=geo.pitch, roll=geo.roll, base_height=base)
    place_in_planet_space(obj, planet_obj, pose, floating_origin=geo.floating_origin)
    if geo.floating_origin:
        for other in _geo_objects(scene) if scene is not None else ():
            if other is not obj and other.planet_lod_geo.planet == planet_obj \
                    and not other.planet_lod_geo.floating_origin:
                place_geo_object(other, None, depsgraph)

