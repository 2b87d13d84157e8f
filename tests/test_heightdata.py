"""Height data people bring: headerless RAW/R16 grids, SRTM .hgt tiles,
signed samples and a height offset (datum).  All maps are generated here."""
import math

import numpy as np
import pytest


def car_texels(cubemap):
    """The CAR map's texels as a (rows, cols) float array, row 0 = north."""
    rows, cols = cubemap.face_shape[1], cubemap.face_shape[0]
    dtype = {"u8": np.uint8, "u16": np.uint16, "f32": np.float32}[cubemap.dtype]
    return np.frombuffer(bytes(cubemap.face(0)), dtype).reshape(rows, cols)[::-1]


def identity_car(planetlod, path, rows, **kwargs):
    return planetlod.CubeMap.from_image(str(path), projection="car", size=rows, filter="nearest",
                                        **kwargs)


@pytest.mark.parametrize("dtype,numpy_type", [("u8", "u1"), ("u16", "u2"), ("i16", "i2"),
                                              ("f32", "f4")])
@pytest.mark.parametrize("byteorder", ["little", "big"])
def test_raw_grid_reads_every_type_and_byte_order(planetlod, tmp_path, dtype, numpy_type,
                                                  byteorder):
    rng = np.random.default_rng(7)
    info = np.iinfo(numpy_type) if numpy_type != "f4" else None
    values = (rng.integers(info.min, info.max, size=(16, 32), endpoint=True) if info
              else rng.normal(0.0, 3000.0, size=(16, 32)))
    grid = values.astype(("<" if byteorder == "little" else ">") + numpy_type)
    path = tmp_path / "grid.raw"
    grid.tofile(path)
    raw = dict(width=32, height=16, dtype=dtype, byteorder=byteorder)
    texels = car_texels(identity_car(planetlod, path, 16, raw=raw))
    # u8/u16 keep their type (normalised on sampling); i16 becomes the
    # integer values as float32; f32 is as stored
    assert texels.dtype == {"u8": np.uint8, "u16": np.uint16}.get(dtype, np.float32)
    np.testing.assert_array_equal(texels, grid.astype(texels.dtype))


def test_r16_size_guessed_square_or_two_to_one(planetlod, tmp_path):
    grid = (np.arange(40 * 20, dtype=np.uint32).reshape(20, 40) * 81 % 65536).astype("<u2")
    path = tmp_path / "terrain.r16"
    grid.tofile(path)
    texels = car_texels(identity_car(planetlod, path, 20))
    np.testing.assert_array_equal(texels, grid)
    (tmp_path / "odd.r16").write_bytes(b"\0" * (2 * 40 * 21))
    with pytest.raises(planetlod.ImageError, match="not a square or 2:1 grid"):
        planetlod.CubeMap.from_image(str(tmp_path / "odd.r16"))


def test_raw_grid_errors_are_clear(planetlod, tmp_path):
    path = tmp_path / "grid.raw"
    np.zeros((8, 16), "<u2").tofile(path)
    with pytest.raises(planetlod.ImageError, match="256 bytes; 16x9 u16 samples need 288"):
        planetlod.CubeMap.from_image(str(path), raw=dict(width=16, height=9, dtype="u16"))
    with pytest.raises(planetlod.InvalidArgument, match="dtype"):
        planetlod.CubeMap.from_image(str(path), raw=dict(width=16, height=8, dtype="i32"))
    with pytest.raises(planetlod.InvalidArgument, match="byteorder"):
        planetlod.CubeMap.from_image(str(path), raw=dict(width=16, height=8, byteorder="middle"))
    with pytest.raises(planetlod.InvalidArgument, match="width and height"):
        planetlod.CubeMap.from_image(str(path), raw=dict(width=0, height=8))
    with pytest.raises(planetlod.InvalidArgument, match="mapping"):
        planetlod.CubeMap.from_image(str(path), raw=(16, 8))
    with pytest.raises(planetlod.FileError):
        planetlod.CubeMap.from_image(str(tmp_path / "missing.raw"),
                                     raw=dict(width=16, height=8))
    with pytest.raises(planetlod.InvalidArgument, match="not to a CubeMap"):
        planetlod.Planet(1000.0, heightmap=planetlod.CubeMap(size=4), height_signed=True)


def write_hgt(path, side, fill):
    lat = np.linspace(0.0, 1.0, side)[:, None]
    lon = np.linspace(0.0, 1.0, side)[None, :]
    heights = fill(lon, lat).astype(">i2")
    heights.tofile(path)
    return heights


def test_hgt_tile_in_metres_with_voids(planetlod, tmp_path):
    path = tmp_path / "N45E006.hgt"
    heights = write_hgt(path, 1201, lambda lon, lat: 3000.0 * lon - 400.0 * lat)
    heights[600, 600] = -32768
    heights.tofile(path)
    # read through a CAR map of the same grid (a tile is not 2:1: warned)
    with pytest.warns(UserWarning, match="not 2:1"):
        cubemap = identity_car(planetlod, path, 1201)
    assert cubemap.dtype == "f32"
    texels = car_texels(cubemap)
    # a CAR map of 1201 rows has 2402 columns: each tile column twice
    sampled = texels[:, ::2]
    void = np.isnan(sampled)
    assert void.sum() == 1 and void[600, 600]
    ok = ~void
    np.testing.assert_array_equal(sampled[ok], heights.astype(np.float32)[ok])
    assert heights.min() < 0  # signed metres survive
    with pytest.raises(planetlod.ImageError, match="NaN samples"):
        with pytest.warns(UserWarning):
            planetlod.Planet(6371000.0, "car", heightmap=str(path), heightmap_size=1201)


