"""Planets and refinement from a settings dict (the add-on's object settings,
or a preset's): the planet a set of settings builds (cached by the settings
that define its geometry), the refinement's keyword arguments, the depth
limit and the mesh-size guard."""
import math
import os
import re

from . import Cancelled, FileError, ImageError, InvalidArgument, presets, require_native


def projection_id(key):
    """The core's name of a settings projection key ('QSC' -> 'qsc'): the
    extension's PROJECTIONS tuple is the one list of projections."""
    name = str(key).lower()
    if name not in require_native().PROJECTIONS:
        raise InvalidArgument(f"unknown projection {key!r}: one of "
                              + ", ".join(p.upper() for p in require_native().PROJECTIONS))
    return name

_planet_cache = {}


def _file_stamp(path):
    """(size, modification time) of a file, None when there is none: a map
    or inset replaced on disk rebuilds the planet."""
    if path and os.path.isfile(path):
        st = os.stat(path)
        return (st.st_size, st.st_mtime_ns)
    return None


BOX_SIDES = ("west", "south", "east", "north")


def inset_entries(settings):
    """The settings' insets, in order, empty entries left out, as the core
    takes them: a path (placed by its SRTM name or GeoTIFF tags) or
    dict(path=, west=, south=, east=, north=[, scale=]) (degrees of the corner
    samples; metres per sample value of an image read as 0..1)."""
    entries = []
    for entry in settings.get("insets") or ():
        if isinstance(entry, dict):
            if entry.get("path"):
                entries.append(dict(path=str(entry["path"]),
                                    scale=float(entry.get("scale", 1.0)),
                                    **{side: float(entry[side]) for side in BOX_SIDES}))
        elif entry:
            entries.append(str(entry))
    return entries


def inset_paths(settings):
    """The settings' inset files, in order, empty entries left out."""
    return [e["path"] if isinstance(e, dict) else e for e in inset_entries(settings)]


def planet_key(settings):
    """The settings that define the planet's geometry (not the LOD)."""
    path = settings.get("heightmap") or ""
    detail = presets.detail_kwargs(settings)
    insets = tuple((path, _file_stamp(path),
                    tuple(entry[side] for side in BOX_SIDES + ("scale",))
                    if isinstance(entry, dict) else None)
                   for path, entry in zip(inset_paths(settings), inset_entries(settings)))
    return (settings["projection"], float(settings["radius"]), path, _file_stamp(path),
            bool(settings.get("heightmap_tiled", False)), insets,
            float(settings.get("inset_feather", INSET_FEATHER)) if insets else None,
            float(settings["height_scale"]), float(settings.get("height_offset", 0.0)),
            bool(settings.get("height_signed", False)),
            float(settings["sea_level"]) if settings.get("use_sea_level") else None,
            tuple(sorted(detail.items())) if detail else None)


def check_heightmap(path):
    """Raises FileError with a clear message for a path that cannot be a map."""
    if not path:
        return
    if not os.path.exists(path):
        raise FileError(f"height map not found: {path}")
    if os.path.isdir(path):
        raise FileError(f"height map is a folder: {path}")
    if os.path.getsize(path) == 0:
        raise FileError(f"height map is empty (0 bytes): {path}")
    check_image_signature(path)


