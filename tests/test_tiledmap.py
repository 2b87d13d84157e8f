"""Height maps beyond the in-memory cap, read out of core: planetlod.TiledMap
(a tile file written once next to the map, a bounded tile cache).  The maps
are generated here: a procedural 4096 x 2048 16-bit grid stands in for the
86400 x 43200 global map of the benchmark (bench/bench_bigmap.py)."""
import math
import os

import numpy as np
import pytest

W, H = 4096, 2048
R = 6371000.0


def relief(lon, lat):
    """A smooth but busy 16-bit test field of lon/lat in radians."""
    value = (0.5 + 0.2 * np.sin(3 * lon) * np.cos(2 * lat) + 0.15 * np.sin(37 * lon + 11 * lat)
             + 0.1 * np.cos(101 * lat) * np.sin(53 * lon))
    return np.clip(value, 0.0, 1.0)


@pytest.fixture(scope="module")
def big_map(tmp_path_factory):
    folder = tmp_path_factory.mktemp("tiled")
    lat = (90.0 - (np.arange(H) + 0.5) * 180.0 / H)[:, None]  # north first
    lon = (-180.0 + (np.arange(W) + 0.5) * 360.0 / W)[None, :]
    grid = np.round(relief(np.radians(lon), np.radians(lat)) * 65535).astype("<u2")
    path = folder / "global.r16"
    grid.tofile(path)
    return path, grid


@pytest.fixture(scope="module")
def tiled(planetlod, big_map):
    path, _ = big_map
    return planetlod.TiledMap(str(path), tile=64, cache_bytes=4 << 20)


@pytest.fixture(scope="module")
def in_memory(planetlod, big_map):
    path, _ = big_map
    return planetlod.CubeMap.from_image(str(path), projection="car", size=H, filter="nearest")


def random_dirs(n, seed=1):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    special = [(0, 0, 1), (0, 0, -1), (-1, 0, 0), (-1, 1e-12, 0), (-1, -1e-12, 0), (1, 0, 0),
               (0.3, -0.1, 0.95)]
    special = np.array(special, float)
    special /= np.linalg.norm(special, axis=1)[:, None]
    return np.vstack([d, special])


def test_tile_file_written_once_next_to_the_map(planetlod, big_map, tiled):
    path, grid = big_map
    assert tiled.tiles_path == str(path) + ".plodtiles"
    assert os.path.exists(tiled.tiles_path)
    assert (tiled.width, tiled.height, tiled.dtype) == (W, H, "u16")
    mtime = os.path.getmtime(tiled.tiles_path)
    again = planetlod.TiledMap(str(path), tile=64)
    assert os.path.getmtime(again.tiles_path) == mtime  # reused, not rebuilt
    lo, hi = tiled.range()
    assert lo == grid.min() / 65535 and hi == grid.max() / 65535


def test_samples_equal_the_in_memory_map_bit_for_bit(planetlod, tiled, in_memory):
    a = planetlod.Planet(R, "car", heightmap=tiled, height_scale=8000.0, height_offset=-100.0)
    b = planetlod.Planet(R, "car", heightmap=in_memory, height_scale=8000.0,
                         height_offset=-100.0)
    assert a.heightmap is tiled
    dirs = random_dirs(3000)
    ha = np.array([a.height(*d) for d in dirs])
    hb = np.array([b.height(*d) for d in dirs])
    np.testing.assert_array_equal(ha, hb)
    assert a.height_range() == b.height_range()
    heights, normals = a.surface(dirs.ravel().tolist())
    np.testing.assert_array_equal(np.array(heights.tolist()),
                                  np.array(b.surface(dirs.ravel().tolist())[0].tolist()))
    n = np.array(normals.tolist()).reshape(-1, 3)
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    assert np.all(np.sum(n * dirs, axis=1) > 0.5)
    # the tile cache never holds more than its bound
    assert 0 < tiled.cached_bytes <= tiled.cache_bytes == 4 << 20


def look_down(lon, lat, altitude, pitch=-30.0):
    lon, lat = math.radians(lon), math.radians(lat)
    up = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    east = np.array([-math.sin(lon), math.cos(lon), 0.0])
    p = math.radians(pitch)
    forward = east * math.cos(p) + up * math.sin(p)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    cam_up = np.cross(right, forward)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, cam_up, -forward, up * (R + altitude)
    return m.tolist()


@pytest.mark.parametrize("projection", ["qsc", "car"])
def test_refined_sectors_bound_the_surface(planetlod, tiled, projection):
    planet = planetlod.Planet(R, projection, heightmap=tiled, height_scale=8000.0)
    for altitude in (2e6, 3e4, 800.0):
        camera = planetlod.Camera(look_down(7.0, 46.0, 8000.0 + altitude), lens=30.0,
                                  clip_end=1e9, resolution_x=480, resolution_y=270)
        stats = planet.refine(camera, max_pixel_error=2.0)
        assert stats["sectors_after_frustum"] > 0
        assert planet.check_invariants()
        corners = np.array(planet.sector_corners().tolist()).reshape(-1, 3, 3)
        bounds = np.array(planet.sector_heights().tolist()).reshape(-1, 2)
        rng = np.random.default_rng(int(altitude))
        pick = rng.choice(len(corners), size=min(60, len(corners)), replace=False)
        for k in pick:
            w = rng.dirichlet((1.0, 1.0, 1.0), size=40)
            points = w @ corners[k]
            points /= np.linalg.norm(points, axis=1)[:, None]
            h = np.array([planet.height(*p) for p in points])
            assert h.min() >= bounds[k, 0] - 1e-3 and h.max() <= bounds[k, 1] + 1e-3
        mesh = planet.mesh(template_level=2)
        positions = np.frombuffer(bytes(mesh.positions), np.float32).reshape(-1, 3)
        assert np.isfinite(positions).all() and mesh.vertex_count > 0


