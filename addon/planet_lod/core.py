"""bpy-free layer of the add-on over the `planetlod` C extension.

The native module is loaded here and only here.  `native` is the module or
None; `native_error` then says why (shown in the UI instead of a traceback).
Search order: $PLANET_LOD_NATIVE (a folder), the add-on package itself (where
tools/install_addon.py puts planetlod*.so), then -- development fallback --
the repository root two levels above this package.

Everything else here is plain Python: planet construction with a cache, camera
parameters, refinement, the deterministic flyby path, CSV rows and the
contact-sheet layout.
"""
import importlib
import importlib.util
import math
import os
import sys

PACKAGE_DIR = os.path.dirname(os.path.realpath(__file__))
REPO_ROOT = os.path.dirname(os.path.dirname(PACKAGE_DIR))

native = None
native_error = ""
native_path = ""


def _candidate_dirs():
    override = os.environ.get("PLANET_LOD_NATIVE")
    if override:
        yield override
    yield PACKAGE_DIR
    yield REPO_ROOT


def load_native(force=False):
    """Import `planetlod` once; returns the module or None (see native_error)."""
    global native, native_error, native_path
    if native is not None and not force:
        return native
    errors = []
    for folder in _candidate_dirs():
        if not os.path.isdir(folder):
            continue
        has_module = any(n.startswith("planetlod") and (n.endswith(".so") or n.endswith(".py")
                                                       or n.endswith(".pyd"))
                         for n in os.listdir(folder))
        if not has_module:
            continue
        sys.path.insert(0, folder)
        try:
            sys.modules.pop("planetlod", None)
            module = importlib.import_module("planetlod")
        except ImportError as exc:
            errors.append(f"{folder}: {exc}")
            continue
        finally:
            sys.path.remove(folder)
        native, native_path, native_error = module, getattr(module, "__file__", folder), ""
        return native
    native = None
    if errors:
        native_error = ("planetlod could not be imported (built for another Python? "
                        f"Blender runs {sys.version_info[0]}.{sys.version_info[1]}; "
                        "rerun tools/install_addon.py): " + "; ".join(errors))
    else:
        native_error = ("planetlod extension not found: run tools/install_addon.py "
                        "(or build it with setup.py build_ext --inplace)")
    return None


def native_or_raise():
    module = load_native()
    if module is None:
        raise RuntimeError(native_error)
    return module


def native_errors():
    """Exception classes that mean bad user input (reported, never raised to the UI)."""
    errs = [OSError, ValueError, MemoryError, RuntimeError]
    if native is not None:
        errs.insert(0, native.PlanetLODError)
    return tuple(errs)


# ---- resources -------------------------------------------------------------

def resource_dirs(name):
    """Folders holding `name` (data, shaders, presets): package first, then repo."""
    return [os.path.join(PACKAGE_DIR, name), os.path.join(REPO_ROOT, name)]


def resource_path(kind, filename):
    for folder in resource_dirs(kind):
        path = os.path.join(folder, filename)
        if os.path.exists(path):
            return path
    return os.path.join(resource_dirs(kind)[-1], filename)


def data_path(filename):
    return resource_path("data", filename)


# ---- planets ----------------------------------------------------------------

PROJECTION_IDS = {"QSC": "qsc", "TSC": "tsc", "CSC": "csc", "SPHERIFIED": "spherified",
                  "CAR": "car"}

_planet_cache = {}


