"""Placing cameras and objects in planet space: the flyby camera (its path is
planetlod.flyby.flyby_pose, a pure function of the frame number, so any
sub-range renders exactly the frames of the full path) and objects at a
planet-space pose, with the planet's floating origin moved to them."""
import math

import bpy
from mathutils import Matrix

from . import core, runtime
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
