"""GPU viewport preview: draws each planet's visible surface with the GLSL in
shaders/, and the frozen LOD camera's frustum.

The preview draws the vertices the core emitted for the viewport's LOD
(surface.PreviewData): the surface a render gets, heights with the detail,
morphing, the sea lifted, the core's normals, relative to the planet's anchor
as the planet's mesh is.  Only the mesh's hand-off to Blender (seconds per
million triangles) is left out: the vertices go to the GPU in one upload.
It is lit by the scene's sun as the render is, seen through the render
material's haze (aerial perspective) and shown through the scene's
exposure and view transform.

GPU resources are cached per planet: the batch (the template's triangles
repeated for `capacity` sectors, grown by doubling, over a vertex index),
the surface texture the vertex shader reads its vertices from (two texels
per vertex), rebuilt when the preview changes, and the colour texture when
the colour map changes.  The surface goes up as a texture because a texture
is created from a NumPy buffer in one copy, where filling a vertex buffer
(`GPUVertBuf.attr_fill`) copies vertex by vertex, 4-5x slower.
"""
import os

import bpy
import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader
from mathutils import Matrix, Vector

from . import atmosphere, compat, core, mappaths, materials, runtime, terrain_shading

# The ground's colour: the render material's elevation ramp (and water on
# the sea), the colour map, or the sector levels' colours.
SHADING_RAMP, SHADING_COLOR_MAP, SHADING_LEVELS = 0, 1, 2

_handle = None
_shaders = {}        # atmosphere key -> compiled preview shader
_shader_error = ""
_cache = {}


def shader_error():
    """Why the GPU preview cannot draw ("" when it can), for the panel."""
    return _shader_error


def _glsl_float(value):
    return repr(float(value))


def _glsl_vec3(values):
    return "vec3(" + ", ".join(_glsl_float(v) for v in values) + ")"


def shader_defines(atm):
    """GLSL #defines of a planet's atmosphere (atmosphere.params), "" for none."""
    if atm is None:
        return ""
    values = {"ATM_RADIUS": _glsl_float(atm["radius"]),
              "ATM_RAYLEIGH": _glsl_vec3(atm["rayleigh"]),
              "ATM_MIE": _glsl_vec3(atm["mie"]),
              "ATM_RAYLEIGH_HEIGHT": _glsl_float(atm["rayleigh_height"]),
              "ATM_MIE_HEIGHT": _glsl_float(atm["mie_height"]),
              "ATM_MIE_G": _glsl_float(atm["mie_g"]),
              "ATM_GAIN": _glsl_float(atm["gain"]),
              "ATM_SKY_GAIN": _glsl_float(atm.get("sky_gain", 1.0))}
    return "#define PLOD_ATMOSPHERE\n" + "".join(f"#define {k} {v}\n" for k, v in values.items())


PREFIX = ("#define PLOD_PI 3.14159265358979\n"
          f"#define SHADING_RAMP {SHADING_RAMP}\n#define SHADING_COLOR_MAP {SHADING_COLOR_MAP}\n"
          f"#define SHADING_LEVELS {SHADING_LEVELS}\n" + terrain_shading.glsl_defines())


def shader_sources(defines="", vertex="planet_preview_vert.glsl",
                   fragment="planet_preview_frag.glsl", libraries=("planet_ground_types.glsl",)):
    """(vertex, fragment) GLSL; every fragment stage gets the display and
    atmosphere functions the planet's and the sky's previews share, then the
    `libraries` it needs (the planet's: its ground types)."""
    folder = next((d for d in core.resource_dirs("shaders") if os.path.isdir(d)), None)
    if folder is None:
        raise FileNotFoundError("shaders/ folder not found")

    def read(name):
        with open(os.path.join(folder, name)) as f:
            return f.read()
    shared = read("planet_display.glsl") + read("planet_atmosphere.glsl")
    shared += "".join(read(name) for name in libraries)
    return PREFIX + defines + read(vertex), PREFIX + defines + shared + read(fragment)


