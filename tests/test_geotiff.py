"""GeoTIFF insets placed by their georeferencing (ModelTiepoint +
ModelPixelScale or ModelTransformation, PixelIsArea / PixelIsPoint,
GDAL_NODATA).  The GeoTIFFs are written here by a minimal TIFF writer."""
import math
import struct

import numpy as np
import pytest

R = 6371000.0
WGS84 = {1024: 2, 1025: 1, 2048: 4326, 2054: 9102}  # geographic, PixelIsArea, degrees
TIFF_TYPES = {"<i2": (16, 2), "<u2": (16, 1), "<f4": (32, 3), "<i4": (32, 2)}


def write_geotiff(path, grid, scale=None, tiepoint=None, transform=None, geokeys=None,
                  nodata=None, byteorder="<", big_tiff=False):
    """A one-strip, one-sample TIFF (or BigTIFF) with GeoTIFF tags, in either
    byte order."""
    grid = np.asarray(grid)
    bits, sample_format = TIFF_TYPES[grid.dtype.newbyteorder("<").str]
    height, width = grid.shape
    pixels = grid.astype(grid.dtype.newbyteorder(byteorder)).tobytes()
    entries = []  # (tag, type, count, payload)

    def add(tag, typ, values):
        if typ == 2:  # ASCII
            payload = values.encode() + b"\0"
            entries.append((tag, typ, len(payload), payload))
        else:
            fmt = byteorder + {3: "H", 4: "I", 12: "d"}[typ]
            entries.append((tag, typ, len(values),
                            b"".join(struct.pack(fmt, v) for v in values)))

    add(256, 4, [width]), add(257, 4, [height]), add(258, 3, [bits]), add(259, 3, [1])
    add(262, 3, [1]), add(273, 4, [0]), add(277, 3, [1]), add(278, 4, [height])
    add(279, 4, [len(pixels)]), add(284, 3, [1]), add(339, 3, [sample_format])
    if scale is not None:
        add(33550, 12, list(scale))
    if tiepoint is not None:
        add(33922, 12, list(tiepoint))
    if transform is not None:
        add(34264, 12, list(transform))
    if geokeys is not None:
        keys = [1, 1, 0, len(geokeys)]
        for key, value in sorted(geokeys.items()):
            keys += [key, 0, 1, value]
        add(34735, 3, keys)
    if nodata is not None:
        add(42113, 2, str(nodata))
    entries.sort()
    inline, entry, count_fmt, offset_fmt = (8, 20, "Q", "Q") if big_tiff else (4, 12, "H", "I")
    head_size = 16 if big_tiff else 8
    extra_at = head_size + struct.calcsize(count_fmt) + entry * len(entries) + inline
    extra, offsets = b"", {}
    for tag, _, _, payload in entries:
        if len(payload) > inline:
            offsets[tag] = extra_at + len(extra)
            extra += payload + b"\0" * (len(payload) % 2)
    pixels_at = extra_at + len(extra)
    table = b""
    for tag, typ, count, payload in entries:
        if tag == 273:
            payload = struct.pack(byteorder + "I", pixels_at)
        head = struct.pack(byteorder + "HH" + ("Q" if big_tiff else "I"), tag, typ, count)
        if len(payload) > inline:
            table += head + struct.pack(byteorder + offset_fmt, offsets[tag])
        else:
            table += head + payload.ljust(inline, b"\0")
    order = b"II" if byteorder == "<" else b"MM"
    head = order + (struct.pack(byteorder + "HHHQ", 43, 8, 0, head_size) if big_tiff
                    else struct.pack(byteorder + "HI", 42, head_size))
    data = (head + struct.pack(byteorder + count_fmt, len(entries)) + table + b"\0" * inline +
            extra + pixels)
    with open(path, "wb") as f:
        f.write(data)
    return str(path)


def direction(lon, lat):
    lon, lat = math.radians(lon), math.radians(lat)
    return (math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat))


SIDE = 241  # a 1 deg x 1 deg tile at 15 arc-seconds, edge samples repeated as SRTM's
STEP = 1.0 / (SIDE - 1)