# What image files start with, by the extensions that promise them.
IMAGE_SIGNATURES = {
    ".png": (b"\x89PNG\r\n\x1a\n",),
    ".jpg": (b"\xff\xd8\xff",), ".jpeg": (b"\xff\xd8\xff",),
    ".tif": (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"),
    ".tiff": (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"),
    ".exr": (b"\x76\x2f\x31\x01",),
}


def check_image_signature(path):
    """Raises ImageError "not an image file (name)" for a file whose extension
    promises an image format that its first bytes are not (a text file named .png)."""
    signatures = IMAGE_SIGNATURES.get(os.path.splitext(path)[1].lower())
    if not signatures:
        return
    try:
        with open(path, "rb") as f:
            head = f.read(8)
    except OSError as exc:
        raise FileError(f"cannot read {path}: {exc.strerror}") from exc
    if not any(head.startswith(sig) for sig in signatures):
        kind = os.path.splitext(path)[1][1:].upper()
        raise ImageError(f"not an image file ({os.path.basename(path)}): it is named "
                         f".{kind.lower()} but does not start like a {kind} image")


def check_insets(paths):
    """Raises FileError naming the first inset file that is missing, a folder or empty."""
    for path in paths:
        if not os.path.exists(path):
            raise FileError(f"inset not found: {path}")
        if os.path.isdir(path):
            raise FileError(f"inset is a folder: {path}")
        if os.path.getsize(path) == 0:
            raise FileError(f"inset is empty (0 bytes): {path}")
        check_image_signature(path)


# The blend border of insets, as a fraction of an inset's smaller side (the
# core's default: a 1-degree tile blends over its outer 0.1 degree).
INSET_FEATHER = 0.1


def _over_pixel_limit(exc):
    """True for the core's refusal of an image with more pixels than it
    loads into memory (such a map needs the tiled, out-of-core reading)."""
    return isinstance(exc, ImageError) and "more than the limit of" in str(exc)


TILES_NOT_WRITTEN = ("Large Map: the map's tile file is not written yet (or the map changed "
                     "since): press Write Tile File")


def tiles_written(settings):
    """Whether the settings' height map has a current tile file next to it."""
    return bool(settings.get("heightmap")) and \
        require_native().TiledMap.is_written(settings["heightmap"])


def write_tiles(settings, progress=None):
    """Writes the settings' height map's tile file (map path + ".plodtiles",
    as big as the map; to a temporary name, renamed when complete).
    progress(fraction) is called as it goes; a true return cancels, and then
    nothing is left behind.  Returns False when cancelled."""
    check_heightmap(settings.get("heightmap"))
    try:
        require_native().TiledMap(settings["heightmap"],
                                  signed=bool(settings.get("height_signed", False)),
                                  cache_bytes=1 << 20, progress=progress)
    except Cancelled:
        return False
    return True


def tiled_map(settings):
    """The settings' height map as an out-of-core TiledMap, read through its
    tile file (write_tiles); at most 128 MiB of tiles stay in memory.  The
    tile file is never written here: writing one takes as long as reading
    the whole map (minutes for a global 500 m map), which the add-on runs
    with a progress bar and a way to cancel."""
    if not tiles_written(settings):
        raise FileError(TILES_NOT_WRITTEN)
    tiled = require_native().TiledMap(settings["heightmap"],
                                      signed=bool(settings.get("height_signed", False)))
    if tiled.width != 2 * tiled.height:
        raise InvalidArgument(f"Large Map reads world maps (2:1 equirectangular); "
                              f"{settings['heightmap']} is {tiled.width}x{tiled.height}")
    return tiled


# Sectors a planet allocates (and touches) when it is built: a 1 px LOD at
# 1920x1080 peaks near 7,000 over the Earth map, so the first flight over a
# new planet does not grow arrays mid-frame (about 10 MB, 3 ms, once).
RESERVE_SECTORS = 16384


def _new_planet(module, radius, settings, kwargs):
    if not settings.get("heightmap"):
        return module.Planet(radius, **kwargs)
    if settings.get("heightmap_tiled"):
        return module.Planet(radius, heightmap=tiled_map(settings), **kwargs)
    try:
        return module.Planet(radius, heightmap=settings["heightmap"],
                             height_signed=bool(settings.get("height_signed", False)),
                             **kwargs)
    except ImageError as exc:
        if not _over_pixel_limit(exc):
            raise
        # not tiled behind the artist's back: the tile file is as big as the map
        raise ImageError(f"{exc}: turn on Large Map to read it a piece at a time "
                         "(through a tile file written next to it)") from exc


def _overlap_by_file(exc, insets):
    """The core names insets by index and in its API's terms; the panel names
    their files and its own settings."""
    unplaced = re.search(r"inset (\d+) \('([^']*)'\): a bare path must be", str(exc))
    if unplaced:
        return InvalidArgument(f"inset {unplaced.group(2)} is neither an SRTM tile named by "
                               "its corner (like N45E006.hgt) nor a GeoTIFF with its "
                               "longitude and latitude in its tags: give its box (Place by "
                               "Box)")
    match = re.search(r"insets (\d+) and (\d+) overlap \(([^)]*)\)", str(exc))
    if not match or max(int(match.group(1)), int(match.group(2))) >= len(insets):
        return exc
    first, second = insets[int(match.group(1))], insets[int(match.group(2))]
    if os.path.basename(first) != os.path.basename(second):
        first, second = os.path.basename(first), os.path.basename(second)
    return InvalidArgument(f"insets {first} and {second} overlap ({match.group(3)}): "
                           "each area may come from one inset only, remove one of them")


def minimum_radius(settings):
    """About the smallest radius the settings' heights allow: the native planet
    refuses ground lower than half the radius below it or higher than ten
    radii (the map's range and the detail's amplitude)."""
    scale = abs(float(settings.get("height_scale", 0.0)))
    offset = float(settings.get("height_offset", 0.0))
    detail = float(settings.get("detail_amplitude", 0.0)) if settings.get("use_detail") else 0.0
    low = offset - (scale if settings.get("height_signed") else 0.0) - detail
    high = offset + scale + detail
    return max(1.0, -2.0 * low * 1.001, high / 10.0)


def build_planet(settings):
    """A native Planet for these settings (cached by planet_key).  Raises on bad input."""
    module = require_native()
    key = planet_key(settings)
    planet = _planet_cache.get(key)
    if planet is not None:
        return planet
    check_heightmap(settings.get("heightmap"))
    insets = inset_paths(settings)
    check_insets(insets)
    kwargs = {"projection": projection_id(settings["projection"]),
              "height_scale": float(settings["height_scale"]),
              "height_offset": float(settings.get("height_offset", 0.0))}
    if settings.get("use_sea_level"):
        kwargs["sea_level"] = float(settings["sea_level"])
    detail = presets.detail_kwargs(settings)
    if detail:
        kwargs["detail"] = detail
    if insets:
        kwargs["insets"] = inset_entries(settings)
        kwargs["inset_feather"] = float(settings.get("inset_feather", INSET_FEATHER))
    try:
        planet = _new_planet(module, float(settings["radius"]), settings, kwargs)
    except InvalidArgument as exc:
        smallest = minimum_radius(settings)
        if float(settings["radius"]) < smallest:
            raise InvalidArgument(f"radius must be at least {math.ceil(smallest):,} m for "
                                  "these heights (the lowest ground may not reach half "
                                  "way to the centre)") from exc
        named = _overlap_by_file(exc, insets)
        if named is exc:
            raise
        raise named from exc
    planet.reserve(RESERVE_SECTORS)
    if len(_planet_cache) > 8:
        _planet_cache.clear()
    _planet_cache[key] = planet
    return planet


def forget_planets():
    _planet_cache.clear()


def make_camera(params):
    """params: dict of planetlod.Camera keyword arguments (matrix_world in planet space)."""
    return require_native().Camera(**params)


# Threads of a refine: the planet's worker evaluates half the leaves of a large
# sector set while the caller does the other half (the same sectors for any
# count); two, as the mesh emission uses.
REFINE_THREADS = max(1, min(2, os.cpu_count() or 1))


# The LOD methods (Planet.refine(method=...)) as the add-on names them, with
# what a level means in each (the Show Levels legend).
LOD_METHOD_ITEMS = [
    ("HRTMR", "HRTMR", "Longest-edge bisection of triangular sectors (hierarchical "
                       "triangular mesh refinement, the default)"),
    ("CHUNKED", "Chunked LOD", "Quadtrees of fixed-size chunks on the six cube faces (T. "
                               "Ulrich, Rendering Massive Terrains using Chunked Level of "
                               "Detail Control, 2002)"),
    ("GEOMIPMAP", "Geomipmapping", "A fixed grid of tiles on the cube faces, each drawn at "
                                   "a mip level (W. H. de Boer, Fast Terrain Rendering Using "
                                   "Geometrical MipMapping, 2000)"),
    ("CLIPMAP", "Geometry Clipmaps", "Nested rings of regular grids on the cube faces centred "
                                     "under the camera (F. Losasso, H. Hoppe, Geometry "
                                     "Clipmaps, 2004)"),
]
LEVEL_MEANING = {
    "HRTMR": "level: bisections of a base sector (higher is finer)",
    "CHUNKED": "level: quadtree depth of the chunk (higher is finer)",
    "GEOMIPMAP": "level: mip level of the tile (0 is full resolution, higher is coarser)",
    "CLIPMAP": "level: clipmap ring (cells halve per level, higher is finer and nearer)",
}


def lod_method(settings):
    """The core's name of the settings' LOD method ('hrtmr', 'chunked', ...)."""
    return str(settings.get("lod_method", "HRTMR")).lower()


def refine(planet, camera, settings, hysteresis=False, max_splits=0):
    """Refines `planet` for `camera`; returns the stats dict plus 'triangles'.
    hysteresis=False (renders) makes the LOD a function of the camera alone.
    max_splits > 0 (the viewport's progressive refresh, refresh.ProgressiveSplits)
    limits the splits of this refresh (stats 'pending': refine again to
    carry on)."""
    template_level = int(settings["template_level"])
    kwargs = dict(criterion="pixel" if settings["criterion"] == "PIXEL" else "side_distance",
                  max_pixel_error=float(settings["max_pixel_error"]),
                  split_border=float(settings["split_border"]),
                  merge_border=float(settings["merge_border"]),
                  hysteresis=bool(hysteresis),
                  template_level=template_level, max_level=max_level(settings),
                  budget=int(settings["budget"]), backface=bool(settings["backface"]),
                  frustum=bool(settings["frustum"]),
                  skip_sea=bool(settings.get("use_sea_level") and settings.get("skip_sea")),
                  threads=REFINE_THREADS, method=lod_method(settings))
    if kwargs["method"] != "hrtmr":  # the other methods' own settings
        kwargs["chunk_cracks"] = str(settings.get("chunk_cracks", "STITCH")).lower()
        kwargs["geomipmap_tiles"] = int(settings.get("geomipmap_tiles", 16))
    if max_splits > 0:
        kwargs["max_splits"] = int(max_splits)
    stats = dict(planet.refine(camera, **kwargs))
    if kwargs["method"] == "hrtmr":
        stats["triangles"] = planet.visible_count * 4 ** template_level
        stats["visible"] = planet.visible_count
    else:  # the refine's bound on what the mesh of its patches holds
        stats["visible"] = stats["sectors_after_budget"]
    return stats


# Most triangles one mesh build may emit.  Template density x sectors can ask for
# billions (16384 x a budget of 1e6); past this the build is refused with a clear
# message instead of exhausting memory inside Blender.
MAX_MESH_TRIANGLES = 1 << 24


def check_mesh_size(stats, template_level):
    """Raises InvalidArgument when the refined LOD would emit more than MAX_MESH_TRIANGLES."""
    triangles = stats.get("triangles", stats["visible"] * 4 ** template_level)
    if triangles > MAX_MESH_TRIANGLES:
        raise InvalidArgument(
            f"the LOD would build {triangles:,} triangles ({stats['visible']:,} sectors x "
            f"{4 ** template_level} per sector), more than the limit of "
            f"{MAX_MESH_TRIANGLES:,}: lower the template density or the sector budget")


def detail_amplitude(planet):
    """The planet's detail amplitude in metres (the unit of the preview's
    crests), None without detail."""
    detail = planet.detail
    return detail["amplitude"] if detail.get("enabled") else None


def camera_inside(planet, matrix_world):
    """True when the camera (planet-space row-major matrix) is below the terrain."""
    location = [row[3] for row in matrix_world[:3]]
    distance = math.sqrt(sum(c * c for c in location))
    if distance == 0.0:
        return True
    ground = planet.radius + planet.height(*(c / distance for c in location))
    return not distance >= ground  # NaN-safe


# The deepest bisection level a planet's settings may ask for.  On a
# 6,371 km Earth a level-48 patch is 0.6 m across.
DEEPEST_LEVEL = 48


def max_level(settings):
    """The refinement's depth limit: the settings' Max Depth, or with Max Depth
    0 (automatic) the level at which a patch's triangles are half the detail's
    smallest feature, from the planet's size -- 34 levels on a 20 km asteroid
    with 10 cm detail, the deepest level on an Earth.  Without detail the
    pixel error and the height map's texels alone stop the refinement."""
    chosen = int(settings["max_level"])
    if chosen > 0:
        return chosen
    if not settings.get("use_detail"):
        return DEEPEST_LEVEL
    smallest = float(settings.get("detail_smallest", 0.1))
    # a level-0 patch is half a cube face, legs of a quarter great circle;
    # every two bisections halve them; a template splits a leg 2^level times
    leg = 0.5 * math.pi * float(settings["radius"])
    spacing = 0.5 * smallest * 2 ** int(settings["template_level"])
    level = 2 * math.ceil(math.log2(max(leg / spacing, 1.0)))
    return max(1, min(DEEPEST_LEVEL, level))


def template_level_from_density(triangles):
    """Template density (1..16384 triangles per sector, a power of 4) -> level 0..7."""
    level = 0
    while 4 ** (level + 1) <= triangles and level < 7:
        level += 1
    return level
