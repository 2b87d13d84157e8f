"""The viewport's sky: the planet's sky world (atmosphere.build_world), the
same single-scattering model in GLSL, drawn behind the planet preview so that
the solid and Material Preview views show the sky a render gets, from orbit
(black, the lit limb) to the ground (blue, hazy at the horizon, the sun).

It fills only the pixels nothing else was drawn on (a triangle at the far
plane, depth-tested), and is drawn before the planet preview, so a planet
whose depth reaches the far plane (a huge clip range) still covers it; lit
by the scene's sun and shown through the scene's
exposure and view transform as the planet preview is.  The nearest planet
with an atmosphere and a preview gives the sky; in Rendered shading the
engine draws the world itself."""
import bpy
import gpu
from gpu_extras.batch import batch_for_shader
from mathutils import Matrix, Vector

from . import atmosphere, core, draw, runtime

_handle = None
_shaders = {}   # atmosphere key -> compiled sky shader
_error = ""


def sky_shader(atm):
    """The sky shader for atmosphere `atm`; None when it cannot be built."""
    global _error
    key = repr(sorted(atm.items()))
    if key in _shaders or _error:
        return _shaders.get(key)
    try:
        vert, frag = draw.shader_sources(draw.shader_defines(atm), "sky_preview_vert.glsl",
                                         "sky_preview_frag.glsl", libraries=())
        info = gpu.types.GPUShaderCreateInfo()
        info.push_constant('MAT3', "rays")    # NDC (x, y, 1) -> planet-space view ray
        info.push_constant('VEC4', "camera")  # the viewer (planet space), exposure
        info.push_constant('VEC4', "sun")     # direction (planet space), strength
        info.push_constant('INT', "display")  # 4 * the view transform
        info.push_constant('BOOL', "srgbTarget")
        info.vertex_in(0, 'VEC2', "pos")
        iface = gpu.types.GPUStageInterfaceInfo("plod_sky_iface")
        iface.smooth('VEC3', "v_ray")
        info.vertex_out(iface)
        info.fragment_out(0, 'VEC4', "FragColor")
        info.vertex_source(vert)
        info.fragment_source(frag)
        _shaders[key] = gpu.shader.create_from_info(info)
    except Exception as exc:  # keep the viewport alive
        _error = f"viewport sky shader failed: {exc}"
        print("planet_lod:", _error)
    return _shaders.get(key)


def view_rays(region_data, to_planet):
    """Matrix taking NDC (x, y, 1) to the planet-space direction of the
    view ray through that pixel.  A perspective view's rays meet a plane of
    constant depth at points linear in x and y; an orthographic view's rays
    are parallel."""
    to_view = region_data.window_matrix.inverted()
    rotation = to_planet.to_3x3() @ region_data.view_matrix.inverted().to_3x3()

    def ray(x, y):
        if not region_data.is_perspective:
            return rotation @ Vector((0.0, 0.0, -1.0))
        p = to_view @ Vector((x, y, -1.0, 1.0))
        return rotation @ (p.xyz / p.w)
    centre, right, up = ray(0.0, 0.0), ray(1.0, 0.0), ray(0.0, 1.0)
    columns = (right - centre, up - centre, centre)
    return Matrix([[columns[0][i], columns[1][i], columns[2][i]] for i in range(3)])


def eye_of(obj, region_data):
    """The viewer in planet space (metres, from the planet's centre)."""
    to_planet = obj.matrix_world.inverted_safe()
    return to_planet @ region_data.view_matrix.inverted().translation + \
        Vector(runtime.anchor(obj)), to_planet


def sky_planet(scene, region_data):
    """(planet, its atmosphere) whose sky the view shows: the one whose
    ground is nearest the viewer, among those previewed with an atmosphere
    whose sky world is the scene's world (as in a render: another world, or
    none, shows no planet sky)."""
    world = scene.world
    if world is None or not world.name.startswith(atmosphere.WORLD_PREFIX):
        return None, None
    best = None
    for obj in runtime.planet_objects(scene):
        s = obj.planet_lod
        atm = atmosphere.params(s)
        if atm is None or not s.gpu_preview or not obj.visible_get() or \
                runtime.existing_state(obj) is None or \
                world.name != atmosphere.WORLD_PREFIX + obj.name:
            continue
        eye, _ = eye_of(obj, region_data)
        height = eye.length - s.radius
        if height < 0.0:
            continue  # inside it (planets sharing a centre): not its sky
        if best is None or height < best[0]:
            best = (height, obj, atm)
    return (best[1], best[2]) if best else (None, None)


def draw_sky(scene, region_data):
    space = bpy.context.space_data
    if space is not None and getattr(space, "shading", None) is not None and \
            space.shading.type == 'RENDERED':
        return
    obj, atm = sky_planet(scene, region_data)
    if obj is None:
        return
    shader = sky_shader(atm)
    if shader is None:
        return
    eye, to_planet = eye_of(obj, region_data)
    sun, strength = atmosphere.sun_of(scene)
    if sun is not None:
        light = (to_planet.to_3x3() @ Vector(sun)).normalized()
    else:  # no sun: the render's sky is lit from above the camera
        light = eye.normalized() if eye.length > 0 else Vector((0.0, 0.0, 1.0))
        strength = 1.0
    view = scene.view_settings
    batch = batch_for_shader(shader, 'TRIS', {"pos": ((-1.0, -1.0), (3.0, -1.0), (-1.0, 3.0))})
    shader.bind()
    shader.uniform_float("rays", view_rays(region_data, to_planet))
    shader.uniform_float("camera", (eye.x, eye.y, eye.z, 2.0 ** view.exposure))
    shader.uniform_float("sun", (light.x, light.y, light.z, strength))
    shader.uniform_int("display", 4 * draw.VIEW_TRANSFORMS.get(view.view_transform, 2))
    batch.draw(shader)


def draw_callback():
    context = bpy.context
    if context.scene is None or context.region_data is None or core.native is None:
        return
    # only pixels still at the far plane take the sky (Blender's own drawing
    # done, the planet preview not yet: it draws over the sky)
    gpu.state.depth_test_set('LESS_EQUAL')
    gpu.state.depth_mask_set(False)
    try:
        draw_sky(context.scene, context.region_data)
    finally:
        gpu.state.depth_test_set('NONE')


def add_draw_handler():
    global _handle
    if _handle is None and not bpy.app.background:
        _handle = bpy.types.SpaceView3D.draw_handler_add(draw_callback, (), 'WINDOW', 'POST_VIEW')


def remove_draw_handler():
    global _handle, _error
    if _handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_handle, 'WINDOW')
        _handle = None
    _shaders.clear()
    _error = ""