def test_hgt_sizes(planetlod, tmp_path):
    for side in (1201, 3601):
        path = tmp_path / f"S12W077_{side}.hgt"
        np.full((side, side), 250, ">i2").tofile(path)
        with pytest.warns(UserWarning):
            cubemap = planetlod.CubeMap.from_image(str(path), projection="car", size=8)
        assert car_texels(cubemap).min() == car_texels(cubemap).max() == 250.0
    (tmp_path / "N00E000.hgt").write_bytes(b"\0" * 1000)
    with pytest.raises(planetlod.ImageError, match="1201 x 1201"):
        planetlod.CubeMap.from_image(str(tmp_path / "N00E000.hgt"))


def test_signed_sixteen_bit_png(planetlod, tmp_path):
    values = np.array([[-12000, -1, 0, 1], [2, 300, 32767, -32768]], np.int16)
    car = planetlod.CubeMap(projection="car", size=2, dtype="u16")
    car.set_face(0, values[::-1].astype("<i2").view("<u2").tobytes())
    path = tmp_path / "signed.png"
    car.save(str(path))
    unsigned = car_texels(identity_car(planetlod, path, 2))
    np.testing.assert_array_equal(unsigned, values.view(np.uint16))
    signed = car_texels(identity_car(planetlod, path, 2, signed=True))
    np.testing.assert_array_equal(signed, values.astype(np.float32))
    # the planet: heights = value * height_scale + height_offset
    planet = planetlod.Planet(6371000.0, "car", heightmap=str(path), height_signed=True,
                              height_scale=0.5, height_offset=100.0, heightmap_size=2)
    assert planet.height_range() == (-32768 * 0.5 + 100.0, 32767 * 0.5 + 100.0)


def sea_floor_map(planetlod, size=32):
    rng = np.random.default_rng(3)
    cubemap = planetlod.CubeMap(projection="qsc", size=size, dtype="u16")
    for face in range(6):
        cubemap.set_face(face, rng.integers(0, 65535, size * size, endpoint=True)
                         .astype("<u2").tobytes())
    return cubemap


def test_height_offset_shifts_heights_bounds_and_mesh(planetlod):
    cubemap = sea_floor_map(planetlod)
    base = planetlod.Planet(6371000.0, heightmap=cubemap, height_scale=9000.0)
    deep = planetlod.Planet(6371000.0, heightmap=cubemap, height_scale=9000.0,
                            height_offset=-11000.0, sea_level=0.0)
    assert deep.height_offset == -11000.0 and base.height_offset == 0.0
    lo, hi = base.height_range()
    assert deep.height_range() == (lo - 11000.0, hi - 11000.0)
    rng = np.random.default_rng(5)
    dirs = rng.normal(size=(500, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    for d in dirs:
        assert deep.height(*d) == base.height(*d) + -11000.0
    heights, normals = deep.surface(dirs.ravel().tolist())
    base_heights, base_normals = base.surface(dirs.ravel().tolist())
    np.testing.assert_array_equal(np.array(heights.tolist()),
                                  np.array(base_heights.tolist()) - 11000.0)
    # the normals of the lowered sphere: nearly those of the same relief
    angle = np.degrees(np.arccos(np.clip(np.sum(
        np.array(normals.tolist()).reshape(-1, 3) * np.array(base_normals.tolist()).reshape(-1, 3),
        axis=1), -1.0, 1.0)))
    assert angle.max() < 0.5
    # a camera over the sea floor: the mesh lies at radius + height, the
    # sector bounds below the sea level
    up = np.array([0.3, 0.2, 0.93])
    up /= np.linalg.norm(up)
    eye = up * (6371000.0 - 11000.0 + 20000.0)
    forward = -up
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    cam_up = np.cross(right, forward)
    matrix = np.eye(4)
    matrix[:3, 0], matrix[:3, 1], matrix[:3, 2], matrix[:3, 3] = right, cam_up, -forward, eye
    camera = planetlod.Camera(matrix.tolist(), lens=20.0, clip_end=1e8, resolution_x=320,
                              resolution_y=180)
    stats = deep.refine(camera, max_pixel_error=2.0, skip_sea=False)
    assert stats["sectors_after_frustum"] > 0
    bounds = np.array(deep.sector_heights().tolist()).reshape(-1, 2)
    assert bounds.max() < 0.0 and bounds.min() >= lo - 11000.0 - 1.0
    mesh = deep.mesh(template_level=2)
    positions = np.frombuffer(bytes(mesh.positions), np.float32).reshape(-1, 3).astype(float)
    points = positions + np.array(mesh.origin)
    radii = np.linalg.norm(points, axis=1)
    assert radii.max() < 6371000.0 and radii.min() > 6371000.0 - 11000.0 - 1.0
    directions = points / radii[:, None]
    expected = np.array([deep.height(*d) for d in directions[:50]]) + 6371000.0
    np.testing.assert_allclose(radii[:50], expected, atol=1.0)


def test_height_offset_errors(planetlod):
    cubemap = sea_floor_map(planetlod, 8)
    with pytest.raises(planetlod.InvalidArgument, match="height_offset"):
        planetlod.Planet(1000.0, heightmap=cubemap, height_offset=math.inf)
    with pytest.raises(planetlod.InvalidArgument):
        planetlod.Planet(1000.0, heightmap=cubemap, height_offset=-600.0)  # below the centre
