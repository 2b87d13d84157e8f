"""Gives land along the coasts the colour of the land, not the sea's.

A colour map and a height map made apart rarely agree on where the coast
is: the bundled Earth's colour texels are 10 km, its height texels 20 km,
and a strip of land a texel or two wide along every coast carried the sea's
dark blue.  The planet's own surface decides what is land, so this asks the
core: each texel the colour map paints as open water, near a texel it paints
as land, is sampled on the planet's surface at 4x4 points; the fraction of
them more than LAND_MARGIN above the sea (lower ground the two maps may
well both call sea) takes the colour of the land-coloured land texels
within three texels (their mean in scene-linear terms), and a second pass
fills from the first's.  Texels the surface keeps in the sea keep their
colour (the viewport preview shows it), and so do lakes that the map paints
near-black, as the bundled Earth does.

    python3 -m tools.fill_coast ORIGINAL.jpg OUT.jpg [--preset EARTH]

The height map, sea level, projection and height scale are the preset's (the
detail field is left out: it keeps the map's coast).  Needs numpy and
OpenImageIO (planetlod.imageio says where it comes from) and the built
module (tools/build.sh).  Deterministic: the same bytes on every run.
"""
import argparse
import os

import numpy

import planetlod
from planetlod import imageio, presets

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

REACH = 3          # texels around a coast texel whose land colours fill it
SUBSAMPLES = 4     # per texel side: the land fraction's resolution
PASSES = 2         # fills from the last pass's: strips up to PASSES * REACH wide
LAND_MARGIN = 50.0 # metres above the sea: lower ground the maps may well call sea


def srgb_to_linear(c):
    return numpy.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c):
    c = numpy.clip(c, 0.0, 1.0)
    return numpy.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1.0 / 2.4) - 0.055)


def water_coloured(linear):
    """Texels that read as open water: blue well above red and green, and
    dark (land is green, brown, grey or white; the bundled lakes are
    near-black, bluish but not the sea's blue)."""
    red, green, blue = linear[..., 0], linear[..., 1], linear[..., 2]
    bluish = blue > 1.15 * (numpy.maximum(red, green) + 0.004)
    return bluish & ((red + green + blue) / 3.0 < 0.22)


def window_offsets(reach):
    return [(dy, dx) for dy in range(-reach, reach + 1) for dx in range(-reach, reach + 1)
            if (dy or dx) and dy * dy + dx * dx <= reach * reach]


def coast_candidates(water, reach):
    """Water-coloured texels with a land-coloured texel within `reach`
    (longitude wraps, latitude clamps)."""
    land = ~water
    near_land = numpy.zeros_like(water)
    h = water.shape[0]
    for dy, dx in window_offsets(reach):
        shifted = numpy.roll(land, dx, axis=1)
        rows = numpy.clip(numpy.arange(h) - dy, 0, h - 1)
        near_land |= shifted[rows]
    return water & near_land


def land_fraction(planet, sea_level, rows, cols, width, height):
    """Fraction of SUBSAMPLES^2 points of each texel (rows top first) that
    the planet's surface puts above the sea level."""
    k = SUBSAMPLES
    offsets = (numpy.arange(k) + 0.5) / k
    u = (cols[:, None, None] + offsets[None, None, :]) / width
    v = (rows[:, None, None] + offsets[None, :, None]) / height
    lon = (u * 2.0 - 1.0) * numpy.pi
    lat = (0.5 - v) * numpy.pi
    lon, lat = numpy.broadcast_arrays(lon, lat)
    dirs = numpy.stack([numpy.cos(lat) * numpy.cos(lon), numpy.cos(lat) * numpy.sin(lon),
                        numpy.sin(lat)], axis=-1).reshape(-1, 3)
    heights = numpy.empty(len(dirs))
    chunk = 1 << 18
    for first in range(0, len(dirs), chunk):
        h, _ = planet.surface(numpy.ascontiguousarray(dirs[first:first + chunk]))
        heights[first:first + chunk] = numpy.frombuffer(h, dtype=numpy.float64)
    return (heights.reshape(len(rows), k * k) > sea_level + LAND_MARGIN).mean(axis=1)