def preview_shader(atm=None):
    """The preview shader for a planet with atmosphere `atm` (None: airless)."""
    global _shader_error
    key = repr(sorted(atm.items())) if atm else ""
    if key in _shaders or _shader_error:
        return _shaders.get(key)
    try:
        vert, frag = shader_sources(shader_defines(atm))
        info = gpu.types.GPUShaderCreateInfo()
        # 128 bytes of push constants (as Blender counts them), the most
        # every GPU backend takes: 124 here
        info.push_constant('MAT4', "ModelViewProjectionMatrix")
        info.push_constant('VEC4', "anchor")  # planet space at the object's origin; height scale
        info.push_constant('VEC4', "sun")     # direction (planet space), strength
        info.push_constant('VEC4', "camera")  # the viewer (planet space), exposure
        # 4 * the view transform (VIEW_TRANSFORMS) + the ground's colour (SHADING_*)
        info.push_constant('INT', "display")
        # the colour map's footprint: radians per pixel, or minus planet-space
        # metres per pixel (orthographic)
        info.push_constant('FLOAT', "pixel_size")
        # set by Blender when it binds the shader: whether the framebuffer
        # encodes to sRGB on write (its own shaders read it the same way)
        info.push_constant('BOOL', "srgbTarget")
        info.sampler(0, 'FLOAT_2D', "color_map")
        info.sampler(1, 'FLOAT_2D', "surface")
        info.vertex_in(0, 'INT', "vertex_index")
        iface = gpu.types.GPUStageInterfaceInfo("plod_preview_iface")
        iface.smooth('VEC3', "v_point")
        iface.smooth('VEC3', "v_normal")
        iface.smooth('FLOAT', "v_height")
        iface.smooth('FLOAT', "v_sea")
        iface.smooth('FLOAT', "v_crest")
        iface.smooth('FLOAT', "v_level")  # one value per sector (one interpolation kind: Vulkan)
        info.vertex_out(iface)
        info.fragment_out(0, 'VEC4', "FragColor")
        info.vertex_source(vert)
        info.fragment_source(frag)
        _shaders[key] = gpu.shader.create_from_info(info)
    except Exception as exc:  # keep the viewport alive; the panel shows the reason
        _shader_error = f"GPU preview shader failed: {exc}"
        print("planet_lod:", _shader_error)
    return _shaders.get(key)


class PlanetGPU:
    def __init__(self):
        self.capacity = 0          # sectors the batch holds
        self.template_key = None   # (vertices, triangles) per sector
        self.batch = None
        self.surface_tex = None
        self.version = -1
        self.color_key = None
        self.color_tex = None
        self.state = None          # the runtime state whose preview this holds


def _dummy_texture():
    return gpu.types.GPUTexture((1, 1), format='RGBA32F',
                                data=gpu.types.Buffer('FLOAT', 4, [0.0, 0.0, 0.0, 1.0]))


