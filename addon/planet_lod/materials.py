"""Planet materials for Cycles and EEVEE, the LOD-level debug material, the ocean sphere.

Planet material: colour map sampled with the mesh's equirectangular `planet_uv`
attribute (written per vertex, unwrapped per sector so no seam), or, without a
colour map, an elevation ramp on the distance from the planet centre.
Debug material: hue from the per-face `sector_level` attribute.
Both shade with the core's normals (the `planet_normal` attribute), the same
on both sides of a sector border, in Cycles and EEVEE.
"""
import hashlib
import math
import os
from array import array

import bpy

from . import atmosphere, compat, core, mappaths, runtime, terrain_shading
from . import nodes as node_maths
from .core import surface

PLANET_PREFIX = "PlanetLOD "
LEVELS_NAME = "PlanetLOD levels"


def _new_tree(material):
    compat.use_node_tree(material)
    nodes = material.node_tree.nodes
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    out.location = (600, 0)
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.location = (300, 0)
    bsdf.inputs["Roughness"].default_value = 0.9
    compat.set_principled_specular(bsdf, 0.1)
    material.node_tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    return nodes, material.node_tree.links, bsdf


def _find_image(path):
    path = bpy.path.abspath(path)
    for image in bpy.data.images:
        if image.filepath and bpy.path.abspath(image.filepath) == path:
            return image
    return None


def _load_image(path):
    """The image of a map the artist chose; one Blender cannot read is a FileError."""
    image = _find_image(path)
    if image is not None:
        return image
    try:
        return bpy.data.images.load(bpy.path.abspath(path), check_existing=True)
    except RuntimeError as exc:  # Blender's "cannot read image"
        raise core.FileError(str(exc)) from exc


def is_cross_layout(width, height):
    """A 4:3 image is a cross-layout cube map (as planetlod.CubeMap.from_image reads it)."""
    return width > 0 and height > 0 and width * 3 == height * 4


def _file_stamp(path):
    st = os.stat(path)
    return f"{st.st_size}:{st.st_mtime_ns}"


def cube_to_equirect(path, projection, max_width=2048, progress=None):
    """(width, height, RGBA floats bottom row first) of the equirectangular image
    of a cross-layout cube map in `projection`, sampled with planetlod.CubeMap
    (the same lookup the heights use).  progress(fraction) is called per row."""
    module = core.native_or_raise()
    cube = module.CubeMap.from_image(path, projection=core.planets.projection_id(projection))
    width = min(max_width, 4 * cube.size)
    height = width // 2
    sample = cube.sample
    channels = cube.channels
    pixels = []
    lon_cos_sin = [(math.cos(lon), math.sin(lon)) for lon in
                   (-math.pi + (i + 0.5) / width * 2.0 * math.pi for i in range(width))]
    for j in range(height):  # Blender images: bottom row first
        lat = -0.5 * math.pi + (j + 0.5) / height * math.pi
        cl, sl = math.cos(lat), math.sin(lat)
        for c, s in lon_cos_sin:
            texel = sample(cl * c, cl * s, sl)
            if channels >= 3:
                pixels.extend((texel[0], texel[1], texel[2], texel[3] if channels == 4 else 1.0))
            else:
                pixels.extend((texel[0], texel[0], texel[0], 1.0))
        if progress is not None and j % 64 == 0:
            progress(j / float(height))
    return width, height, pixels


def _convert_with_progress(path, projection):
    wm = bpy.context.window_manager
    if wm:
        wm.progress_begin(0, 100)
    try:
        return cube_to_equirect(path, projection,
                                progress=(lambda f: wm.progress_update(int(100 * f)))
                                if wm else None)
    finally:
        if wm:
            wm.progress_end()


def equirect_cache_path(key):
    """Cache file prefix of the converted image for `key` (map path, stamp, projection):
    in the add-on's user cache folder (the extension's user folder in 4.2+)."""
    digest = hashlib.sha1(key.encode("utf-8")).hexdigest()[:24]
    return os.path.join(compat.user_cache_dir("equirect"), digest)


