"""Regional high-resolution insets (SRTM .hgt tiles, or any grid with its
lon/lat box) blended over the global map across a feathered border.  The
tiles are generated here."""
import math

import numpy as np
import pytest

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