def tile_grid(lon0, lat0, side=SIDE):
    la = np.linspace(lat0 + 1, lat0, side)[:, None]  # row 0 north
    lo = np.linspace(lon0, lon0 + 1, side)[None, :]
    field = 1500.0 + 700.0 * np.sin(np.radians(lo * 900.0)) * np.cos(np.radians(la * 700.0))
    return np.round(field).astype("<i2")


def area_tiepoint(lon0, lat0):
    """PixelIsArea: the raster's outer corner, half a pixel beyond the corner samples."""
    return (0.0, 0.0, 0.0, lon0 - STEP / 2, lat0 + 1 + STEP / 2, 0.0)


@pytest.fixture(scope="module")
def base(planetlod):
    cubemap = planetlod.CubeMap(projection="qsc", size=32, dtype="u16")
    rng = np.random.default_rng(3)
    for face in range(6):
        cubemap.set_face(face, rng.integers(100, 200, 32 * 32).astype("<u2").tobytes())
    return cubemap


def planet(planetlod, base, insets, feather=0.0):
    return planetlod.Planet(R, heightmap=base, height_scale=65535.0, insets=insets,
                            inset_feather=feather)


def heights(p, points):
    return np.array([p.height(*direction(lon, lat)) for lon, lat in points])


SAMPLE_POINTS = [(6.0 + c * STEP, 46.0 - r * STEP) for r, c in
                 ((3, 5), (60, 200), (120, 120), (200, 31), (239, 238))]
BETWEEN_POINTS = [(6.123456, 45.654321), (6.5, 45.5), (6.987, 45.013)]


def test_tags_place_the_tile_as_an_explicit_box(planetlod, base, tmp_path):
    grid = tile_grid(6, 45)
    tif = write_geotiff(tmp_path / "dem.tif", grid, scale=(STEP, STEP, 0.0),
                        tiepoint=area_tiepoint(6, 45), geokeys=WGS84)
    raw = tmp_path / "dem.raw"
    grid.tofile(raw)
    by_box = planet(planetlod, base, [dict(path=str(raw), west=6.0, south=45.0, east=7.0,
                                           north=46.0,
                                           raw=dict(width=SIDE, height=SIDE, dtype="i16"))])
    points = SAMPLE_POINTS + BETWEEN_POINTS
    reference = heights(by_box, points)
    for inset in (tif, dict(path=tif), dict(path=tif, west=6.0, south=45.0, east=7.0, north=46.0)):
        by_tags = planet(planetlod, base, [inset])
        assert np.array_equal(heights(by_tags, points), reference)  # bit for bit
    # on the samples: the file's metres (int16 read as stored, not normalised)
    placed = planet(planetlod, base, [tif])
    for (lon, lat), (r, c) in zip(SAMPLE_POINTS, ((3, 5), (60, 200), (120, 120), (200, 31),
                                                  (239, 238))):
        assert placed.height(*direction(lon, lat)) == pytest.approx(float(grid[r, c]), abs=1e-3)
    assert placed.texel_size(*direction(6.5, 45.5)) == pytest.approx(R * math.radians(STEP))
    # a big-endian file and a ModelTransformation give the same surface
    big = write_geotiff(tmp_path / "big.tif", grid, scale=(STEP, STEP, 0.0),
                        tiepoint=area_tiepoint(6, 45), geokeys=WGS84, byteorder=">")
    x0, y0 = area_tiepoint(6, 45)[3:5]
    matrix = write_geotiff(tmp_path / "matrix.tif", grid, geokeys=WGS84,
                           transform=(STEP, 0, 0, x0, 0, -STEP, 0, y0, 0, 0, 0, 0, 0, 0, 0, 1))
    bigtiff = write_geotiff(tmp_path / "bigtiff.tif", grid, scale=(STEP, STEP, 0.0),
                            tiepoint=area_tiepoint(6, 45), geokeys=WGS84, big_tiff=True)
    for path in (big, matrix, bigtiff):
        assert np.array_equal(heights(planet(planetlod, base, [path]), points), reference)


