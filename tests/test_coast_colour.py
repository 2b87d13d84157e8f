"""The bundled Earth's colour along its coasts (tools/fill_coast.py): ground
that the planet's surface raises clearly above the sea does not carry the
sea's colour, while the sea and the lakes keep theirs."""
import numpy as np
import pytest

from tools import fill_coast
from tests.conftest import data_path


@pytest.fixture(scope="module")
def earth_colour():
    oiio = pytest.importorskip("OpenImageIO")
    image = oiio.ImageBuf(data_path("earth-blue-marble.jpg"))
    return np.asarray(image.get_pixels(oiio.UINT8))[..., :3]


def land_under_water_colour(colour, planet, sea_level):
    """Water-coloured texels near land-coloured ones whose every subsample
    the surface puts above the sea by the fill's margin."""
    linear = fill_coast.srgb_to_linear(colour.astype(np.float64) / 255.0)
    water = fill_coast.water_coloured(linear)
    rows, cols = np.nonzero(fill_coast.coast_candidates(water, fill_coast.REACH))
    fraction = fill_coast.land_fraction(planet, sea_level, rows, cols, colour.shape[1],
                                        colour.shape[0])
    return int(np.sum(fraction == 1.0))


def test_bundled_earth_coasts_have_the_land_colour(earth_colour):
    """The Blue Marble copied unchanged had 36,151 such texels (a strip of
    land 10-20 km wide along the coasts, blue in renders); filled, the JPEG
    coding leaves about 3,200 (texels right at the threshold)."""
    planet, sea_level = fill_coast.preset_planet("EARTH")
    assert land_under_water_colour(earth_colour, planet, sea_level) < 6000


def test_fill_paints_land_and_keeps_the_sea_and_lakes(earth_colour):
    """Big Sur's coastal range (over 50 m at every subsample of a block of
    5 x 5 texels) painted the sea's colour takes a land colour again; Lake
    Michigan (near-black, not the sea's blue) and the open Pacific keep
    every texel."""
    planet, sea_level = fill_coast.preset_planet("EARTH")
    height, width = earth_colour.shape[:2]

    def region(lon, lat, half):
        col = int((lon + 180.0) / 360.0 * width)
        row = int((90.0 - lat) / 180.0 * height)
        return slice(row - half, row + half + 1), slice(col - half, col + half + 1)

    colour = earth_colour.copy()
    coast = region(-121.5, 36.3, 2)
    colour[coast] = (24, 41, 57)  # the sea's texel at Big Sur in the original map
    filled, _ = fill_coast.fill(colour, planet, sea_level, passes=1)
    linear = fill_coast.srgb_to_linear(filled[coast].astype(np.float64) / 255.0)
    assert not fill_coast.water_coloured(linear).any()
    for kept in (region(-87.0, 44.0, 20), region(-140.0, 30.0, 20)):
        assert np.array_equal(filled[kept], colour[kept])