def _presets():
    """presets.py (bpy-free), also when this file is loaded on its own."""
    if __package__:
        from . import presets
        return presets
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "presets.py")
    spec = importlib.util.spec_from_file_location("plod_presets", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def planet_key(settings):
    """The settings that define the planet's geometry (not the LOD)."""
    path = settings.get("heightmap") or ""
    stamp = None
    if path and os.path.exists(path):
        st = os.stat(path)
        stamp = (st.st_size, st.st_mtime_ns)
    detail = _presets().detail_kwargs(settings)
    return (settings["projection"], float(settings["radius"]), path, stamp,
            float(settings["height_scale"]), float(settings.get("height_offset", 0.0)),
            bool(settings.get("height_signed", False)),
            float(settings["sea_level"]) if settings.get("use_sea_level") else None,
            tuple(sorted(detail.items())) if detail else None)


def check_heightmap(path):
    """Raises OSError with a clear message for a path that cannot be a map."""
    if not path:
        return
    if not os.path.exists(path):
        raise FileNotFoundError(f"height map not found: {path}")
    if os.path.isdir(path):
        raise IsADirectoryError(f"height map is a folder: {path}")
    if os.path.getsize(path) == 0:
        raise OSError(f"height map is empty (0 bytes): {path}")


# Sectors a planet allocates (and touches) when it is built: a 1 px LOD at
# 1920x1080 peaks near 7,000 over the Earth map, so the first flight over a
# new planet does not grow arrays mid-frame (about 11 MB, 3 ms, once).
RESERVE_SECTORS = 16384


def build_planet(settings):
    """A native Planet for these settings (cached by planet_key).  Raises on bad input."""
    module = native_or_raise()
    key = planet_key(settings)
    planet = _planet_cache.get(key)
    if planet is not None:
        return planet
    check_heightmap(settings.get("heightmap"))
    kwargs = {"projection": PROJECTION_IDS[settings["projection"]],
              "height_scale": float(settings["height_scale"]),
              "height_offset": float(settings.get("height_offset", 0.0))}
    if settings.get("heightmap"):
        kwargs["heightmap"] = settings["heightmap"]
        kwargs["height_signed"] = bool(settings.get("height_signed", False))
    if settings.get("use_sea_level"):
        kwargs["sea_level"] = float(settings["sea_level"])
    detail = _presets().detail_kwargs(settings)
    if detail:
        kwargs["detail"] = detail
    planet = module.Planet(float(settings["radius"]), **kwargs)
    planet.reserve(RESERVE_SECTORS)
    if len(_planet_cache) > 8:
        _planet_cache.clear()
    _planet_cache[key] = planet
    return planet


def forget_planets():
    _planet_cache.clear()


def make_camera(params):
    """params: dict of planetlod.Camera keyword arguments (matrix_world in planet space)."""
    return native_or_raise().Camera(**params)


def refine(planet, camera, settings, hysteresis=False):
    """Refines `planet` for `camera`; returns the stats dict plus 'triangles'.
    hysteresis=False (renders) makes the LOD a function of the camera alone."""
    template_level = int(settings["template_level"])
    kwargs = dict(criterion="pixel" if settings["criterion"] == "PIXEL" else "side_distance",
                  max_pixel_error=float(settings["max_pixel_error"]),
                  split_border=float(settings["split_border"]),
                  merge_border=float(settings["merge_border"]),
                  hysteresis=bool(hysteresis),
                  template_level=template_level, max_level=max_level(settings),
                  budget=int(settings["budget"]), backface=bool(settings["backface"]),
                  frustum=bool(settings["frustum"]),
                  skip_sea=bool(settings.get("use_sea_level") and settings.get("skip_sea")))
    stats = dict(planet.refine(camera, **kwargs))
    stats["triangles"] = planet.visible_count * 4 ** template_level
    stats["visible"] = planet.visible_count
    return stats


# Most triangles one mesh build may emit.  Template density x sectors can ask for
# billions (16384 x a budget of 1e6); past this the build is refused with a clear
# message instead of exhausting memory inside Blender.
MAX_MESH_TRIANGLES = 1 << 24


def check_mesh_size(stats, template_level):
    """Raises ValueError when the refined LOD would emit more than MAX_MESH_TRIANGLES."""
    triangles = stats["visible"] * 4 ** template_level
    if triangles > MAX_MESH_TRIANGLES:
        raise ValueError(
            f"the LOD would build {triangles:,} triangles ({stats['visible']:,} sectors x "
            f"{4 ** template_level} per sector), more than the limit of "
            f"{MAX_MESH_TRIANGLES:,}: lower the template density or the sector budget")


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


# ---- flyby path -------------------------------------------------------------
# A pure function of (frame, path_frames, radius, heights): rendering any
# sub-range of a path gives exactly the cameras of the full run (farm splits).

ORBIT_END = 0.4
DESCENT_END = 0.75
# share of the descent over which the gaze turns from the planet's centre to
# the horizon: the rest of the descent keeps the horizon and the sky in view
GAZE_TURN = 0.3
# The flyby's sun (a sun lamp's XYZ Euler rotation and strength): afternoon
# light from the south-west, about 40 degrees up over the orbit and the
# descent and 25-30 over the skim, low enough for the relief to show
FLYBY_SUN_ROTATION = (1.914, 0.0, 2.314)
FLYBY_SUN_STRENGTH = 4.0


def _normalise(v):
    n = math.sqrt(sum(c * c for c in v))
    return tuple(c / n for c in v)


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _smooth(t):
    t = min(max(t, 0.0), 1.0)
    return t * t * (3 - 2 * t)


def look_matrix(location, forward, up_hint):
    """Row-major 4x4 camera matrix (Blender camera looks down -Z, +Y up)."""
    f = _normalise(forward)
    right = _cross(f, up_hint)
    if sum(c * c for c in right) < 1e-20:
        right = _cross(f, (1.0, 0.0, 0.0) if abs(f[0]) < 0.9 else (0.0, 1.0, 0.0))
    right = _normalise(right)
    up = _cross(right, f)
    z = tuple(-c for c in f)
    return ((right[0], up[0], z[0], location[0]),
            (right[1], up[1], z[1], location[1]),
            (right[2], up[2], z[2], location[2]),
            (0.0, 0.0, 0.0, 1.0))


def flyby_pose(frame, path_frames, radius, skim_height=5.0, ground_height=None,
               orbit_distance=3.0):
    """Camera matrix (planet space, row-major 4x4) at `frame` of a `path_frames` path.

    orbit (camera at orbit_distance*radius circling over 60 degrees of longitude,
    looking at the centre) -> descent (altitude falls exponentially to
    skim_height; the gaze turns to just below the horizon early on, so the
    ground comes down to meet a sky) -> skim (skim_height metres above
    the ground, flying east).  ground_height(dir) -> metres gives the terrain
    under the camera (None: the bare sphere)."""
    t = 0.0 if path_frames <= 1 else (frame - 1) / float(path_frames - 1)
    t = min(max(t, 0.0), 1.0)
    lon0, lat = math.radians(10.0), math.radians(20.0)
    lon = lon0 + math.radians(60.0) * (t / ORBIT_END if t < ORBIT_END else 1.0)
    if t > ORBIT_END:  # keep moving east along the descent and the skim
        lon += math.radians(25.0) * _smooth((t - ORBIT_END) / (1.0 - ORBIT_END))
        lon += (t - DESCENT_END) / (1 - DESCENT_END) * 2000.0 / radius if t > DESCENT_END else 0.0
    direction = (math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat))
    east = (-math.sin(lon), math.cos(lon), 0.0)
    north = _cross(direction, east)
    top = (orbit_distance - 1.0) * radius
    ground = ground_height(direction) if ground_height else 0.0
    if t <= ORBIT_END:
        altitude = top
        tilt = 0.0
    elif t <= DESCENT_END:
        s = _smooth((t - ORBIT_END) / (DESCENT_END - ORBIT_END))
        altitude = math.exp(math.log(top) * (1 - s) + math.log(skim_height) * s)
        tilt = _smooth(s / GAZE_TURN)
    else:
        altitude = skim_height
        tilt = 1.0
    r = radius + ground + altitude
    location = tuple(c * r for c in direction)
    # gaze: centre (tilt 0) -> a little below the horizon, heading east (tilt 1)
    down = tuple(-c for c in direction)
    horizon_dip = math.acos(min(1.0, radius / r)) + math.radians(8.0)
    ahead = tuple(math.cos(horizon_dip) * e + math.sin(horizon_dip) * d
                  for e, d in zip(east, down))
    forward = _normalise(tuple((1 - tilt) * d + tilt * a for d, a in zip(down, ahead)))
    return look_matrix(location, forward, north if tilt < 0.5 else direction)


