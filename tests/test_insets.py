"""Regional high-resolution insets (SRTM .hgt tiles, or any grid with its
lon/lat box) blended over the global map across a feathered border.  The
tiles are generated here."""
import math

import numpy as np
import pytest

from test_refine import look_at

R = 6371000.0


def direction(lon, lat):
    lon, lat = math.radians(lon), math.radians(lat)
    return (math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat))


def tile_field(lon, lat):
    return 2000.0 + 800.0 * np.sin(np.radians(lon * 300.0)) * np.cos(np.radians(lat * 300.0))


def write_hgt(folder, lon, lat, side=1201, void=None):
    name = f"{'N' if lat >= 0 else 'S'}{abs(lat):02d}{'E' if lon >= 0 else 'W'}{abs(lon):03d}.hgt"
    la = np.linspace(lat + 1, lat, side)[:, None]  # row 0 north
    lo = np.linspace(lon, lon + 1, side)[None, :]
    grid = np.round(tile_field(lo, la)).astype(">i2")
    if void:
        grid[void] = -32768
    path = folder / name
    grid.tofile(path)
    return str(path), grid


@pytest.fixture(scope="module")
def tiles(tmp_path_factory):
    folder = tmp_path_factory.mktemp("srtm")
    a, grid_a = write_hgt(folder, 6, 45, void=(slice(590, 611), slice(590, 611)))
    b, grid_b = write_hgt(folder, 7, 45)
    return folder, [a, b], grid_a


@pytest.fixture(scope="module")
def base(planetlod):
    cubemap = planetlod.CubeMap(projection="qsc", size=64, dtype="u16")
    rng = np.random.default_rng(9)
    for face in range(6):
        cubemap.set_face(face, rng.integers(900, 1100, 64 * 64).astype("<u2").tobytes())
    return cubemap


def planets(planetlod, base, insets, **kw):
    return (planetlod.Planet(R, heightmap=base, height_scale=65535.0, insets=insets, **kw),
            planetlod.Planet(R, heightmap=base, height_scale=65535.0))


def test_inset_values_inside_and_global_map_outside(planetlod, tiles, base):
    _, paths, grid = tiles
    with_insets, plain = planets(planetlod, base, paths)
    # on the tile's samples, far from the border: the tile's metres
    for row, col in ((200, 200), (300, 900), (1000, 250), (900, 1150)):  # beyond the feather
        lon, lat = 6 + col / 1200, 46 - row / 1200
        assert with_insets.height(*direction(lon, lat)) == pytest.approx(float(grid[row, col]),
                                                                         abs=1e-6)
    # outside every tile: the global map, bit for bit
    for lon, lat in ((5.5, 45.5), (8.5, 45.5), (6.5, 44.5), (7.5, 46.5), (-120, 10)):
        d = direction(lon, lat)
        assert with_insets.height(*d) == plain.height(*d)
    # a void falls back to the global map
    d = direction(6.5, 45.5)
    assert with_insets.height(*d) == plain.height(*d)
    # the data's resolution where the tile counts: 3 arc-seconds
    assert with_insets.texel_size(*direction(6.3, 45.3)) == pytest.approx(
        R * math.radians(1 / 1200))
    assert plain.texel_size(*direction(6.3, 45.3)) == pytest.approx(R * math.pi / 2 / 64)


def test_feathered_border_and_seamless_shared_edge(planetlod, tiles, base):
    _, paths, _ = tiles
    with_insets, plain = planets(planetlod, base, paths, inset_feather=0.1)
    # across the mosaic's outer west border: from the global map to the
    # tile over the feather (0.1 deg), without a step
    lons = np.linspace(5.95, 6.2, 2501)
    h = np.array([with_insets.height(*direction(lon, 45.3)) for lon in lons])
    g = np.array([plain.height(*direction(lon, 45.3)) for lon in lons])
    t = tile_field(lons, 45.3)
    assert np.all(h[lons < 6.0] == g[lons < 6.0])
    inside = lons > 6.1 + 1e-9
    np.testing.assert_allclose(h[inside], t[inside], atol=1.0)  # rounded to metres
    assert np.max(np.abs(np.diff(h))) < 5.0  # 0.0001 deg steps: smooth, no cliff
    # across the edge the two tiles share (lon 7): no feather, no seam
    lons = np.linspace(6.95, 7.05, 1001)
    h = np.array([with_insets.height(*direction(lon, 45.3)) for lon in lons])
    np.testing.assert_allclose(h, tile_field(lons, 45.3), atol=1.0)


