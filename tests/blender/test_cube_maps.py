"""Cube-map inputs: a cross-layout (4:3) height map and colour map work like the
equirectangular originals -- heights agree, and the colour map the material
samples (converted to equirectangular through planetlod.CubeMap) matches the
original Blue Marble."""
import math
import os

import bpy

import plod_testlib as lib


def image_pixels(image):
    w, h = image.size
    return w, h, list(image.pixels)


def texel(w, h, px, lon_deg, lat_deg):
    """RGB of an equirectangular image (bottom row first) at lon/lat."""
    i = min(w - 1, int((lon_deg + 180.0) / 360.0 * w))
    j = min(h - 1, int((lat_deg + 90.0) / 180.0 * h))
    k = (j * w + i) * 4
    return px[k:k + 3]


def main():
    lib.enable()
    from planet_lod import core, materials
    lib.clear_scene()
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 160, 90
    lib.add_camera((0, -3.0e7, 0))
    native = core.native
    out = lib.out_dir()
    height_cross = os.path.join(out, "earth_height_cross.png")
    color_cross = os.path.join(out, "earth_color_cross.png")
    native.CubeMap.from_image(core.data_path("earth-topology.png"), projection="qsc",
                              size=256, channels=1).save(height_cross)
    native.CubeMap.from_image(core.data_path("earth-blue-marble.jpg"), projection="qsc",
                              size=256, channels=3).save(color_cross)

    assert bpy.ops.mesh.planet_add(preset='EARTH', quality='DRAFT', heightmap=height_cross,
                                   color_map=color_cross) == {'FINISHED'}
    cube_planet = bpy.context.object
    assert len(cube_planet.data.polygons) > 0
    # heights from the cube map agree with those of the equirectangular original
    equirect = core.planets.build_planet(dict(cube_planet.planet_lod.as_dict(),
                                      heightmap=core.data_path("earth-topology.png")))
    cubed = core.planets.build_planet(cube_planet.planet_lod.as_dict())
    diffs, land = [], 0
    for lat in range(-60, 75, 15):
        for lon in range(-180, 180, 20):
            la, lo = math.radians(lat), math.radians(lon)
            d = (math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la))
            a, b = equirect.height(*d), cubed.height(*d)
            land += a > 50.0
            diffs.append(abs(a - b))
    mean = sum(diffs) / len(diffs)
    print(f"heights: {land} land samples, mean |equirect - cube| = {mean:.1f} m")
    assert land > 10 and mean < 150.0, mean

    # the colour map: converted once to a packed 2:1 image used by the material
    image = materials.color_image(cube_planet.planet_lod)
    assert image is not None and image.packed_file is not None
    w, h, px = image_pixels(image)
    assert w == 2 * h == 1024, (w, h)
    tree = cube_planet.active_material.node_tree
    tex = next(n for n in tree.nodes if n.type == 'TEX_IMAGE')
    assert tex.image == image
    original = bpy.data.images.load(core.data_path("earth-blue-marble.jpg"))
    original.scale(1024, 512)  # same resolution as the converted image (and fast to read)
    ow, oh, opx = image_pixels(original)
    err, n = 0.0, 0
    for lat in range(-75, 80, 5):
        for lon in range(-178, 180, 7):
            a, b = texel(w, h, px, lon, lat), texel(ow, oh, opx, lon, lat)
            err += sum(abs(x - y) for x, y in zip(a, b)) / 3.0
            n += 1
    print(f"colour: mean |converted - original| = {err / n:.3f} over {n} samples")
    assert err / n < 0.06, err / n
    # the conversion is cached on disk (the add-on's user cache folder): a new
    # .blend or session reads the same pixels instead of converting again
    key = image["planet_lod_source"]
    cached = [n for n in os.listdir(os.path.dirname(materials.equirect_cache_path(key)))
              if n.startswith(os.path.basename(materials.equirect_cache_path(key)))]
    assert cached == [os.path.basename(materials.equirect_cache_path(key)) + "-1024x512.f32"], \
        cached
    calls = []
    cw, ch, cpx = materials.cached_equirect(key, lambda: calls.append(1))
    assert not calls and (cw, ch) == (w, h)
    # (the image holds 8-bit texels, the cache the floats they were rounded from)
    assert max(abs(a - b) for a, b in zip(cpx[::997], px[::997])) < 0.5 / 255 + 1e-6
    # a second planet with the same cube colour map reuses the converted image
    def colour_images():  # not counting the sea masks' height-map images
        return [i.name for i in bpy.data.images if not i.get(materials.HEIGHT_IMAGE_KEY)]
    count = len(colour_images())
    assert bpy.ops.mesh.planet_add(preset='EARTH', quality='DRAFT',
                                   color_map=color_cross) == {'FINISHED'}
    assert len(colour_images()) == count, colour_images()


lib.run(main)
