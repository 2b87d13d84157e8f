"""GPU viewport preview: draws each planet's visible sectors with the GLSL in
shaders/ (template barycentrics + per-sector corner texture, heights from a
cube-map face atlas in the vertex shader), and the frozen LOD camera's frustum.

GPU resources are cached per planet and rebuilt only when needed: the vertex
and index buffers when the sector count outgrows their capacity (or the
template changes), the sector texture when the LOD changes, the height atlas
when the height map changes.
"""
import math
import os

import bpy
import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader
from mathutils import Matrix, Vector

from . import atmosphere, compat, core, live, materials

DATA_WIDTH = 768          # sector texture width (texels); 3 texels per sector
HEIGHT_ATLAS_SIZE = 256   # face size of the preview's height cube map
_handle = None
_shader = None
_shader_error = ""
_cache = {}


def shader_error():
    """Why the GPU preview cannot draw ("" when it can), for the panel."""
    return _shader_error


def shader_sources():
    folder = next((d for d in core.resource_dirs("shaders") if os.path.isdir(d)), None)
    if folder is None:
        raise FileNotFoundError("shaders/ folder not found")

    def read(name):
        with open(os.path.join(folder, name)) as f:
            return f.read()
    common = read("planet_common.glsl")
    return (common + read("planet_preview_vert.glsl"), common + read("planet_preview_frag.glsl"))


def preview_shader():
    global _shader, _shader_error
    if _shader is not None or _shader_error:
        return _shader
    try:
        vert, frag = shader_sources()
        info = gpu.types.GPUShaderCreateInfo()
        info.push_constant('MAT4', "ModelViewProjectionMatrix")
        info.push_constant('FLOAT', "radius")
        info.push_constant('FLOAT', "height_scale")
        info.push_constant('FLOAT', "height_offset")
        info.push_constant('FLOAT', "height_norm")
        info.push_constant('INT', "template_vertices")
        info.push_constant('INT', "sector_count")
        info.push_constant('INT', "data_width")
        info.push_constant('INT', "projection")
        info.push_constant('INT', "has_height")
        info.push_constant('INT', "has_color")
        info.push_constant('INT', "show_levels")
        info.push_constant('VEC3', "light_dir")
        info.sampler(0, 'FLOAT_2D', "sector_data")
        info.sampler(1, 'FLOAT_2D', "height_atlas")
        info.sampler(2, 'FLOAT_2D', "color_map")
        info.vertex_in(0, 'VEC3', "bary")
        iface = gpu.types.GPUStageInterfaceInfo("plod_preview_iface")
        iface.smooth('VEC3', "v_dir")
        iface.smooth('FLOAT', "v_level")
        iface.smooth('FLOAT', "v_height")
        iface.smooth('VEC3', "v_normal")
        info.vertex_out(iface)
        info.fragment_out(0, 'VEC4', "FragColor")
        info.vertex_source(vert)
        info.fragment_source(frag)
        _shader = gpu.shader.create_from_info(info)
    except Exception as exc:  # keep the viewport alive; the panel shows the reason
        _shader_error = f"GPU preview shader failed: {exc}"
        print("planet_lod:", _shader_error)
    return _shader


PROJECTION_CODES = {"TSC": 0, "CSC": 1, "QSC": 2, "SPHERIFIED": 3, "CAR": 4}


class PlanetGPU:
    def __init__(self):
        self.capacity = 0
        self.template_vertices = 0
        self.template_key = None
        self.batch = None
        self.sector_tex = None
        self.sector_version = -1
        self.sector_count = 0
        self.height_key = None
        self.height_tex = None
        self.height_norm = 1.0
        self.color_key = None
        self.color_tex = None


def _dummy_texture():
    return gpu.types.GPUTexture((1, 1), format='RGBA32F',
                                data=gpu.types.Buffer('FLOAT', 4, [0.0, 0.0, 0.0, 1.0]))


def _float_buffer(array):
    array = np.ascontiguousarray(array, dtype=np.float32).ravel()
    return gpu.types.Buffer('FLOAT', array.size, array)


def _ensure_batch(res, shader, inst, count):
    """One vertex buffer repeating the template for `capacity` sectors (grown by
    doubling, so a growing LOD rebuilds it a few times only), built with numpy."""
    bary = np.frombuffer(inst["template_barycentrics"], dtype=np.float32).reshape(-1, 3)
    tris = np.frombuffer(inst["template_triangles"], dtype=np.int32).reshape(-1, 3)
    vt = len(bary)
    key = (vt, len(tris))
    if res.batch is not None and res.template_key == key and count <= res.capacity:
        return
    capacity = 64
    while capacity < max(count, res.capacity if res.template_key == key else 0):
        capacity *= 2
    coords = np.tile(bary, (capacity, 1))
    offsets = (np.arange(capacity, dtype=np.int32) * vt)[:, None, None]
    indices = (tris[None, :, :] + offsets).reshape(-1, 3)
    res.batch = batch_for_shader(shader, 'TRIS', {"bary": coords}, indices=indices)
    res.capacity, res.template_vertices, res.template_key = capacity, vt, key