def test_sector_bounds_hold_over_insets(planetlod, tiles, base):
    _, paths, _ = tiles
    planet, _ = planets(planetlod, base, paths)
    up = np.array(direction(6.02, 45.4))
    east = np.array([-math.sin(math.radians(6.02)), math.cos(math.radians(6.02)), 0.0])
    for altitude in (3e5, 2e4, 3000.0):
        forward = east * math.cos(math.radians(-35)) + up * math.sin(math.radians(-35))
        right = np.cross(forward, up)
        right /= np.linalg.norm(right)
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2] = right, np.cross(right, forward), -forward
        m[:3, 3] = up * (R + 3000.0 + altitude)
        camera = planetlod.Camera(m.tolist(), lens=30.0, clip_end=1e9, resolution_x=480,
                                  resolution_y=270)
        planet.refine(camera, max_pixel_error=2.0)
        assert planet.check_invariants()
        corners = np.array(planet.sector_corners().tolist()).reshape(-1, 3, 3)
        bounds = np.array(planet.sector_heights().tolist()).reshape(-1, 2)
        rng = np.random.default_rng(int(altitude))
        for k in rng.choice(len(corners), size=min(80, len(corners)), replace=False):
            w = rng.dirichlet((1.0, 1.0, 1.0), size=30)
            points = w @ corners[k]
            points /= np.linalg.norm(points, axis=1)[:, None]
            h = np.array([planet.height(*p) for p in points])
            assert h.min() >= bounds[k, 0] - 1e-3 and h.max() <= bounds[k, 1] + 1e-3
        mesh = planet.mesh(template_level=3)
        assert np.isfinite(np.frombuffer(bytes(mesh.positions), np.float32)).all()
    # the mountains of the tiles show up in the sectors over them
    assert bounds.max() > 2500.0


def test_grids_by_box_and_errors(planetlod, tmp_path, base):
    grid = np.linspace(0.0, 1.0, 50 * 40, dtype=np.float32).reshape(40, 50)
    path = tmp_path / "region.raw"
    grid.tofile(path)
    inset = dict(path=str(path), west=-10.0, south=20.0, east=-5.0, north=24.0,
                 raw=dict(width=50, height=40, dtype="f32"), scale=1000.0, offset=-200.0)
    planet, _ = planets(planetlod, base, [inset], inset_feather=0.0)  # hard edges
    # the box's north-west corner sample, and its centre row's middle
    assert planet.height(*direction(-10.0 + 1e-9, 24.0 - 1e-9)) == pytest.approx(-200.0, abs=1e-3)
    assert planet.height(*direction(-7.5, 22.0)) == pytest.approx(
        1000.0 * float(np.mean(grid[19:21, 24:26])) - 200.0, abs=0.5)
    with pytest.raises(planetlod.InvalidArgument, match="overlap"):
        planets(planetlod, base, [inset, dict(inset, west=-6.0, east=-1.0)])
    with pytest.raises(planetlod.InvalidArgument, match="N45E006"):
        planets(planetlod, base, [str(path)])  # a bare path must be an SRTM tile
    with pytest.raises(planetlod.InvalidArgument, match="west, south, east, north"):
        planets(planetlod, base, [dict(path=str(path))])
    with pytest.raises(planetlod.InvalidArgument, match="date line"):
        planets(planetlod, base, [dict(inset, west=170.0, east=-170.0)])
    with pytest.raises(planetlod.FileError):
        planets(planetlod, base, [str(tmp_path / "N10E010.hgt")])
    (tmp_path / "N11E010.hgt").write_bytes(b"\0" * 100)
    with pytest.raises(planetlod.ImageError, match="1201 x 1201"):
        planets(planetlod, base, [str(tmp_path / "N11E010.hgt")])
    with pytest.raises(planetlod.InvalidArgument, match="feather"):
        planets(planetlod, base, [inset], inset_feather=0.9)


def test_insets_over_a_tiled_map(planetlod, tiles, tmp_path):
    _, paths, grid = tiles
    values = np.full((256, 512), 20000, "<u2")
    path = tmp_path / "flat.r16"
    values.tofile(path)
    tiled = planetlod.TiledMap(str(path), tile=64)
    planet = planetlod.Planet(R, heightmap=tiled, height_scale=8848.0, insets=paths)
    assert planet.height(*direction(6 + 300 / 1200, 46 - 300 / 1200)) == pytest.approx(
        float(grid[300, 300]), abs=1e-6)
    assert planet.height(*direction(30.0, 10.0)) == pytest.approx(20000 / 65535 * 8848.0)


