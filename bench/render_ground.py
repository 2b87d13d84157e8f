"""Ground renders of the Earth preset in Cycles, run inside Blender:

    blender -b --factory-startup --python bench/render_ground.py -- \\
        --out DIR [--size 480x270] [--samples 8] [--white] [--jacksboro-inset]
        [--shot NAME,LON,LAT,ALTITUDE,HEADING,PITCH ...] [--metrics FILE]
        [--band BOTTOM,TOP]

(the add-on found through $BLENDER_USER_SCRIPTS/addons/planet_lod, the module
through $PLANET_LOD_NATIVE, as the Blender tests run it).  Each --shot places
the camera with the add-on's planet placement (altitude above the ground,
heading from north, pitch above the horizon) and renders DIR/NAME.png.  One
sun stands 20 degrees above the horizon at each place, 90 degrees right of
the view.

--white: the white-diffuse pass (every planet face a white diffuse surface
shaded with the core's normals, no sky, no haze, direct sunlight alone):
what is left of the picture is the relief lit by the sun, its shadows black.  --metrics writes, per shot, the
ground's fine-scale luminance variation: the mean absolute difference
between the luminance and its 5x5 box blur over the pixels below the
horizon, relative to their mean luminance (relief shows as shading that
changes from pixel to pixel; smooth blobs score low), and the count of dark
specks: pixels under half the median luminance of their eight lit
neighbours (black pixels along ridges; in the white pass a cast shadow one
pixel wide counts too, and at few samples so does the noise of a sky-lit
picture).
--jacksboro-inset places matplotlib's sample DEM of the Jacksboro fault
(Tennessee, 3 arc-seconds) as an inset at its own coordinates: the real
terrain, rendered as the synthetic one, calibrates the score.
"""
import argparse
import math
import os
import struct
import sys
import zlib

import bpy
from mathutils import Vector


def parse():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="render_ground.py")
    parser.add_argument("--out", required=True)
    parser.add_argument("--size", default="480x270")
    parser.add_argument("--samples", type=int, default=8)
    parser.add_argument("--white", action="store_true")
    parser.add_argument("--jacksboro-inset", action="store_true")
    parser.add_argument("--quality", default="PREVIEW")
    parser.add_argument("--sun-elevation", type=float, default=20.0)
    parser.add_argument("--shot", action="append", default=[],
                        help="NAME,LON,LAT,ALTITUDE,HEADING,PITCH")
    parser.add_argument("--metrics", default="")
    parser.add_argument("--detail", default="",
                        help="the planet's detail settings changed after the preset, "
                             "key=value,... (keys without the detail_ prefix)")
    parser.add_argument("--planet-sun", action="store_true",
                        help="light with the sun Add > Planet makes (an artist's F12), "
                             "not one 20 degrees above each place")
    parser.add_argument("--band", default="",
                        help="BOTTOM,TOP: render only this band of rows (fractions of the "
                             "height from the bottom), e.g. the horizon's")
    return parser.parse_args(argv)


def write_png16(path, rows):
    """A 16-bit greyscale PNG of `rows` (lists of ints 0..65535, top row first)."""
    raw = b"".join(b"\x00" + struct.pack(f">{len(r)}H", *r) for r in rows)

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data +
                struct.pack(">I", zlib.crc32(kind + data) & 0xffffffff))
    header = struct.pack(">IIBBBBB", len(rows[0]), len(rows), 16, 0, 0, 0, 0)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) +
                chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def jacksboro_inset(folder):
    """(png path, box) of the Jacksboro fault DEM as a 16-bit PNG in metres."""
    import numpy as np
    import matplotlib
    dem = np.load(os.path.join(matplotlib.get_data_path(), "sample_data",
                               "jacksboro_fault_dem.npz"))
    z = dem["elevation"].astype(int)  # rows north first (ymin is its northern edge)
    path = os.path.join(folder, "jacksboro_fault_dem.png")
    write_png16(path, [list(row) for row in z])
    lats = sorted((float(dem["ymin"]), float(dem["ymax"])))
    return path, dict(west=float(dem["xmin"]), east=float(dem["xmax"]), south=lats[0],
                      north=lats[1])


def white_material():
    from planet_lod import materials
    from planet_lod import nodes as node_maths
    material = bpy.data.materials.new("white diffuse")
    material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    b = node_maths.Builder(tree)
    b.link(materials.shading_normal(b), diffuse.inputs["Normal"])
    tree.links.new(diffuse.outputs[0], out.inputs["Surface"])
    return material


def local_frame(lon, lat):
    lo, la = math.radians(lon), math.radians(lat)
    up = Vector((math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)))
    east = Vector((-math.sin(lo), math.cos(lo), 0.0))
    north = up.cross(east)
    return up, east, north


def aim_sun(sun, planet, lon, lat, heading, elevation):
    up, east, north = local_frame(lon, lat)
    azimuth = math.radians(heading + 90.0)
    horizontal = north * math.cos(azimuth) + east * math.sin(azimuth)
    direction = horizontal * math.cos(math.radians(elevation)) + up * math.sin(
        math.radians(elevation))
    world = planet.matrix_world.to_3x3() @ direction
    sun.rotation_euler = world.to_track_quat('Z', 'Y').to_euler()