def _ensure_sector_texture(res, st, inst):
    if res.sector_version == st.gpu_version and res.sector_tex is not None:
        return
    corners = np.frombuffer(inst["corners"], dtype=np.float32).reshape(-1, 3)
    levels = np.frombuffer(inst["levels"], dtype=np.float32)
    count = len(levels)
    texels = max(3 * count, 1)
    rows = (texels + DATA_WIDTH - 1) // DATA_WIDTH
    data = np.zeros((DATA_WIDTH * rows, 4), dtype=np.float32)
    data[:3 * count, :3] = corners[:3 * count]
    data[:3 * count, 3] = np.repeat(levels, 3)
    res.sector_tex = gpu.types.GPUTexture((DATA_WIDTH, rows), format='RGBA32F',
                                          data=_float_buffer(data))
    res.sector_version, res.sector_count = st.gpu_version, count


def _ensure_height(res, settings):
    path = bpy.path.abspath(settings.heightmap) if settings.heightmap else ""
    key = (path, settings.projection)
    if res.height_key == key:
        return
    res.height_key, res.height_tex = key, None
    module = core.native
    if not path or not os.path.isfile(path) or not hasattr(module, "CubeMap"):
        return
    try:
        cube = module.CubeMap.from_image(path, projection=core.PROJECTION_IDS[settings.projection],
                                         size=HEIGHT_ATLAS_SIZE, channels=1)
    except core.native_errors() as exc:
        print("planet_lod: preview height map:", exc)
        return
    faces = 1 if settings.projection == 'CAR' else 6
    size = cube.size
    face_w = 2 * size if faces == 1 else size
    # texels of any type (u8, u16, f32) as floats; the shader scales by height_norm
    dtype = {"u8": np.uint8, "u16": np.uint16}.get(cube.dtype, np.float32)
    norm = {"u8": 1.0 / 255.0, "u16": 1.0 / 65535.0}.get(cube.dtype, 1.0)
    channels = cube.channels
    atlas = np.hstack([np.frombuffer(cube.face(f), dtype=dtype)
                       .reshape(size, face_w, channels)[:, :, 0] for f in range(faces)])
    res.height_tex = gpu.types.GPUTexture((face_w * faces, size), format='R32F',
                                          data=_float_buffer(atlas))
    res.height_norm = norm


def _ensure_color(res, settings):
    """The colour map as a texture: the equirectangular image materials.py made
    (a cross-layout cube map is converted there, outside the draw callback)."""
    path = bpy.path.abspath(settings.color_map) if settings.color_map else ""
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


def draw_planet(obj, st, region_data):
    shader = preview_shader()
    inst = st.instances
    if shader is None or not inst:
        return
    res = _cache.setdefault(obj.name_full, PlanetGPU())
    count = len(inst["levels"])
    if count == 0:
        return
    s = obj.planet_lod
    _ensure_batch(res, shader, inst, count)
    _ensure_sector_texture(res, st, inst)
    _ensure_height(res, s)
    _ensure_color(res, s)
    dummy = _dummy_texture()
    # planet space -> world through the floating origin (the anchor)
    planet_to_world = obj.matrix_world @ Matrix.Translation(-Vector(live.anchor(obj)))
    eye = planet_to_world.inverted_safe() @ region_data.view_matrix.inverted().translation
    sun = atmosphere.sun_of(bpy.context.scene)[0]  # the render's light, else the viewer's
    light = Vector(sun) if sun is not None else eye.normalized() if eye.length > 0 \
        else Vector((0, 0, 1))
    shader.bind()
    shader.uniform_float("ModelViewProjectionMatrix",
                         region_data.perspective_matrix @ planet_to_world)
    shader.uniform_float("radius", s.radius)
    shader.uniform_float("height_scale", s.height_scale)
    shader.uniform_float("height_offset", s.height_offset)
    shader.uniform_float("height_norm", res.height_norm)
    shader.uniform_int("template_vertices", res.template_vertices)
    shader.uniform_int("sector_count", res.sector_count)
    shader.uniform_int("data_width", DATA_WIDTH)
    shader.uniform_int("projection", PROJECTION_CODES[s.projection])
    shader.uniform_int("has_height", 1 if res.height_tex is not None else 0)
    shader.uniform_int("has_color", 1 if res.color_tex is not None else 0)
    shader.uniform_int("show_levels", 1 if s.show_levels else 0)
    shader.uniform_float("light_dir", light)
    shader.uniform_sampler("sector_data", res.sector_tex)
    shader.uniform_sampler("height_atlas", res.height_tex or dummy)
    shader.uniform_sampler("color_map", res.color_tex or dummy)
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
    world = obj.matrix_world @ Matrix.Translation(-Vector(live.anchor(obj)))
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
        for obj in live.planets(scene):
            s = obj.planet_lod
            st = live.RUNTIME.get(obj.name_full)
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


def register():
    global _handle
    if _handle is None and not bpy.app.background:
        _handle = bpy.types.SpaceView3D.draw_handler_add(draw_callback, (), 'WINDOW', 'POST_VIEW')


def unregister():
    global _handle, _shader, _shader_error
    if _handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_handle, 'WINDOW')
        _handle = None
    _cache.clear()
    _shader, _shader_error = None, ""
