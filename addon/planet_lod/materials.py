"""Planet materials for Cycles and EEVEE, the LOD-level debug material, the ocean sphere.

Planet material: colour map sampled with the mesh's equirectangular `planet_uv`
attribute (written per vertex, unwrapped per sector so no seam), or, without a
colour map, an elevation ramp on the distance from the planet centre.
Debug material: hue from the per-face `sector_level` attribute.
"""
import os

import bpy

PLANET_PREFIX = "PlanetLOD "
LEVELS_NAME = "PlanetLOD levels"


def _new_tree(material):
    material.use_nodes = True
    nodes = material.node_tree.nodes
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    out.location = (600, 0)
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.location = (300, 0)
    bsdf.inputs["Roughness"].default_value = 0.9
    bsdf.inputs["Specular"].default_value = 0.1
    material.node_tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    return nodes, material.node_tree.links, bsdf


def _load_image(path):
    path = bpy.path.abspath(path)
    for image in bpy.data.images:
        if image.filepath and bpy.path.abspath(image.filepath) == path:
            return image
    return bpy.data.images.load(path, check_existing=True)


def planet_material(obj):
    s = obj.planet_lod
    name = PLANET_PREFIX + obj.name
    material = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    color_map = bpy.path.abspath(s.color_map) if s.color_map else ""
    key = (color_map, round(s.radius, 3), round(s.height_scale, 3))
    if material.get("planet_lod_key") == repr(key):
        return material
    nodes, links, bsdf = _new_tree(material)
    if color_map and os.path.isfile(color_map):
        uv = nodes.new("ShaderNodeAttribute")
        uv.attribute_type = 'GEOMETRY'
        uv.attribute_name = "planet_uv"
        uv.location = (-400, 0)
        tex = nodes.new("ShaderNodeTexImage")
        tex.location = (-150, 0)
        tex.image = _load_image(color_map)
        tex.extension = 'REPEAT'
        links.new(uv.outputs["Vector"], tex.inputs["Vector"])
        links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    else:  # elevation ramp: distance from the centre, radius .. radius + height_scale
        coords = nodes.new("ShaderNodeTexCoord")
        coords.location = (-800, 0)
        length = nodes.new("ShaderNodeVectorMath")
        length.operation = 'LENGTH'
        length.location = (-600, 0)
        remap = nodes.new("ShaderNodeMapRange")
        remap.location = (-400, 0)
        remap.inputs["From Min"].default_value = s.radius
        remap.inputs["From Max"].default_value = s.radius + max(s.height_scale, 1.0)
        ramp = nodes.new("ShaderNodeValToRGB")
        ramp.location = (-150, 0)
        elements = ramp.color_ramp.elements
        elements[0].color = (0.18, 0.16, 0.14, 1.0)
        elements[1].color = (0.92, 0.9, 0.88, 1.0)
        mid = elements.new(0.45)
        mid.color = (0.55, 0.42, 0.3, 1.0)
        links.new(coords.outputs["Object"], length.inputs[0])
        links.new(length.outputs["Value"], remap.inputs["Value"])
        links.new(remap.outputs["Result"], ramp.inputs["Fac"])
        links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
    material["planet_lod_key"] = repr(key)
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
        water.use_nodes = True
        bsdf = water.node_tree.nodes.get("Principled BSDF")
        if bsdf is not None:
            bsdf.inputs["Base Color"].default_value = (0.01, 0.05, 0.2, 1.0)
            bsdf.inputs["Roughness"].default_value = 0.2
        mesh.materials.append(water)
    ocean.scale = (radius, radius, radius)