class LandFractions:
    """land_fraction per texel, each computed once."""

    def __init__(self, planet, sea_level, width, height):
        self.planet, self.sea_level = planet, sea_level
        self.width, self.height = width, height
        self.known = numpy.full((height, width), numpy.nan)

    def __call__(self, rows, cols):
        missing = numpy.isnan(self.known[rows, cols])
        if missing.any():
            r, c = rows[missing], cols[missing]
            self.known[r, c] = land_fraction(self.planet, self.sea_level, r, c,
                                             self.width, self.height)
        return self.known[rows, cols]


def fill(colour_u8, planet, sea_level, passes=PASSES):
    """The filled copy of an (h, w, 3) uint8 sRGB image, and the texels changed.
    Each pass fills the coast texels with land-coloured land within REACH;
    the next one fills from those, so strips wider than REACH fill inwards."""
    height, width = colour_u8.shape[:2]
    linear = srgb_to_linear(colour_u8[..., :3].astype(numpy.float64) / 255.0)
    fractions = LandFractions(planet, sea_level, width, height)
    done = numpy.zeros((height, width), dtype=bool)
    for _ in range(passes):
        water = water_coloured(linear)
        rows, cols = numpy.nonzero(coast_candidates(water, REACH) & ~done)
        fraction = fractions(rows, cols)
        keep = fraction > 0.0
        rows, cols, fraction = rows[keep], cols[keep], fraction[keep]
        # the colours that fill them: texels painted as land where the
        # surface is land too (a shallow sea's pale blue or a beach's sand
        # would not do)
        around = numpy.zeros_like(water)
        for dy, dx in window_offsets(REACH):
            around[numpy.clip(rows + dy, 0, height - 1), (cols + dx) % width] = True
        around &= ~water
        source = numpy.zeros_like(water)
        source_rows, source_cols = numpy.nonzero(around)
        source[source_rows, source_cols] = fractions(source_rows, source_cols) == 1.0
        total = numpy.zeros((len(rows), 3))
        count = numpy.zeros(len(rows))
        for dy, dx in window_offsets(REACH):
            r = numpy.clip(rows + dy, 0, height - 1)
            c = (cols + dx) % width
            land = source[r, c]
            total += linear[r, c] * land[:, None]
            count += land
        filled = count > 0
        if not filled.any():
            break
        rows, cols, fraction = rows[filled], cols[filled], fraction[filled]
        fill_colour = total[filled] / count[filled][:, None]
        linear[rows, cols] += (fill_colour - linear[rows, cols]) * fraction[:, None]
        done[rows, cols] = True
    out = colour_u8.copy()
    rows, cols = numpy.nonzero(done)
    out[rows, cols, :3] = numpy.round(linear_to_srgb(linear[rows, cols]) * 255.0).astype(
        numpy.uint8)
    return out, len(rows)


def preset_planet(name):
    def data_path(file_name):
        return os.path.join(ROOT, "data", file_name)
    s = presets.planet_settings(name, data_path)
    if not s.get("use_sea_level"):
        raise SystemExit(f"fill_coast: the {name} preset has no sea")
    planet = planetlod.Planet(float(s["radius"]), heightmap=s["heightmap"],
                              projection=s["projection"].lower(),
                              height_scale=float(s["height_scale"]),
                              sea_level=float(s["sea_level"]))
    return planet, float(s["sea_level"])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("original")
    parser.add_argument("out")
    parser.add_argument("--preset", default="EARTH")
    args = parser.parse_args(argv)
    width, height, channels, dtype, pixels = imageio.read(args.original)
    if dtype != "u8" or channels < 3:
        raise SystemExit(f"fill_coast: {args.original} is not an 8-bit colour image")
    planet, sea_level = preset_planet(args.preset)
    filled, changed = fill(pixels, planet, sea_level)
    # full-resolution colour (no chroma subsampling): the coast is a texel wide
    imageio.write(args.out, numpy.ascontiguousarray(filled), width, height, channels, "u8",
                  attributes=(("compression", "jpeg:95"), ("jpeg:subsampling", "4:4:4")))
    print(f"{args.out}: {changed} coast texels of {width}x{height} filled")


if __name__ == "__main__":
    main()