def cached_equirect(key, convert):
    """(width, height, RGBA floats) for `key`: read from the cache file written by an
    earlier conversion (another .blend or session), else convert() and write it.
    The file is raw float32 RGBA named <digest>-<width>x<height>.f32; a missing,
    short or unwritable cache only costs the conversion."""
    try:
        prefix = equirect_cache_path(key)
        for name in os.listdir(os.path.dirname(prefix)):
            if name.startswith(os.path.basename(prefix) + "-") and name.endswith(".f32"):
                w, h = (int(v) for v in name[len(os.path.basename(prefix)) + 1:-4].split("x"))
                pixels = array("f")
                with open(os.path.join(os.path.dirname(prefix), name), "rb") as f:
                    pixels.fromfile(f, w * h * 4)
                return w, h, pixels
    except (OSError, ValueError, EOFError):
        prefix = None
    w, h, pixels = convert()
    if prefix is not None:
        target = f"{prefix}-{w}x{h}.f32"
        try:
            with open(target + ".partial", "wb") as f:
                array("f", pixels).tofile(f)
            os.replace(target + ".partial", target)
        except OSError:
            pass
    return w, h, pixels


def color_image(settings, create=True):
    """The equirectangular bpy image for the planet's colour map, or None.
    A cross-layout cube map (4:3) is converted once to an equirectangular image
    (packed into the .blend, so it survives save/reload without the cache).
    create=False (draw callbacks, where ID data must not be added) only finds
    images that already exist."""
    path = mappaths.resolve(settings.color_map)
    if not path or not os.path.isfile(path):
        return None
    image = _load_image(path) if create else _find_image(path)
    if image is None:
        return None
    width, height = image.size
    if not is_cross_layout(width, height):
        return image
    key = f"{path}|{_file_stamp(path)}|{settings.projection}"
    for candidate in bpy.data.images:
        if candidate.get("planet_lod_source") == key:
            return candidate
    if not create:
        return None
    w, h, pixels = cached_equirect(key, lambda: _convert_with_progress(path, settings.projection))
    converted = bpy.data.images.new("PlanetLOD equirect " + os.path.basename(path), w, h)
    converted.pixels.foreach_set(pixels)
    converted.pack()
    converted["planet_lod_source"] = key
    if image.users == 0:
        bpy.data.images.remove(image)
    return converted


_attribute = terrain_shading.attribute


def shading_normal(b):
    """The core's normal (the mesh's `planet_normal` attribute, object space) in
    world space, normalised: what every planet BSDF shades with."""
    normal = _attribute(b, surface.NORMAL_ATTRIBUTE)
    transform = b.node("ShaderNodeVectorTransform")
    transform.vector_type = 'NORMAL'
    transform.convert_from = 'OBJECT'
    transform.convert_to = 'WORLD'
    b.links.new(normal.outputs["Vector"], transform.inputs["Vector"])
    return b.normalize(b.socket(transform.outputs["Vector"]))


HEIGHT_IMAGE_KEY = "planet_lod_sea_mask"


def _height_image(path):
    """The add-on's own image of an equirectangular height map (None for none or
    a cube cross); images no material uses any more go with forget_height_images."""
    if not path or not os.path.isfile(path):
        return None
    saved = mappaths.portable(path)  # kept in the .blend: a bundled map by its token
    image = next((i for i in bpy.data.images if i.get(HEIGHT_IMAGE_KEY) == saved), None)
    if image is None:
        try:
            image = bpy.data.images.load(path, check_existing=False)
        except RuntimeError as exc:  # Blender's "cannot read image"
            raise core.FileError(str(exc)) from exc
        image[HEIGHT_IMAGE_KEY], image.colorspace_settings.name = saved, 'Non-Color'
    if is_cross_layout(*image.size):
        bpy.data.images.remove(image)
        return None
    return image


def forget_height_images():
    for image in list(bpy.data.images):
        if image.get(HEIGHT_IMAGE_KEY) and image.users == 0:
            bpy.data.images.remove(image)