def _ensure_batch(res, st):
    """The batch for `capacity` sectors (grown by doubling, so a growing LOD
    rebuilds it a few times only) and the surface texture of the planet's
    current preview.  Slots past the preview's vertices, and its free slots
    (sectors that left the view: zeros), draw nothing."""
    preview = st.preview
    tris = preview.template_triangles
    vt = preview.vertices_per_sector
    # a whole mesh's triangles are its own (a new batch with each preview,
    # one copy); a template's are the same for every sector of that size
    key = ("whole", st.gpu_version) if preview.whole else (vt, len(tris))
    count = preview.sector_count
    if res.batch is None or res.template_key != key or count > res.capacity:
        capacity = 1 if preview.whole else 64
        while capacity < max(count, res.capacity if res.template_key == key else 0):
            capacity *= 2
        fmt = gpu.types.GPUVertFormat()
        fmt.attr_add(id="vertex_index", comp_type='I32', len=1, fetch_mode='INT')
        vbo = gpu.types.GPUVertBuf(fmt, capacity * vt)
        vbo.attr_fill("vertex_index", np.arange(capacity * vt, dtype=np.int32))
        offsets = (np.arange(capacity, dtype=np.int32) * vt)[:, None, None]
        ibo = gpu.types.GPUIndexBuf(type='TRIS', seq=(tris[None, :, :] + offsets).reshape(-1, 3))
        res.batch = gpu.types.GPUBatch(type='TRIS', buf=vbo, elem=ibo)
        res.capacity, res.template_key = capacity, key
    if res.surface_tex is None or res.version != st.gpu_version:
        texels = preview.texels
        res.surface_tex = gpu.types.GPUTexture(
            (preview.row_texels, len(texels) // preview.row_texels), format='RGBA32F',
            data=gpu.types.Buffer('FLOAT', texels.size, texels))
        res.version = st.gpu_version


def _ensure_color(res, settings):
    """The colour map as a texture: the equirectangular image materials.py made
    (a cross-layout cube map is converted there, outside the draw callback)."""
    path = mappaths.resolve(settings.color_map)
    image = materials.color_image(settings, create=False) if path else None
    key = (path, image.name if image is not None else None)
    if res.color_key == key:
        return
    res.color_key, res.color_tex = key, None
    if image is None:
        return
    try:
        res.color_tex = gpu.texture.from_image(image)
    except (RuntimeError, OSError) as exc:
        print("planet_lod: preview colour map:", exc)


# How the preview's colour reaches the screen, after the scene's exposure, as
# the render is shown: the scene's view transform (the shader's grey-axis
# curves; others than these three are shown as AgX).
VIEW_TRANSFORMS = {"Standard": 0, "Filmic": 1, "AgX": 2}


def pixel_size(region_data, to_planet):
    """Radians per pixel of the view (perspective), or minus planet-space
    metres per pixel (orthographic), from the window matrix: its [1][1] is
    1 / tan(half the vertical field), or 2 / the height the view shows."""
    height = max(bpy.context.region.height if bpy.context.region else 1, 1)
    window = region_data.window_matrix
    per_pixel = 2.0 / (max(abs(window[1][1]), 1e-12) * height)
    if region_data.is_perspective:
        return per_pixel
    scale = to_planet.to_scale()
    return -per_pixel * (abs(scale.x) + abs(scale.y) + abs(scale.z)) / 3.0


def draw_planet(obj, st, region_data):
    s = obj.planet_lod
    shader = preview_shader(atmosphere.params(s))
    preview = st.preview
    if shader is None or preview is None or preview.vertex_count == 0:
        return
    res = _cache.get(obj.name_full)
    if res is None or res.state is not st:  # a renamed object can meet another's cache
        res = _cache[obj.name_full] = PlanetGPU()
        res.state = st
    _ensure_batch(res, st)
    _ensure_color(res, s)
    to_planet = obj.matrix_world.inverted_safe()
    anchor = Vector(runtime.anchor(obj))
    eye = to_planet @ region_data.view_matrix.inverted().translation + anchor
    sun, strength = atmosphere.sun_of(bpy.context.scene)
    if sun is not None:
        light = (to_planet.to_3x3() @ Vector(sun)).normalized()
    else:  # no sun: a light at the viewer
        light = eye.normalized() if eye.length > 0 else Vector((0.0, 0.0, 1.0))
        strength = 1.0
    view = bpy.context.scene.view_settings
    shader.bind()
    shader.uniform_float("ModelViewProjectionMatrix",
                         region_data.perspective_matrix @ obj.matrix_world)
    shader.uniform_float("anchor", (anchor.x, anchor.y, anchor.z, s.height_scale))
    shader.uniform_float("sun", (light.x, light.y, light.z, strength))
    shader.uniform_float("camera", (eye.x, eye.y, eye.z, 2.0 ** view.exposure))
    shading = SHADING_LEVELS if s.show_levels else \
        SHADING_COLOR_MAP if res.color_tex is not None else SHADING_RAMP
    shader.uniform_int("display", 4 * VIEW_TRANSFORMS.get(view.view_transform, 2) + shading)
    shader.uniform_float("pixel_size", pixel_size(region_data, to_planet))
    shader.uniform_sampler("color_map", res.color_tex or _dummy_texture())
    shader.uniform_sampler("surface", res.surface_tex)
    res.batch.draw(shader)


def frustum_lines(params, far_limit):
    """Line segments (planet space) of a camera frustum from planetlod.Camera params."""
    m = Matrix(params["matrix_world"])
    near = params["clip_start"]
    far = min(params["clip_end"], far_limit)
    rx, ry = params["resolution_x"], params["resolution_y"]
    aspect = rx / float(ry)
    if params["type"] == 'ORTHO':
        half_w = params["ortho_scale"] / 2.0
        corners = lambda d: [(x * half_w, y * half_w / aspect, -d) for x in (-1, 1) for y in (-1, 1)]
    else:
        sensor = params["sensor_width"] if aspect >= 1 else params["sensor_width"] * aspect
        t = sensor / 2.0 / params["lens"]
        corners = lambda d: [(x * t * d, y * t * d / aspect, -d) for x in (-1, 1) for y in (-1, 1)]
    n = [m @ Vector(c) for c in corners(near)]
    f = [m @ Vector(c) for c in corners(far)]
    order = (0, 1, 3, 2)
    lines = []
    for i in range(4):
        a, b = order[i], order[(i + 1) % 4]
        lines += [n[a], n[b], f[a], f[b], n[a], f[a]]
    return lines


def draw_frustum(obj, st):
    params = st.frozen_camera
    if not params:
        return
    world = obj.matrix_world @ Matrix.Translation(-Vector(runtime.anchor(obj)))
    coords = [tuple(world @ p) for p in frustum_lines(params, obj.planet_lod.radius * 4.0)]
    shader = gpu.shader.from_builtin(compat.UNIFORM_COLOR_SHADER)
    batch = batch_for_shader(shader, 'LINES', {"pos": coords})
    shader.bind()
    shader.uniform_float("color", (1.0, 0.8, 0.1, 1.0))
    batch.draw(shader)


def draw_callback():
    context = bpy.context
    scene = context.scene
    region_data = context.region_data
    if scene is None or region_data is None or core.native is None:
        return
    gpu.state.depth_test_set('LESS_EQUAL')
    gpu.state.depth_mask_set(True)
    # the far hemisphere faces away: culled, it cannot show through the near one
    # where the depth buffer cannot tell them apart
    gpu.state.face_culling_set('BACK')
    try:
        for obj in runtime.planet_objects(scene):
            s = obj.planet_lod
            st = runtime.existing_state(obj)
            if st is None or not obj.visible_get():
                continue
            if s.gpu_preview:
                draw_planet(obj, st, region_data)
            if s.freeze_lod:
                gpu.state.face_culling_set('NONE')
                draw_frustum(obj, st)
                gpu.state.face_culling_set('BACK')
    finally:
        gpu.state.face_culling_set('NONE')
        gpu.state.depth_mask_set(False)
        gpu.state.depth_test_set('NONE')


def add_draw_handler():
    global _handle
    if _handle is None and not bpy.app.background:
        _handle = bpy.types.SpaceView3D.draw_handler_add(draw_callback, (), 'WINDOW', 'POST_VIEW')


def remove_draw_handler():
    global _handle, _shader_error
    if _handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_handle, 'WINDOW')
        _handle = None
    _cache.clear()
    _shaders.clear()
    _shader_error = ""