# ---- the detail field over insets ---------------------------------------------

INSET_DETAIL = dict(style="mountains", amplitude=300.0, seed=3, smallest=10.0)


@pytest.fixture(scope="module")
def detailed(planetlod, tiles, base):
    """(with insets and detail, insets alone, detail alone)."""
    _, paths, _ = tiles
    kw = dict(heightmap=base, height_scale=65535.0)
    return (planetlod.Planet(R, insets=paths, detail=INSET_DETAIL, **kw),
            planetlod.Planet(R, insets=paths, **kw),
            planetlod.Planet(R, detail=INSET_DETAIL, **kw))


def detail_part(with_detail, without, lons, lat):
    dirs = np.array([direction(lon, lat) for lon in lons]).reshape(-1).tolist()
    return np.array(with_detail.surface(dirs)[0]) - np.array(without.surface(dirs)[0])


def test_detail_starts_below_the_insets_resolution(detailed):
    """Inside a 3-arc-second inset the field keeps only the octaves below
    two of its samples: over the global map's wavelengths (a 1 km running
    mean along the ground) it has next to no amplitude, and all of it lies
    within the fine octaves' bounds; outside the mosaic the field is the
    inset-free planet's, bit for bit."""
    planet, insets_alone, detail_alone = detailed
    texel = R * math.radians(1 / 1200)
    step = math.degrees(5.0 / (R * math.cos(math.radians(45.7))))  # 5 m
    lons = 6.3 + step * np.arange(8192)  # 41 km, past the feather
    inside = detail_part(planet, insets_alone, lons, 45.7)  # clear of the void
    outside = detail_part(planet, insets_alone, lons - 1.0, 45.7)
    mean_1km = np.ones(200) / 200
    long_inside = np.convolve(inside, mean_1km, mode="valid")
    long_outside = np.convolve(outside, mean_1km, mode="valid")
    assert long_outside.std() > 1.0
    assert long_inside.std() < 2e-3 * long_outside.std()
    # the octaves a 3" inset keeps: wavelengths <= 2 samples (185 m)
    info = planet.detail
    largest = info["finest_wavelength"] * 2 ** (info["octaves"] - 1)
    first = next(i for i in range(info["octaves"]) if largest / 2 ** i <= 2 * texel)
    assert largest / 2 ** first > texel
    kept = sum(INSET_DETAIL["amplitude"] * 0.5 ** i for i in range(first, info["octaves"]))
    assert np.abs(inside).max() <= kept
    assert np.abs(inside).std() > 0.0  # finer relief than the data is still there
    # outside every inset: the detail-only planet's heights, bit for bit
    # (normals differ: with insets they come from height differences)
    for lon in (5.5, 8.5, -120.0):
        dirs = np.array([direction(lon + 1e-3 * k, 45.5) for k in range(64)]).reshape(-1)
        assert list(planet.surface(dirs.tolist())[0]) == list(
            detail_alone.surface(dirs.tolist())[0])


def test_detail_is_continuous_across_the_insets_border(detailed):
    """Across the mosaic's feathered west border the field fades from all
    octaves to the fine ones with the heights' blend: dense samples (0.8 m
    apart) step by no more than its slope explains, nowhere more than on
    either side; across the edge the tiles share nothing changes."""
    planet, insets_alone, _ = detailed
    lons = np.linspace(5.95, 6.25, 30001)
    part = detail_part(planet, insets_alone, lons, 45.3)
    steps = np.abs(np.diff(part))
    outside = steps[lons[:-1] < 5.999].max()
    assert steps.max() < 0.05
    assert steps.max() < 4.0 * outside
    lons = np.linspace(6.98, 7.02, 5001)
    steps = np.abs(np.diff(detail_part(planet, insets_alone, lons, 45.3)))
    assert steps.max() < 0.02


def inset_camera(planetlod, eye_height, lon=6.02, lat=45.4):
    """Looking east, 35 degrees down, from eye_height metres above the radius."""
    up = np.array(direction(lon, lat))
    east = np.array([-math.sin(math.radians(lon)), math.cos(math.radians(lon)), 0.0])
    forward = east * math.cos(math.radians(-35)) + up * math.sin(math.radians(-35))
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = right, np.cross(right, forward), -forward
    m[:3, 3] = up * (R + eye_height)
    return planetlod.Camera(m.tolist(), lens=30.0, clip_end=1e9, resolution_x=480,
                            resolution_y=270)


