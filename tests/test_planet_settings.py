"""planetlod.planets.build_planet from a settings dict (what the add-on's
panel holds): regional insets and the out-of-core large-map option, the
planet key that rebuilds a planet when they change, and clear errors for
bad inset files.  The tiles and maps are generated here."""
import math
import os
import re

import numpy as np
import pytest

from planetlod import FileError, ImageError, InvalidArgument, planets
from test_geotiff import WGS84, write_geotiff
from test_insets import direction, write_hgt

R = 6371000.0


def settings(**changes):
    values = dict(projection="QSC", radius=R, heightmap="", height_scale=8848.0,
                  height_offset=0.0, height_signed=False, use_sea_level=False, sea_level=0.0,
                  use_detail=False)
    values.update(changes)
    return values


@pytest.fixture
def tiles(tmp_path):
    a, grid = write_hgt(tmp_path, 6, 45)
    b, _ = write_hgt(tmp_path, 7, 45)
    return [a, b], grid


def test_insets_raise_the_terrain_inside_their_tiles_only(planetlod, tiles):
    paths, grid = tiles
    plain = planets.build_planet(settings())
    with_insets = planets.build_planet(settings(insets=paths))
    assert with_insets is not plain
    for row, col in ((300, 300), (600, 900)):  # well inside the blend border
        lon, lat = 6 + col / 1200, 46 - row / 1200
        assert with_insets.height(*direction(lon, lat)) == pytest.approx(grid[row, col], abs=1.0)
        assert plain.height(*direction(lon, lat)) == 0.0
    assert with_insets.height(*direction(7.5, 45.5)) > 1000.0  # the second tile
    assert with_insets.height(*direction(20.0, 45.5)) == 0.0
    assert with_insets.texel_size(*direction(6.5, 45.5)) < 100.0  # ~90 m SRTM samples


def test_changing_insets_or_their_files_rebuilds(planetlod, tiles):
    paths, _ = tiles
    first = planets.build_planet(settings(insets=paths))
    assert planets.build_planet(settings(insets=list(paths))) is first  # cached
    assert planets.build_planet(settings(insets=paths[:1])) is not first
    assert planets.build_planet(settings(insets=paths, inset_feather=0.0)) is not first
    assert planets.build_planet(settings(insets=paths + [""])) is first  # empty entries
    stat = os.stat(paths[0])
    os.utime(paths[0], ns=(stat.st_atime_ns, stat.st_mtime_ns + 10 ** 9))
    assert planets.build_planet(settings(insets=paths)) is not first


def test_bad_inset_files_are_clear_errors_and_change_nothing(planetlod, tiles, tmp_path):
    paths, _ = tiles
    good = planets.build_planet(settings(insets=paths))
    key = planets.planet_key(settings(insets=paths))
    with pytest.raises(FileError, match="inset not found: .*N10E010"):
        planets.build_planet(settings(insets=[paths[0], str(tmp_path / "N10E010.hgt")]))
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileError, match="inset is a folder"):
        planets.build_planet(settings(insets=[str(tmp_path / "empty")]))
    with pytest.raises(InvalidArgument, match="overlap"):
        planets.build_planet(settings(insets=[paths[0], paths[0]]))
    copy = tmp_path / "copy"
    copy.mkdir()
    copied, _ = write_hgt(copy, 6, 45)
    with pytest.raises(InvalidArgument, match=re.escape(f"insets {paths[0]} and {copied} "
                                                        "overlap (lon 6..7")):
        planets.build_planet(settings(insets=[paths[0], copied]))
    named_badly = tmp_path / "tile.hgt"
    named_badly.write_bytes(open(paths[0], "rb").read())
    with pytest.raises(InvalidArgument, match=r"tile\.hgt is neither an SRTM tile .*Place by Box"):
        planets.build_planet(settings(insets=[str(named_badly)]))
    short = tmp_path / "N30E030.hgt"
    short.write_bytes(b"\0" * 1000)
    with pytest.raises(ImageError):
        planets.build_planet(settings(insets=[str(short)]))
    utm = write_geotiff(tmp_path / "utm.tif", np.zeros((16, 16), "<i2"),
                        scale=(30.0, 30.0, 0.0), tiepoint=(0, 0, 0, 500000.0, 5e6, 0),
                        geokeys={1024: 1, 1025: 1, 3072: 32632})
    with pytest.raises(ImageError, match="(?i)projected"):
        planets.build_planet(settings(insets=[utm]))
    assert planets.build_planet(settings(insets=paths)) is good
    assert planets.planet_key(settings(insets=paths)) == key


def test_geotiff_inset_placed_by_its_tags(planetlod, tmp_path):
    side, step = 121, 1.0 / 120
    grid = np.full((side, side), 3000, "<i2")
    path = write_geotiff(tmp_path / "alps.tif", grid, scale=(step, step, 0.0),
                         tiepoint=(0, 0, 0, 10 - step / 2, 47 + step / 2, 0), geokeys=WGS84)
    planet = planets.build_planet(settings(insets=[path]))
    assert planet.height(*direction(10.5, 46.5)) == pytest.approx(3000.0, abs=1e-6)
    assert planet.height(*direction(12.0, 46.5)) == 0.0


