"""The LOD camera a planet refines for, and the clip ranges fitted to planets.

* camera parameters (planetlod.Camera keyword arguments in planet space)
  from a camera object at render resolution or from the largest 3D
  viewport: which one a refresh uses (the render camera for renders, the
  viewport, the scene camera or a chosen camera otherwise);
* clip ranges: each 3D view's and the render camera's fitted to the
  horizon of the planets that ask for it;
* keyframed matrices: a camera's transform at a frame before the depsgraph
  has evaluated it (the clip range of an animation render's frame is set
  before the frame renders).
"""
import bpy
from mathutils import Matrix

from . import compat, core, runtime
from .core import planets as planet_settings


def _render_resolution(scene):
    r = scene.render
    return (max(1, r.resolution_x * r.resolution_percentage // 100),
            max(1, r.resolution_y * r.resolution_percentage // 100),
            r.pixel_aspect_x, r.pixel_aspect_y)


def camera_object(obj, scene):
    """The camera object the viewport's detail is made for when the planet asks
    for a camera (Scene Camera, Chosen Camera); None: the viewport itself."""
    s = obj.planet_lod
    if s.lod_camera == 'CAMERA' and s.camera is not None and s.camera.name in scene.objects:
        return s.camera
    if s.lod_camera in ('CAMERA', 'SCENE') and scene.camera is not None:
        return scene.camera
    return None


def render_camera(scene):
    """The camera renders see (F12, animations, flybys): always the scene camera."""
    return scene.camera


def evaluated(obj, depsgraph):
    """The evaluated object: during `-a` renders animation is evaluated in the
    render depsgraph only, the original objects keep frame-1 transforms."""
    if depsgraph is None:
        return obj
    try:
        return obj.evaluated_get(depsgraph)
    except (ReferenceError, RuntimeError):
        return obj


def camera_params_from_object(obj, cam, scene, depsgraph=None, cam_matrix=None):
    """planetlod.Camera keyword arguments for a camera object at render resolution
    (cam_matrix: its world matrix, when known better than cam.matrix_world)."""
    cam = evaluated(cam, depsgraph)
    data = cam.data
    res_x, res_y, asp_x, asp_y = _render_resolution(scene)
    planet = evaluated(obj, depsgraph)
    local = planet.matrix_world.inverted_safe() @ (
        cam_matrix if cam_matrix is not None else cam.matrix_world)
    matrix = [list(row) for row in local]
    for i, a in enumerate(runtime.anchor(obj)):
        matrix[i][3] += a
    return dict(matrix_world=matrix,
                type='ORTHO' if data.type == 'ORTHO' else 'PERSP', lens=data.lens,
                sensor_width=data.sensor_width, sensor_height=data.sensor_height,
                sensor_fit=data.sensor_fit, ortho_scale=data.ortho_scale,
                shift_x=data.shift_x, shift_y=data.shift_y, clip_start=data.clip_start,
                clip_end=data.clip_end, resolution_x=res_x, resolution_y=res_y,
                pixel_aspect_x=asp_x, pixel_aspect_y=asp_y)


def viewport():
    """(space, region, region_3d) of the largest 3D viewport, or None."""
    best = None
    wm = bpy.context.window_manager
    for window in wm.windows if wm else ():
        for area in window.screen.areas:
            if area.type != 'VIEW_3D':
                continue
            for region in area.regions:
                if region.type == 'WINDOW' and (best is None or
                                                region.width * region.height > best[1].width * best[1].height):
                    best = (area.spaces.active, region, area.spaces.active.region_3d)
    return best


def view_to_world(r3d):
    """The view's camera matrix from its location, rotation and distance: current
    as soon as they are set (view_matrix is only updated when the view redraws)."""
    return (Matrix.Translation(r3d.view_location) @ r3d.view_rotation.to_matrix().to_4x4()
            @ Matrix.Translation((0.0, 0.0, r3d.view_distance)))


def camera_params_from_view(obj, view):
    space, region, r3d = view
    matrix = runtime.to_planet_space(obj, view_to_world(r3d))
    ortho = r3d.view_perspective == 'ORTHO'
    return dict(matrix_world=matrix, type='ORTHO' if ortho else 'PERSP',
                lens=space.lens, sensor_width=72.0, sensor_height=72.0, sensor_fit='AUTO',
                ortho_scale=max(r3d.view_distance * 72.0 / space.lens, 1e-6),
                clip_start=space.clip_start, clip_end=space.clip_end,
                resolution_x=max(region.width, 1), resolution_y=max(region.height, 1))


def lod_camera_params(obj, scene, for_render=False, depsgraph=None):
    """Keyword arguments for planetlod.Camera, or None when there is no camera at all.

    Renders (for_render) always refine for the render camera, whatever the
    viewport shows, so a render never gets the viewport's detail.  The viewport
    refines for itself (or, looking through the camera, for that camera), or for
    the camera the planet names; without a viewport (background) it falls back
    to the scene camera."""
    if for_render:
        cam = render_camera(scene)
        return None if cam is None else camera_params_from_object(obj, cam, scene, depsgraph)
    s = obj.planet_lod
    cam = camera_object(obj, scene)
    if (s.lod_camera == 'VIEWPORT' or cam is None) and not bpy.app.background:
        view = viewport()
        if view is not None:
            if view[2].view_perspective == 'CAMERA' and scene.camera is not None:
                return camera_params_from_object(obj, scene.camera, scene)
            return camera_params_from_view(obj, view)
    cam = cam or render_camera(scene)
    if cam is None:
        return None
    return camera_params_from_object(obj, cam, scene, depsgraph)


# ---- clip ranges ------------------------------------------------------------------
# The horizon-distance correction (K. Gasiński's HRTMR, master's thesis,
# Gdańsk University of Technology, 2010): the nearest
# terrain cannot be closer than the camera's height above the highest peak and
# nothing beyond the horizon plus the distance at which the highest peak still
# rises over it can be seen.  Clipping there keeps depth precision where the
# terrain is and cuts the far hemisphere away.

def _scale(obj):
    return max(obj.matrix_world.to_scale()) or 1.0


def view_clip(obj, planet, params):
    """(clip_start, clip_end) in scene units for a viewport camera: Gasiński's
    range, with a clip start of a tenth of the height above the ground below the
    camera where the camera is lower than the highest peak (his clip
    start is then ~0) and at most a million times shorter than the clip end."""
    near, far = planet.recommended_clip(planet_settings.make_camera(params))
    eye = [row[3] for row in params["matrix_world"][:3]]
    distance = sum(c * c for c in eye) ** 0.5
    if distance > 0.0:
        ground = planet.radius + planet.height(*(c / distance for c in eye))
        near = max(near, 0.1 * (distance - ground))
    near = _depth_safe_near(near, far)
    scale = _scale(obj)
    return near * scale, far * scale


def _depth_safe_near(near, far):
    """A clip start no more than a million times shorter than the clip end (and
    at least 1 mm): below the highest peak Gasiński's clip start is ~0, and a
    rasterizer's depth buffer (the viewport, EEVEE) then cannot order surfaces
    kilometres away -- the far side beyond the horizon shows through the
    ground in front of it."""
    return max(near, far * 1e-6, 1e-3)


def fit_view_clips(scene):
    """Fits each 3D view's clip range to the planets it shows (those with Viewport
    Clip to Horizon on); views looking through the camera use its clip range."""
    targets = []
    for obj in runtime.planet_objects(scene):
        if obj.planet_lod.view_clip_from_horizon and obj.visible_get():
            try:
                targets.append((obj, planet_settings.build_planet(obj.planet_lod.as_dict())))
            except core.REPORTED_ERRORS:
                continue
    if not targets:
        return
    wm = bpy.context.window_manager
    for window in wm.windows if wm else ():
        for area in window.screen.areas:
            if area.type != 'VIEW_3D':
                continue
            space = area.spaces.active
            region = next((r for r in area.regions if r.type == 'WINDOW'), None)
            r3d = space.region_3d
            if region is None or r3d is None or r3d.view_perspective == 'CAMERA':
                continue
            near = far = None
            for obj, planet in targets:
                try:
                    n, f = view_clip(obj, planet, camera_params_from_view(obj, (space, region, r3d)))
                except core.REPORTED_ERRORS:
                    continue
                near = n if near is None else min(near, n)
                far = f if far is None else max(far, f)
            if near is None:
                continue
            if not (0.97 < space.clip_start / near < 1.03 and 0.97 < space.clip_end / far < 1.03):
                space.clip_start, space.clip_end = near, far
                area.tag_redraw()


def keyframed_matrix(obj, frame):
    """obj's world matrix at `frame` from its keyframed location, rotation and
    scale, before the depsgraph has evaluated that frame (frame_change_pre);
    None for objects with a parent or constraints (the depsgraph's job)."""
    anim = obj.animation_data
    if anim is None or anim.action is None or obj.parent is not None or obj.constraints:
        return None
    loc, rot, scale = obj.location.copy(), obj.rotation_euler.copy(), obj.scale.copy()
    if obj.rotation_mode not in ('XYZ', 'XZY', 'YXZ', 'YZX', 'ZXY', 'ZYX'):
        return None
    targets = {"location": loc, "rotation_euler": rot, "scale": scale}
    for fcurve in compat.action_fcurves(obj):
        target = targets.get(fcurve.data_path)
        if target is not None and 0 <= fcurve.array_index < 3 and not fcurve.mute:
            target[fcurve.array_index] = fcurve.evaluate(frame)
    return Matrix.LocRotScale(loc, rot, scale)


def apply_camera_clip(scene, depsgraph=None, cam_matrix=None):
    """Sets the render camera's clip range from the horizon of the planets that
    ask for it (Camera Clip to Horizon): the union of their ranges.  Returns it
    (None: nothing set)."""
    cam = render_camera(scene)
    if cam is None or cam.type != 'CAMERA':
        return None
    near = far = None
    for obj in runtime.planet_objects(scene):
        if not obj.planet_lod.clip_from_horizon:
            continue
        try:
            planet = planet_settings.build_planet(obj.planet_lod.as_dict())
            params = camera_params_from_object(obj, cam, scene, depsgraph, cam_matrix)
            n, f = planet.recommended_clip(planet_settings.make_camera(params))
        except core.REPORTED_ERRORS:
            continue
        n, f = _depth_safe_near(n, f) * _scale(obj), f * _scale(obj)
        near = n if near is None else min(near, n)
        far = f if far is None else max(far, f)
    if near is None:
        return None
    data = cam.data
    if abs(data.clip_start - near) > 1e-6 * near or abs(data.clip_end - far) > 1e-6 * far:
        data.clip_start, data.clip_end = near, far
        data.update_tag()
    return near, far


def with_clip(params, clip):
    """Camera params with the clip range just set on the camera: an evaluated
    camera (animation renders) still has the old one."""
    if params is not None and clip is not None:
        params = dict(params, clip_start=clip[0], clip_end=clip[1])
    return params



def fit_render_clip(scene, keyframed_only=False):
    """Camera Clip to Horizon for the current frame, from the render camera's
    keyframes where it has them (the original object still holds another
    frame's transform during animation renders).  Returns the range or None."""
    cam = render_camera(scene)
    if cam is None:
        return None
    matrix = keyframed_matrix(cam, scene.frame_current + scene.frame_subframe)
    if matrix is None and keyframed_only:
        return None
    return apply_camera_clip(scene, cam_matrix=matrix)