def ground_variation(path):
    """The fine-scale luminance variation below the horizon (see the module
    doc), and the share of pixels it covers."""
    import numpy as np
    image = bpy.data.images.load(path)
    w, h = image.size
    px = np.array(image.pixels[:], dtype=np.float64).reshape(h, w, 4)
    bpy.data.images.remove(image)
    lum = px[..., 0] * 0.2126 + px[..., 1] * 0.7152 + px[..., 2] * 0.0722
    ground = px[..., 3] > 0.99  # the sky is transparent (--white) or lit
    pad = np.pad(lum, 2, mode="edge")
    blur = sum(pad[i:i + h, j:j + w] for i in range(5) for j in range(5)) / 25.0
    gpad = np.pad(ground, 2, mode="constant")
    inner = ground & np.all([gpad[i:i + h, j:j + w] for i in range(5) for j in range(5)], axis=0)
    if inner.sum() < 100:
        return float("nan"), float(inner.mean())
    return (float(np.abs(lum - blur)[inner].mean() / max(lum[inner].mean(), 1e-6)),
            float(inner.mean()))


def dark_specks(path):
    """Ground pixels darker than half the median of their eight neighbours
    (where those are lit): single black pixels along ridges and horizons."""
    import numpy as np
    image = bpy.data.images.load(path)
    w, h = image.size
    px = np.array(image.pixels[:], dtype=np.float64).reshape(h, w, 4)
    bpy.data.images.remove(image)
    lum = px[..., 0] * 0.2126 + px[..., 1] * 0.7152 + px[..., 2] * 0.0722
    pad = np.pad(lum, 1, mode="edge")
    around = np.median([pad[i:i + h, j:j + w] for i in range(3) for j in range(3)
                        if (i, j) != (1, 1)], axis=0)
    return int(((lum < 0.5 * around) & (around > 0.05) & (px[..., 3] > 0.99)).sum())


def main():
    args = parse()
    os.makedirs(args.out, exist_ok=True)
    import addon_utils
    addon_utils.enable("planet_lod", default_set=True, handle_error=None)
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    scene = bpy.context.scene
    width, height = (int(v) for v in args.size.split("x"))
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = args.samples
    scene.cycles.use_denoising = False
    scene.render.film_transparent = args.white
    if args.band:
        bottom, top = (float(v) for v in args.band.split(","))
        scene.render.use_border, scene.render.use_crop_to_border = True, True
        scene.render.border_min_x, scene.render.border_max_x = 0.0, 1.0
        scene.render.border_min_y, scene.render.border_max_y = bottom, top
    scene.render.image_settings.file_format = 'PNG'
    scene.render.image_settings.color_mode = 'RGBA'
    result = bpy.ops.mesh.planet_add(preset='EARTH', quality=args.quality,
                                     add_sun=args.planet_sun)
    if result != {'FINISHED'}:
        raise SystemExit("planet_add failed")
    planet = bpy.context.object
    for item in filter(None, args.detail.split(",")):
        key, value = item.split("=")
        setattr(planet.planet_lod, "detail_" + key, float(value))
    if args.jacksboro_inset:
        path, box = jacksboro_inset(args.out)
        inset = planet.planet_lod.insets.add()
        inset.filepath = path
        inset.use_box = True
        inset.west, inset.east, inset.south, inset.north = (box["west"], box["east"],
                                                            box["south"], box["north"])
        inset.scale = 65535.0
    sun = None
    if not args.planet_sun:
        sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
        sun.data.energy = 4.0
        sun.data.angle = math.radians(0.5)
        scene.collection.objects.link(sun)
    if args.white:
        # direct sunlight alone: at a few samples, light bounced into the
        # shadows is noise that the fine-scale score would count as relief
        scene.cycles.max_bounces = 0
        scene.view_layers[0].material_override = white_material()
        world = bpy.data.worlds.new("black")
        world.use_nodes = True
        world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
        scene.world = world
    cam = bpy.data.objects.new("Ground camera", bpy.data.cameras.new("Ground camera"))
    cam.data.lens = 35.0
    scene.collection.objects.link(cam)
    scene.camera = cam
    geo = cam.planet_lod_geo
    geo.planet = planet
    geo.enabled = True
    lines = []
    for shot in args.shot:
        name, lon, lat, alt, heading, pitch = shot.split(",")
        lon, lat, alt, heading, pitch = (float(v) for v in (lon, lat, alt, heading, pitch))
        geo.longitude, geo.latitude, geo.altitude = lon, lat, alt
        geo.heading, geo.pitch = heading, pitch
        if sun is not None:
            aim_sun(sun, planet, lon, lat, heading, args.sun_elevation)
        bpy.context.view_layer.update()
        if not args.white:
            from planet_lod import atmosphere
            scene.world = atmosphere.ensure_world(planet, scene)
        target = os.path.join(args.out, name + ".png")
        scene.render.filepath = target
        if bpy.ops.render.render(write_still=True) != {'FINISHED'} or not os.path.isfile(target):
            raise SystemExit(f"render of {name} failed")
        variation, share = ground_variation(target)
        specks = dark_specks(target)
        lines.append(f"{name},{lon},{lat},{alt},{heading},{pitch},{variation:.4f},{share:.3f},"
                     f"{specks}")
        print(f"render_ground: {name} variation {variation:.4f} ground {share:.0%} "
              f"dark specks {specks}", flush=True)
    if args.metrics:
        with open(args.metrics, "w") as f:
            f.write("name,lon,lat,altitude,heading,pitch,variation,ground_share,dark_specks\n")
            f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    try:
        main()
    except SystemExit:
        raise
    except BaseException:
        import traceback
        traceback.print_exc()
        sys.exit(1)