def test_grid_without_placement_needs_and_takes_a_box(planetlod, tmp_path):
    grid = np.full((101, 201), 2500, "<i2")
    path = write_geotiff(tmp_path / "plain.tif", grid)  # no georeferencing tags
    with pytest.raises(InvalidArgument, match="Place by Box"):
        planets.build_planet(settings(insets=[path]))
    box = dict(path=path, west=20.0, south=-10.0, east=22.0, north=-9.0, scale=32767.0)
    planet = planets.build_planet(settings(insets=[box]))  # 16 bits read as 0..1
    assert planet.height(*direction(21.0, -9.5)) == pytest.approx(2500.0, abs=0.5)
    assert planet.height(*direction(23.0, -9.5)) == 0.0
    moved = planets.build_planet(settings(insets=[dict(box, west=19.0)]))
    assert moved is not planet and moved.height(*direction(19.5, -9.5)) > 0.0
    assert planets.build_planet(settings(insets=[dict(box, scale=1.0)])) is not planet
    assert planets.build_planet(settings(insets=[dict(box, path="")])) is \
        planets.build_planet(settings())


def write_world(path, width=512):
    lat = (90.0 - (np.arange(width // 2) + 0.5) * 360.0 / width)[:, None]
    lon = (-180.0 + (np.arange(width) + 0.5) * 360.0 / width)[None, :]
    field = 0.5 + 0.3 * np.sin(np.radians(3 * lon)) * np.cos(np.radians(2 * lat))
    np.round(field * 65535).astype("<u2").tofile(path)
    return str(path)


def test_large_map_reads_the_map_through_a_tile_file(planetlod, tmp_path):
    world = write_world(tmp_path / "world.r16")
    in_memory = planets.build_planet(settings(heightmap=world))
    assert not os.path.exists(world + ".plodtiles")
    # the tile file is written on request only (the add-on: with progress and Esc)
    with pytest.raises(FileError, match="Write Tile File"):
        planets.build_planet(settings(heightmap=world, heightmap_tiled=True))
    seen = []
    assert not planets.write_tiles(settings(heightmap=world),
                                   progress=lambda f: seen.append(f) or True)
    assert seen and not os.path.exists(world + ".plodtiles")  # cancelled: nothing left
    assert not planets.tiles_written(settings(heightmap=world))
    assert planets.write_tiles(settings(heightmap=world), progress=seen.append)
    assert planets.tiles_written(settings(heightmap=world)) and seen[-1] <= 1.0
    tiled = planets.build_planet(settings(heightmap=world, heightmap_tiled=True))
    assert tiled is not in_memory
    assert os.path.isfile(world + ".plodtiles")
    for lon, lat in ((10.0, 20.0), (-120.0, -35.0), (170.0, 60.0)):
        assert tiled.height(*direction(lon, lat)) == pytest.approx(
            in_memory.height(*direction(lon, lat)), abs=0.02 * 8848.0)
    square = tmp_path / "square.r16"
    np.zeros((64, 64), "<u2").tofile(square)
    assert planets.write_tiles(settings(heightmap=str(square)))
    with pytest.raises(InvalidArgument, match="2:1"):
        planets.build_planet(settings(heightmap=str(square), heightmap_tiled=True))
    with_insets = planets.build_planet(settings(heightmap=world, heightmap_tiled=True,
                                                insets=[write_hgt(tmp_path, 6, 45)[0]]))
    assert with_insets.height(*direction(6.3, 45.3)) > 1000.0


def test_maps_over_the_memory_limit_ask_for_the_large_map_option(planetlod, tmp_path,
                                                                  monkeypatch):
    """The core refuses to load a map of more than 2^28 pixels (a real one is
    hundreds of megabytes, too big to write here): the refusal is simulated.
    The message names the option; no tile file is written unasked."""
    world = write_world(tmp_path / "world.r16")
    native = planetlod.require_native()

    class RefusingPlanet:
        def __new__(cls, radius, heightmap=None, **kwargs):
            if isinstance(heightmap, str):
                raise ImageError(f"'{heightmap}' is 86400x43200 pixels, more than the limit "
                                 f"of {1 << 28}")
            return native.Planet(radius, heightmap=heightmap, **kwargs)

    class Module:
        Planet = RefusingPlanet
        TiledMap = native.TiledMap
        PROJECTIONS = native.PROJECTIONS

    monkeypatch.setattr(planets, "require_native", lambda: Module)
    with pytest.raises(ImageError, match="more than the limit .*turn on Large Map"):
        planets.build_planet(settings(heightmap=world, height_scale=1000.0))
    assert not os.path.exists(world + ".plodtiles")
    assert planets.write_tiles(settings(heightmap=world))
    planet = planets.build_planet(settings(heightmap=world, height_scale=1000.0,
                                           heightmap_tiled=True))
    assert math.isfinite(planet.height(*direction(0.0, 0.0)))


def test_a_radius_too_small_for_the_heights_says_so(planetlod):
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    topology = os.path.join(root, "data", "earth-topology.png")
    for radius in (1.0, 100.0):
        with pytest.raises(InvalidArgument, match=r"radius must be at least [\d,]+ m"):
            planets.build_planet(settings(radius=radius, heightmap=topology))
    smallest = planets.minimum_radius(settings(heightmap=topology))
    assert smallest == pytest.approx(884.8)
    planets.build_planet(settings(radius=smallest + 1.0, heightmap=topology))


def test_a_text_file_named_like_an_image_is_not_an_image_file(planetlod, tmp_path):
    for name in ("notes.png", "notes.jpg", "notes.tif", "notes.exr"):
        fake = tmp_path / name
        fake.write_text("not an image at all\n")
        with pytest.raises(ImageError, match=rf"not an image file \({re.escape(name)}\)"):
            planets.build_planet(settings(heightmap=str(fake)))
        with pytest.raises(ImageError, match=rf"not an image file \({re.escape(name)}\)"):
            planets.build_planet(settings(insets=[str(fake)]))