@pytest.fixture(scope="module")
def flat_detailed(planetlod, tmp_path_factory):
    """A flat 1000 m world with a flat 1000 m inset and full modulation:
    the sector bounds are the detail field's alone."""
    path = tmp_path_factory.mktemp("flat") / "N45E006.hgt"
    np.full((1201, 1201), 1000, ">i2").tofile(path)
    cubemap = planetlod.CubeMap(projection="qsc", size=64, dtype="u16")
    for face in range(6):
        cubemap.set_face(face, np.full(64 * 64, 1000, "<u2").tobytes())
    return planetlod.Planet(R, heightmap=cubemap, height_scale=65535.0, insets=[str(path)],
                            detail=dict(INSET_DETAIL, plains=1.0))


@pytest.mark.parametrize("which", ["tiles", "flat"])
def test_detail_bounds_hold_over_insets(planetlod, detailed, flat_detailed, which):
    """Sector bounds hold the detailed surface at many points of sectors
    over the inset, its feathered border and the global map around it."""
    planet = detailed[0] if which == "tiles" else flat_detailed
    ground = 3000.0 if which == "tiles" else 1000.0
    checked = 0
    # down to sectors of metres (side-distance splits near the ground),
    # where the bounds tighten around a corner's coarse octaves
    views = [(3e5, 6.02, {}), (2e4, 6.02, {}), (3000.0, 6.02, {}), (500.0, 6.02, {})]
    views += [(altitude, lon, dict(criterion="side_distance", split_border=0.25))
              for altitude in (100.0, 20.0) for lon in (6.04, 6.4)]
    for altitude, lon, kw in views:
        planet.refine(inset_camera(planetlod, ground + altitude, lon=lon, lat=45.3),
                      max_pixel_error=1.0, **kw)
        assert planet.check_invariants()
        corners = np.array(planet.sector_corners().tolist()).reshape(-1, 3, 3)
        bounds = np.array(planet.sector_heights().tolist()).reshape(-1, 2)
        rng = np.random.default_rng(int(altitude + 100 * lon))
        for k in range(len(corners)):
            points = rng.dirichlet((1.0, 1.0, 1.0), size=40) @ corners[k]
            points /= np.linalg.norm(points, axis=1)[:, None]
            h = np.array(planet.surface(points.reshape(-1).tolist())[0])
            assert h.min() >= bounds[k, 0] - 1e-3 and h.max() <= bounds[k, 1] + 1e-3, k
            checked += 1
    assert checked > 1000


def test_detail_mesh_over_an_inset_border_is_watertight(planetlod, detailed):
    """A mesh across the inset's border: shared edge vertices bit-identical
    (a closed sphere after welding), and the same bytes for 1 and 2
    threads, cached or not."""
    from test_mesh import arrays, edge_report
    planet = detailed[0]
    hits = 0
    for k, altitude in enumerate((2e4, 3000.0, 800.0)):
        planet.refine(inset_camera(planetlod, 3000.0 + altitude, lon=5.99 + 0.002 * k),
                      backface=False,
                      frustum=False, max_sectors=60000)
        base_mesh = planet.mesh(template_level=3, threads=1, cache=False)
        assert edge_report(*arrays(base_mesh)) == (0, 0, 0, 2), k
        got = planet.mesh(template_level=3, threads=2, cache=True)
        for name in ("positions", "normals", "uv", "triangles", "detail"):
            assert bytes(getattr(base_mesh, name)) == bytes(getattr(got, name)), (k, name)
        hits += planet.mesh_cache_info["hits"]
    assert hits > 0


@pytest.mark.parametrize("style", ["hills", "mountains", "craters"])
def test_batched_detail_over_insets_is_the_point_path(planetlod, tiles, base, style):
    """surface() over many directions (inside the tiles, across their
    feathered border, over the void, on the global map) evaluates the field
    in batches, each point from its own first octave; every height and
    normal is that of surface() at the point alone, bit for bit."""
    _, paths, _ = tiles
    planet = planetlod.Planet(R, heightmap=base, height_scale=65535.0, insets=paths,
                              detail=dict(style=style, amplitude=300.0, seed=4, smallest=2.0,
                                          craters=1.0))
    rng = np.random.default_rng(17)
    lons = np.concatenate([rng.uniform(5.9, 8.1, 700), rng.uniform(6.49, 6.51, 100)])
    lats = np.concatenate([rng.uniform(44.9, 46.1, 700), rng.uniform(45.49, 45.51, 100)])
    dirs = np.array([direction(lon, lat) for lon, lat in zip(lons, lats)]).reshape(-1).tolist()
    heights, normals = planet.surface(dirs)
    normals = list(normals)
    for k in range(len(lons)):
        h, n = planet.surface(dirs[3 * k:3 * k + 3])
        assert (h[0], list(n)) == (heights[k], normals[3 * k:3 * k + 3]), k