def test_pixel_is_point_and_pixel_is_area_differ_by_half_a_texel(planetlod, base, tmp_path):
    grid = tile_grid(6, 45)
    tie = (0.0, 0.0, 0.0, 6.0, 46.0, 0.0)
    point = write_geotiff(tmp_path / "point.tif", grid, scale=(STEP, STEP, 0.0), tiepoint=tie,
                          geokeys={**WGS84, 1025: 2})
    area = write_geotiff(tmp_path / "area.tif", grid, scale=(STEP, STEP, 0.0), tiepoint=tie,
                         geokeys=WGS84)
    # PixelIsPoint: the tiepoint is sample (0, 0): the tile covers 6..7, 45..46
    at_point = planet(planetlod, base, [point])
    raw = tmp_path / "dem.raw"
    grid.tofile(raw)
    by_box = planet(planetlod, base, [dict(path=str(raw), west=6.0, south=45.0, east=7.0,
                                           north=46.0,
                                           raw=dict(width=SIDE, height=SIDE, dtype="i16"))])
    points = SAMPLE_POINTS + BETWEEN_POINTS
    assert np.array_equal(heights(at_point, points), heights(by_box, points))
    # PixelIsArea, same tiepoint: the tiepoint is the outer corner, the
    # samples lie half a texel east and south
    at_area = planet(planetlod, base, [area])
    for lon, lat in points:
        shifted = (lon + STEP / 2, lat - STEP / 2)
        assert at_area.height(*direction(*shifted)) == pytest.approx(
            at_point.height(*direction(lon, lat)), abs=1e-3)
    # the area tile starts half a texel east of 6 deg: the global map there
    plain = planetlod.Planet(R, heightmap=base, height_scale=65535.0)
    d = direction(6.0 + STEP / 4, 45.5)
    assert at_area.height(*d) == plain.height(*d)
    assert at_point.height(*d) != plain.height(*d)
    # a box that mistakes the raster's outer corner for the samples' is refused
    with pytest.raises(planetlod.InvalidArgument, match="disagrees.*PixelIsArea"):
        planet(planetlod, base, [dict(path=area, west=6.0, south=45.0, east=7.0, north=46.0)])


def test_nodata_falls_back_to_the_global_map(planetlod, base, tmp_path):
    grid = tile_grid(6, 45)
    grid[100:140, 100:140] = -9999
    tif = write_geotiff(tmp_path / "voids.tif", grid, scale=(STEP, STEP, 0.0),
                        tiepoint=area_tiepoint(6, 45), geokeys=WGS84, nodata=-9999)
    placed = planet(planetlod, base, [tif])
    plain = planetlod.Planet(R, heightmap=base, height_scale=65535.0)
    inside_voids = (6.0 + 120 * STEP, 46.0 - 120 * STEP)
    assert placed.height(*direction(*inside_voids)) == plain.height(*direction(*inside_voids))
    assert placed.height(*direction(6.2, 45.2)) == pytest.approx(
        float(grid[round(0.8 / STEP), round(0.2 / STEP)]), abs=1e-3)
    lo, hi = placed.height_range()
    assert lo > -9000.0  # the no-data value is no height
    # float data with a float no-data value
    values = grid.astype("<f4")
    values[grid == -9999] = -3.4028234663852886e38
    tif = write_geotiff(tmp_path / "float.tif", values, scale=(STEP, STEP, 0.0),
                        tiepoint=area_tiepoint(6, 45), geokeys=WGS84,
                        nodata="-3.4028234663852886e+38")
    placed_float = planet(planetlod, base, [tif])
    assert placed_float.height(*direction(*inside_voids)) == plain.height(
        *direction(*inside_voids))
    assert placed_float.height(*direction(6.2, 45.2)) == placed.height(*direction(6.2, 45.2))


def test_adjacent_tiles_meet_without_overlap(planetlod, base, tmp_path):
    tiles = [write_geotiff(tmp_path / f"t{lon}.tif", tile_grid(lon, 45),
                           scale=(STEP, STEP, 0.0), tiepoint=area_tiepoint(lon, 45),
                           geokeys=WGS84) for lon in (6, 7)]
    mosaic = planet(planetlod, base, tiles, feather=0.1)
    lons = np.linspace(6.95, 7.05, 201)
    h = np.array([mosaic.height(*direction(lon, 45.3)) for lon in lons])
    assert np.max(np.abs(np.diff(h))) < 60.0  # across the shared edge: no feather, no step