def test_detail_starts_at_the_tiled_maps_texel(planetlod, tiled, in_memory):
    """The detail field's first octave is two texels of the map it refines,
    out of core as in memory, not a fraction of the radius."""
    detail = dict(amplitude=100.0, smallest=1.0)
    out_of_core = planetlod.Planet(R, "car", heightmap=tiled, height_scale=8000.0, detail=detail)
    loaded = planetlod.Planet(R, "car", heightmap=in_memory, height_scale=8000.0, detail=detail)
    texel = math.pi / H * R
    first = out_of_core.detail["finest_wavelength"] * 2.0 ** (out_of_core.detail["octaves"] - 1)
    assert first == pytest.approx(2.0 * texel, rel=1e-9)
    assert out_of_core.detail["octaves"] == loaded.detail["octaves"]


def test_texel_size_and_bounded_memory_in_the_core(planetlod, tiled):
    planet = planetlod.Planet(R, "qsc", heightmap=tiled, height_scale=8000.0)
    assert planet.texel_size(1.0, 0.0, 0.0) == pytest.approx(math.pi / H * R)
    sphere = planetlod.Planet(R)
    assert sphere.texel_size(1.0, 0.0, 0.0) == math.inf


def test_bad_and_changed_files(planetlod, tmp_path):
    with pytest.raises(planetlod.FileError):
        planetlod.TiledMap(str(tmp_path / "missing.r16"))
    odd = tmp_path / "odd.r16"
    odd.write_bytes(b"\0" * (2 * 40 * 21))
    with pytest.raises(planetlod.ImageError, match="not a square or 2:1"):
        planetlod.TiledMap(str(odd))
    raw = tmp_path / "grid.raw"
    np.zeros((8, 16), "<u2").tofile(raw)
    with pytest.raises(planetlod.ImageError, match="need 288"):
        planetlod.TiledMap(str(raw), raw=dict(width=16, height=9))
    assert not os.path.exists(str(raw) + ".plodtiles")
    assert not os.path.exists(str(raw) + ".plodtiles.partial")
    with pytest.raises(planetlod.InvalidArgument, match="tile size"):
        planetlod.TiledMap(str(raw), raw=dict(width=16, height=8), tile=48)
    grid = tmp_path / "g.r16"
    values = (np.arange(64 * 32) * 37 % 5000).astype("<u2")
    values.tofile(grid)
    # a tile file cut short after it was written: a clear error
    cut = tmp_path / "cut.plodtiles"
    planetlod.TiledMap(str(grid), tiles=str(cut), tile=16)
    with open(cut, "r+b") as f:
        f.truncate(2000)
    with pytest.raises(planetlod.ImageError, match="truncated"):
        planetlod.TiledMap(str(grid), tiles=str(cut), tile=16)
    # a changed map is re-tiled
    first = planetlod.TiledMap(str(grid), tile=16)
    assert first.range()[1] == values.max() / 65535
    values = values + 1000
    values.tofile(grid)
    os.utime(grid, (1, 1))
    second = planetlod.TiledMap(str(grid), tile=16)
    assert second.range()[1] == values.max() / 65535
    # a tile file truncated under an open map: NaN samples, counted, no crash
    third = planetlod.TiledMap(str(grid), tile=16, cache_bytes=1)
    with open(third.tiles_path, "r+b") as f:
        f.truncate(512 + 512)  # the header, the bounds and the first tile
    values = [third.sample(lon, 0.0) for lon in range(-180, 180, 7)]
    assert any(math.isnan(v) for v in values) and third.read_errors > 0
    # texels that contradict the bounds the file declares (a damaged file):
    # the tile is refused as a read error, never sampled outside its bounds
    fourth = planetlod.TiledMap(str(grid), tiles=str(tmp_path / "damaged.plodtiles"), tile=16,
                                cache_bytes=1)
    tile_bytes = 16 * 16 * 2
    with open(fourth.tiles_path, "r+b") as f:
        f.seek(-tile_bytes, os.SEEK_END)  # the last tile: south-east corner
        f.write(b"\xff" * tile_bytes)
    low, high = fourth.range()
    assert math.isnan(fourth.sample(170.0, -80.0)) and fourth.read_errors > 0
    assert low <= fourth.sample(-170.0, 80.0) <= high


def test_nan_texels_refused_by_the_planet(planetlod, tmp_path):
    grid = np.full((32, 64), 100.0, ">f4")
    grid[5, 7] = np.nan
    path = tmp_path / "voids.raw"
    grid.tofile(path)
    tiled = planetlod.TiledMap(str(path), raw=dict(width=64, height=32, dtype="f32",
                                                   byteorder="big"), tile=16)
    assert tiled.nan_count == 1 and tiled.dtype == "f32"
    with pytest.raises(planetlod.ImageError, match="NaN"):
        planetlod.Planet(R, heightmap=tiled)


def test_signed_tiles(planetlod, tmp_path):
    values = (np.arange(64 * 32).reshape(32, 64) * 37 % 20000 - 10000).astype("<i2")
    path = tmp_path / "sea.r16"
    values.view("<u2").tofile(path)
    tiled = planetlod.TiledMap(str(path), signed=True, tile=16)
    assert tiled.dtype == "f32" and tiled.range() == (values.min(), values.max())
    planet = planetlod.Planet(R, heightmap=tiled, height_offset=-50.0)
    assert planet.height_range() == (values.min() - 50.0, values.max() - 50.0)