def _sea_mask(b, s):
    """1 on the sea, 0 on land: where the height map (if equirectangular) is at
    or below sea level, per pixel (a coarse LOD's triangles span coast and sea,
    their interpolated vertex heights would draw the coast as triangles), and
    where the mesh lifted ground below sea level (detail below the map's
    resolution floods low coasts)."""
    lifted = b.socket(_attribute(b, "planet_sea").outputs["Fac"], vector=False)
    # ground the mesh lifted to the sea surface (only close to lifted vertices:
    # a coarse triangle spanning the coast must not turn to water)
    flooded = b.smoothstep(0.8, 0.99, lifted)
    image = _height_image(mappaths.resolve(s.heightmap))
    if image is None:
        return flooded
    uv = _attribute(b, "planet_uv")
    tex = b.node("ShaderNodeTexImage")
    tex.image = image
    tex.extension = 'REPEAT'
    tex.interpolation = 'Cubic'
    b.links.new(uv.outputs["Vector"], tex.inputs["Vector"])
    metres = b.math("MULTIPLY", b.split(b.socket(tex.outputs["Color"]))[0], s.height_scale)
    # the coast halfway up the map's first step above the sea (8-bit Earth: 35 m)
    step = max(s.height_scale / 255.0, 1.0)
    return b.maximum(
        1.0 - b.smoothstep(s.sea_level + 0.25 * step, s.sea_level + 0.6 * step, metres), flooded)


def planet_material(obj):
    s = obj.planet_lod
    name = PLANET_PREFIX + obj.name
    material = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    color_map = mappaths.resolve(s.color_map)
    atm = atmosphere.params(s)
    key = (mappaths.portable(color_map), s.projection, round(s.radius, 3), round(s.height_scale, 3),
           s.use_sea_level, round(s.sea_level, 3), s.heightmap, repr(atm), s.use_detail,
           round(s.detail_amplitude, 3), 7)
    if material.get("planet_lod_key") == repr(key):
        return material
    compat.use_node_tree(material)
    tree = material.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.location = (600, 0)
    b = node_maths.Builder(tree)
    image = color_image(s)
    if image is not None:
        uv = _attribute(b, "planet_uv")
        tex = b.node("ShaderNodeTexImage")
        tex.image = image
        tex.extension = 'REPEAT'
        tex.interpolation = 'Cubic'
        b.links.new(uv.outputs["Vector"], tex.inputs["Vector"])
        base = b.socket(tex.outputs["Color"])
    else:  # elevation ramp over the height above the radius / sea level
        height = _attribute(b, "planet_height")
        remap = b.node("ShaderNodeMapRange")
        remap.inputs["From Min"].default_value = 0.0
        remap.inputs["From Max"].default_value = max(s.height_scale, 1.0)
        ramp = b.node("ShaderNodeValToRGB")
        elements = ramp.color_ramp.elements
        elements[0].color = (0.18, 0.16, 0.14, 1.0)
        elements[1].color = (0.92, 0.9, 0.88, 1.0)
        mid = elements.new(0.45)
        mid.color = (0.55, 0.42, 0.3, 1.0)
        b.links.new(height.outputs["Fac"], remap.inputs["Value"])
        b.links.new(remap.outputs["Result"], ramp.inputs["Fac"])
        base = b.socket(ramp.outputs["Color"])
    normal = shading_normal(b)
    ground_colour, relief = terrain_shading.ground_types(b, s, base, normal,
                                                         airless=atm is None)
    ground = b.node("ShaderNodeBsdfPrincipled")
    b.link(ground_colour, ground.inputs["Base Color"])
    ground.inputs["Roughness"].default_value = 0.9
    bump = b.node("ShaderNodeBump")
    bump.inputs["Strength"].default_value = 0.35
    bump.inputs["Distance"].default_value = 0.05
    b.link(relief, bump.inputs["Height"])
    b.link(normal, bump.inputs["Normal"])
    b.links.new(bump.outputs["Normal"], ground.inputs["Normal"])
    surface = ground.outputs[0]
    if s.use_sea_level:
        water = terrain_shading.water(b, normal)
        sea = _sea_mask(b, s)
        mix = b.node("ShaderNodeMixShader")
        b.link(sea, mix.inputs["Fac"])
        b.links.new(surface, mix.inputs[1])
        b.links.new(water.outputs[0], mix.inputs[2])
        surface = mix.outputs[0]
    if atm is not None:
        surface = atmosphere.aerial_perspective(b, atm, surface)
    tree.links.new(surface, out.inputs["Surface"])
    material["planet_lod_key"] = repr(key)
    forget_height_images()
    return material