def test_unsupported_georeferencing_is_a_clear_error(planetlod, base, tmp_path):
    grid = tile_grid(6, 45, side=16)
    cases = {
        "projected": dict(scale=(30.0, 30.0, 0.0), tiepoint=(0, 0, 0, 500000.0, 5e6, 0),
                          geokeys={1024: 1, 1025: 1, 3072: 32632}),
        "rotated": dict(transform=(0.01, 0.002, 0, 6, 0.002, -0.01, 0, 46, 0, 0, 0, 0, 0, 0, 0, 1),
                        geokeys=WGS84),
        "EPSG:4230": dict(scale=(0.01, 0.01, 0), tiepoint=(0, 0, 0, 6, 46, 0),
                          geokeys={**WGS84, 2048: 4230}),
        "names no geographic CRS": dict(scale=(0.01, 0.01, 0), tiepoint=(0, 0, 0, 6, 46, 0),
                                        geokeys={1024: 2}),
        "tiepoints": dict(scale=(0.01, 0.01, 0), geokeys=WGS84,
                          tiepoint=(0, 0, 0, 6, 46, 0, 15, 15, 0, 6.2, 45.8, 0)),
        "north-up": dict(scale=(0.01, -0.01, 0), tiepoint=(0, 0, 0, 6, 46, 0), geokeys=WGS84),
    }
    for what, tags in cases.items():
        path = write_geotiff(tmp_path / "bad.tif", grid, **tags)
        for inset in (path, dict(path=path), dict(path=path, west=6, south=45, east=7, north=46)):
            with pytest.raises(planetlod.ImageError, match=what):
                planet(planetlod, base, [inset])
    # a TIFF without georeferencing still needs its box
    plain = write_geotiff(tmp_path / "plain.tif", grid)
    with pytest.raises(planetlod.InvalidArgument, match="not a GeoTIFF"):
        planet(planetlod, base, [dict(path=plain)])
    with pytest.raises(planetlod.InvalidArgument, match="N45E006.hgt or a GeoTIFF"):
        planet(planetlod, base, [plain])
    with pytest.raises(planetlod.InvalidArgument, match="all four"):
        planet(planetlod, base, [dict(path=plain, west=6.0)])


def test_truncated_or_corrupt_files_are_errors(planetlod, base, tmp_path):
    good = write_geotiff(tmp_path / "good.tif", tile_grid(6, 45), scale=(STEP, STEP, 0.0),
                         tiepoint=area_tiepoint(6, 45), geokeys=WGS84, nodata=-9999)
    data = open(good, "rb").read()
    for n, cut in enumerate((6, 20, 120, 200, 400, len(data) // 2, len(data) - 1)):
        path = tmp_path / f"cut{n}.tif"
        path.write_bytes(data[:cut])
        with pytest.raises(planetlod.ImageError, match="corrupt|truncated|not a readable"):
            planet(planetlod, base, [str(path)])
    with pytest.raises(planetlod.FileError, match="missing.tif"):
        planet(planetlod, base, [str(tmp_path / "missing.tif")])
    # an offset beyond the file's end in a tag that places the raster
    broken = bytearray(data)
    at = data.index(struct.pack("<HHI", 33550, 12, 3))
    broken[at + 8:at + 12] = struct.pack("<I", 10 ** 9)
    (tmp_path / "offset.tif").write_bytes(bytes(broken))
    with pytest.raises(planetlod.ImageError, match="corrupt or truncated"):
        planet(planetlod, base, [str(tmp_path / "offset.tif")])
    # random bytes, a random tail
    rng = np.random.default_rng(5)
    for n in range(20):
        junk = bytearray(data[:int(rng.integers(8, len(data)))])
        for _ in range(8):
            junk[int(rng.integers(0, len(junk)))] = int(rng.integers(0, 256))
        path = tmp_path / f"junk{n}.tif"
        path.write_bytes(bytes(junk))
        try:
            planet(planetlod, base, [str(path)])
        except (planetlod.ImageError, planetlod.InvalidArgument):
            pass