# ---- placing objects by longitude, latitude, altitude ------------------------

def geo_pose(radius, longitude, latitude, east=0.0, north=0.0, altitude=0.0, heading=0.0,
             pitch=0.0, roll=0.0, base_height=None):
    """Row-major 4x4 matrix (planet space, float64) of an object placed on a planet.

    longitude/latitude (degrees) pick a point; east/north (metres, along the
    surface) move from it, so a float32 property animated in metres keeps
    millimetre steps where degrees would not (1e-7 degrees is 1 cm).  The
    object is `altitude` metres above base_height(direction) (None: the
    sphere of `radius`).  heading (degrees from north towards east), pitch
    (degrees above the horizon) and roll (degrees about the view direction)
    turn its -Z axis (a camera's view) and +Y (its up)."""
    lon, lat = math.radians(longitude), math.radians(latitude)
    p0 = (math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat))
    east0 = (-math.sin(lon), math.cos(lon), 0.0)
    north0 = _cross(p0, east0)
    distance = math.hypot(east, north)
    if distance > 0.0:
        tangent = tuple((east * e + north * n) / distance for e, n in zip(east0, north0))
        angle = distance / radius
        up = _normalise(tuple(math.cos(angle) * p + math.sin(angle) * t
                              for p, t in zip(p0, tangent)))
    else:
        up = p0
    east_axis = _cross((0.0, 0.0, 1.0), up)
    if sum(c * c for c in east_axis) < 1e-24:  # at a pole: keep the start's east
        east_axis = east0
    east_axis = _normalise(east_axis)
    north_axis = _cross(up, east_axis)
    r = radius + (base_height(up) if base_height else 0.0) + altitude
    location = tuple(c * r for c in up)
    h, p, q = math.radians(heading), math.radians(pitch), math.radians(roll)
    level = tuple(math.cos(h) * n + math.sin(h) * e for n, e in zip(north_axis, east_axis))
    right = tuple(math.cos(h) * e - math.sin(h) * n for n, e in zip(north_axis, east_axis))
    forward = tuple(math.cos(p) * l + math.sin(p) * u for l, u in zip(level, up))
    cam_up = _cross(right, forward)
    right, cam_up = (tuple(math.cos(q) * r_ + math.sin(q) * u_ for r_, u_ in zip(right, cam_up)),
                     tuple(-math.sin(q) * r_ + math.cos(q) * u_ for r_, u_ in zip(right, cam_up)))
    z = tuple(-c for c in forward)
    return ((right[0], cam_up[0], z[0], location[0]),
            (right[1], cam_up[1], z[1], location[1]),
            (right[2], cam_up[2], z[2], location[2]),
            (0.0, 0.0, 0.0, 1.0))