def levels_material():
    material = bpy.data.materials.get(LEVELS_NAME)
    if material is not None:
        return material
    material = bpy.data.materials.new(LEVELS_NAME)
    nodes, links, bsdf = _new_tree(material)
    level = nodes.new("ShaderNodeAttribute")
    level.attribute_type = 'GEOMETRY'
    level.attribute_name = "sector_level"
    level.location = (-700, 0)
    scale = nodes.new("ShaderNodeMath")
    scale.operation = 'MULTIPLY'
    scale.inputs[1].default_value = 0.137
    scale.location = (-500, 0)
    fract = nodes.new("ShaderNodeMath")
    fract.operation = 'FRACT'
    fract.location = (-350, 0)
    ramp = nodes.new("ShaderNodeValToRGB")
    ramp.location = (-150, 0)
    ramp.color_ramp.color_mode = 'HSV'
    ramp.color_ramp.hue_interpolation = 'FAR'
    ramp.color_ramp.elements[0].color = (1.0, 0.1, 0.1, 1.0)
    ramp.color_ramp.elements[1].color = (1.0, 0.1, 0.12, 1.0)
    links.new(level.outputs["Fac"], scale.inputs[0])
    links.new(scale.outputs[0], fract.inputs[0])
    links.new(fract.outputs[0], ramp.inputs["Fac"])
    links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
    b = node_maths.Builder(material.node_tree, x0=-700, y0=-300)
    b.link(shading_normal(b), bsdf.inputs["Normal"])
    return material


def ensure(obj):
    """Assigns the planet or the debug material and keeps the ocean sphere in sync."""
    s = obj.planet_lod
    material = levels_material() if s.show_levels else planet_material(obj)
    mats = obj.data.materials
    if len(mats) == 0:
        mats.append(material)
    elif mats[0] != material:
        mats[0] = material
    atmosphere.ensure_world(obj, None)
    ensure_ocean(obj)


def ensure_ocean(obj):
    s = obj.planet_lod
    name = obj.name + " ocean"
    ocean = bpy.data.objects.get(name)
    want = s.ocean_sphere and s.use_sea_level
    if not want:
        if ocean is not None and ocean.get("planet_lod_ocean"):
            mesh = ocean.data
            bpy.data.objects.remove(ocean)
            if mesh.users == 0:
                bpy.data.meshes.remove(mesh)
        return
    radius = s.radius + s.sea_level
    if ocean is None:
        import bmesh
        mesh = bpy.data.meshes.new(name)
        bm = bmesh.new()
        bmesh.ops.create_uvsphere(bm, u_segments=128, v_segments=64, radius=1.0)
        bm.to_mesh(mesh)
        bm.free()
        for poly in mesh.polygons:
            poly.use_smooth = True
        ocean = bpy.data.objects.new(name, mesh)
        ocean["planet_lod_ocean"] = True
        for collection in obj.users_collection:
            collection.objects.link(ocean)
        ocean.parent = obj
        water = bpy.data.materials.get("PlanetLOD ocean") or bpy.data.materials.new("PlanetLOD ocean")
        water.diffuse_color = (0.02, 0.08, 0.25, 1.0)
        compat.use_node_tree(water)
        bsdf = water.node_tree.nodes.get("Principled BSDF")
        if bsdf is not None:
            bsdf.inputs["Base Color"].default_value = (0.01, 0.05, 0.2, 1.0)
            bsdf.inputs["Roughness"].default_value = 0.2
        mesh.materials.append(water)
    ocean.scale = (radius, radius, radius)
    ocean.location = tuple(-c for c in runtime.anchor(obj))  # the planet's centre
