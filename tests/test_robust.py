"""Robustness of the C core against bad height maps (the parts that live below
the add-on): NaN texels are refused with a readable error."""
import math
import struct

import pytest


def _float_tiff(path, width, height, values):
    pixels = struct.pack(f"<{width * height}f", *values)
    tags = [(256, 4, width), (257, 4, height), (258, 3, 32), (259, 3, 1), (262, 3, 1),
            (273, 4, 8), (277, 3, 1), (278, 4, height), (279, 4, len(pixels)), (339, 3, 3)]
    ifd = struct.pack("<H", len(tags))
    for tag, kind, value in tags:
        ifd += struct.pack("<HHI", tag, kind, 1)
        ifd += struct.pack("<HH", value, 0) if kind == 3 else struct.pack("<I", value)
    ifd += struct.pack("<I", 0)
    with open(path, "wb") as f:
        f.write(b"II*\0" + struct.pack("<I", 8 + len(pixels)) + pixels + ifd)
    return str(path)


@pytest.mark.parametrize("nan_count", [64 * 32, 64 * 8])
def test_nan_heightmap_refused(planetlod, tmp_path, nan_count):
    values = [0.25] * (64 * 32)
    for i in range(nan_count):
        values[i] = math.nan
    path = _float_tiff(tmp_path / "nan.tif", 64, 32, values)
    with pytest.raises(planetlod.ImageError, match="NaN samples"):
        planetlod.Planet(6371000.0, heightmap=path, height_scale=1000.0)


def test_finite_float_heightmap_accepted(planetlod, tmp_path):
    path = _float_tiff(tmp_path / "flat.tif", 64, 32, [0.25] * (64 * 32))
    planet = planetlod.Planet(6371000.0, heightmap=path, height_scale=1000.0)
    assert planet.height(1.0, 0.0, 0.0) == pytest.approx(250.0)
    assert planet.heightmap is not None


@pytest.mark.parametrize("radius,height_scale,height_offset", [
    (100.0, 4e3, 0.0),           # 1-4 km above a 100 m planet: over ten radii
    (6371000.0, 1000.0, -4e6),   # 4,000 km down: past half the radius
    (6371000.0, -5e6, 0.0),      # a negative scale reaching 5,000 km down
])
def test_terrain_reaching_the_centre_or_far_above_refused(planetlod, tmp_path, radius,
                                                         height_scale, height_offset):
    path = _float_tiff(tmp_path / "steep.tif", 64, 32, [0.25] * (64 * 16) + [1.0] * (64 * 16))
    with pytest.raises(planetlod.InvalidArgument, match="half the radius below"):
        planetlod.Planet(radius, heightmap=path, height_scale=height_scale,
                         height_offset=height_offset)