# ---- CSV and contact sheet ----------------------------------------------------

CSV_FIELDS = ("frame", "sectors_total", "sectors_after_backface", "sectors_after_frustum",
              "sectors_after_budget", "triangles", "vertices", "splits", "merges", "max_level",
              "refine_us", "mesh_ms", "render_s", "camera_altitude_m", "camera_ground_m",
              "mesh_hash")


def csv_row(values):
    return ",".join(str(values.get(name, "")) for name in CSV_FIELDS)


def contact_sheet_layout(count, thumb_w, thumb_h, columns=None, gap=2):
    """(sheet_w, sheet_h, [(x, y) of each thumbnail's lower-left corner])."""
    if count <= 0:
        return 0, 0, []
    columns = columns or max(1, min(count, int(math.ceil(math.sqrt(count * 16 / 9.0)))))
    rows = (count + columns - 1) // columns
    width = columns * thumb_w + (columns + 1) * gap
    height = rows * thumb_h + (rows + 1) * gap
    places = []
    for i in range(count):
        col, row = i % columns, i // columns
        places.append((gap + col * (thumb_w + gap), height - (row + 1) * (thumb_h + gap)))
    return width, height, places


def parse_frames(text):
    """'1-120' or '7' -> (first, last); raises ValueError."""
    parts = text.split("-")
    if len(parts) == 1:
        first = last = int(parts[0])
    elif len(parts) == 2:
        first, last = int(parts[0]), int(parts[1])
    else:
        raise ValueError(f"bad frame range {text!r} (want A-B)")
    if first < 0 or last < first:
        raise ValueError(f"bad frame range {text!r}")
    return first, last