def test_detail_continuous_across_a_mosaic_of_two_resolutions(planetlod, base, tmp_path):
    """A 1-arc-second tile beside a 3-arc-second one (a shared, unfeathered
    edge): the field starts below the mosaic's coarser spacing on both, so
    it has no step at the edge, and the finer tile reports its own texel."""
    fine, _ = write_hgt(tmp_path, 6, 45, side=3601)
    coarse, _ = write_hgt(tmp_path, 7, 45)
    kw = dict(heightmap=base, height_scale=65535.0, insets=[fine, coarse])
    planet = planetlod.Planet(R, detail=INSET_DETAIL, **kw)
    plain = planetlod.Planet(R, **kw)
    lons = np.linspace(6.999, 7.001, 2001)  # 0.08 m apart
    steps = np.abs(np.diff(detail_part(planet, plain, lons, 45.3)))
    assert steps.max() < 0.01
    assert planet.texel_size(*direction(6.5, 45.3)) == pytest.approx(R * math.radians(1 / 3600))


def test_pixel_criterion_counts_an_insets_relief(planetlod, tmp_path):
    """A rough 3" tile on a flat global map, seen from 60 km: the pixel
    criterion splits where the tile's relief shows, so the mesh stays near
    the surface in view (with the global map's flatness alone it keeps
    sectors kilometres wide: 27 px at the 99th percentile)."""
    rng = np.random.default_rng(3)
    noise = rng.normal(0.0, 1.0, (1201, 1201))
    box = np.ones(16) / 16.0  # relief correlated over ~1.4 km, ~40 % slopes
    for axis in (0, 1):
        noise = np.apply_along_axis(lambda r: np.convolve(r, box, "same"), axis, noise)
    grid = np.round(2000.0 + 120.0 * noise / noise.std()).astype(">i2")
    path = tmp_path / "N45E006.hgt"
    grid.tofile(path)
    flat = planetlod.CubeMap(projection="qsc", size=64, dtype="u16")
    for face in range(6):
        flat.set_face(face, np.full(64 * 64, 1000, "<u2").tobytes())
    planet = planetlod.Planet(R, heightmap=flat, height_scale=1000.0, insets=[str(path)])
    eye = np.array(direction(6.5, 45.5)) * (R + 5000.0 + 60000.0)
    matrix = look_at(eye, (0.0, 0.0, 0.0))
    camera = planetlod.Camera(matrix, lens=50.0, sensor_width=36.0, resolution_x=1920,
                              resolution_y=1080, clip_start=1.0, clip_end=1e8)
    for _ in range(20):
        stats = planet.refine(camera, template_level=3, max_pixel_error=2.0, budget=0)
        if not stats["splits"] and not stats["merges"]:
            break
    mesh = planet.mesh(template_level=3)
    points = np.frombuffer(mesh.positions, np.float32).reshape(-1, 3).astype(float)
    points += np.array(mesh.origin)
    triangles = np.frombuffer(mesh.triangles, np.int32).reshape(-1, 3)
    pick = np.random.default_rng(4).choice(len(triangles), 4000, replace=False)
    centroids = points[triangles[pick]].mean(axis=1)
    radius = np.linalg.norm(centroids, axis=1)
    heights = np.array([planet.height(*(c / r)) for c, r in zip(centroids, radius)])
    local = (centroids - eye) @ np.array(matrix)[:3, :3]  # right, up, back
    in_view = (local[:, 2] < 0) & (np.abs(local[:, 0] / local[:, 2]) < 18.0 / 50.0) & \
        (np.abs(local[:, 1] / local[:, 2]) < 18.0 * 1080 / 1920 / 50.0)
    pixels = (np.abs(radius - (R + heights)) * camera.pixels_per_radian /
              np.linalg.norm(centroids - eye, axis=1))[in_view]
    assert in_view.mean() > 0.8
    assert np.percentile(pixels, 99) < 2.0 and pixels.mean() < 0.5, \
        (stats["sectors_total"], np.percentile(pixels, 99), pixels.max())
