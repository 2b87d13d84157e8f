"""planetlod.refresh, a refresh's work in the core without Blender: the
refine for the LOD camera, the GPU preview's surface emitted in full or
sector by sector, and the progressive refreshes' split allowance."""
import math

import numpy as np
import pytest

from planetlod import presets, surface
from planetlod.refresh import ProgressiveSplits, SurfaceWork, mesh_digest, preview_key
from test_mesh import refiner_available
from test_refine import look_at

RADIUS = 6371000.0


def settings(**changes):
    """The add-on's settings dict for a smooth Earth-sized sphere, Draft quality."""
    values = dict(projection="QSC", radius=RADIUS, heightmap="", height_scale=8848.0,
                  height_offset=0.0, height_signed=False, use_sea_level=False, sea_level=0.0,
                  skip_sea=False, use_detail=True, detail_style="MOUNTAINS",
                  detail_amplitude=400.0, detail_roughness=0.5, detail_smallest=1.0,
                  detail_craters=0.0, detail_plains=0.5, detail_seed=presets.DETAIL_SEED,
                  criterion="PIXEL", max_pixel_error=8.0, split_border=2.0, merge_border=1.6,
                  template_level=2, budget=2000, max_level=0, backface=True, frustum=True)
    values.update(changes)
    return values


def camera_params(altitude, pitch_down=0.2):
    """planetlod.Camera keyword arguments `altitude` metres above the sphere,
    looking north and a little down."""
    lat, lon = math.radians(44.4), math.radians(8.9)
    up = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    north = np.array([0.0, 0.0, 1.0]) - up * up[2]
    eye = up * (RADIUS + altitude)
    target = eye + north / np.linalg.norm(north) - pitch_down * up
    matrix = np.asarray(look_at(eye, target)).reshape(4, 4).tolist()
    return dict(matrix_world=matrix, lens=24.0, clip_start=1.0, clip_end=1e8,
                resolution_x=320, resolution_y=180)


@pytest.fixture
def planet(planetlod):
    refiner_available(planetlod)
    from planetlod import planets
    planets.forget_planets()
    return planets.build_planet(settings())


def test_a_render_work_refines_for_its_camera_alone(planetlod, planet):
    """Without hysteresis the LOD is a function of the camera: the same
    camera after another one gives the same sectors and the same mesh."""
    work = SurfaceWork(planet, settings(), camera_params(2000.0), refine=True, for_render=True,
                       check_size=True, preview=None)
    work.run()
    assert work.stats["visible"] > 0 and not work.inside and work.ms > 0.0
    assert work.preview_key is None and work.preview_data is None
    first = mesh_digest(planet.mesh(template_level=2))
    SurfaceWork(planet, settings(), camera_params(5e6), refine=True, for_render=True,
                check_size=True, preview=None).run()
    again = SurfaceWork(planet, settings(), camera_params(2000.0), refine=True, for_render=True,
                        check_size=True, preview=None)
    again.run()
    assert again.stats["visible"] == work.stats["visible"]
    assert mesh_digest(planet.mesh(template_level=2)) == first


def test_a_frozen_work_keeps_the_lod(planetlod, planet):
    SurfaceWork(planet, settings(), camera_params(2000.0), refine=True, for_render=True,
                check_size=False, preview=None).run()
    ids = bytes(planet.sector_ids())
    frozen = SurfaceWork(planet, settings(), camera_params(5e6), refine=False, for_render=False,
                         check_size=False, preview=None)
    frozen.run()
    assert frozen.stats is None and bytes(planet.sector_ids()) == ids


def test_the_preview_follows_the_sectors_in_view(planetlod, planet):
    """The first preview is emitted whole; one for an unchanged view keeps it
    (only its serial moves on); one after the view changed replaces the
    sectors that changed, and holds what a whole preview of that LOD holds;
    another key (the sea level here) emits it whole again."""
    anchor = tuple(float(v) for v in np.asarray(camera_params(0.0)["matrix_world"])[:3, 3])

    def run(params, key, data, sea_level=None):
        work = SurfaceWork(planet, settings(), params, refine=True, for_render=False,
                           check_size=True, preview=(anchor, RADIUS, sea_level, False, key, data))
        work.run()
        assert work.preview_key == preview_key(planet, 2, anchor, RADIUS, sea_level, False)
        return work

    first = run(camera_params(3000.0), None, None)
    assert first.preview_data is not None
    assert first.preview_data.serial == planet.mesh_cache_info["emissions"]
    key, data = first.preview_key, first.preview_data
    same = run(camera_params(3000.0), key, data)
    assert same.preview_data is None and same.preview_serial is not None
    data.serial = same.preview_serial
    moved = run(camera_params(1500.0), key, data)
    assert moved.preview_data is not None and moved.preview_data is not data
    whole = surface.preview_data(planet.mesh(template_level=2, cache=False), anchor, RADIUS)
    ids = np.frombuffer(planet.sector_ids(visible_only=True), np.uint64)
    assert moved.preview_data.sectors == whole.sector_count == len(ids)
    assert sorted(int(i) for i in moved.preview_data.slot_ids if i) == \
        sorted(int(i) for i in whole.slot_ids if i)
    sea = run(camera_params(1500.0), key, moved.preview_data, sea_level=0.0)
    assert sea.preview_key != key and sea.preview_data.sector_count == len(ids)


def test_progressive_splits_follow_the_refreshes_time():
    """The viewport's progressive refreshes: none without a budget; a floor
    of START_NEW_VERTICES new vertices; a refresh that used its allowance
    scales the next by TARGET_MS over its time, at most 1.5x up or 2x down,
    never below the floor; one that finished (not pending) changes nothing."""
    assert ProgressiveSplits(3, 0).splits == 0
    p = ProgressiveSplits(3, 8000)
    least = ProgressiveSplits.START_NEW_VERTICES // (2 * 45)  # 45 vertices a sector
    assert p.splits == least
    p.measured({"pending": True}, ProgressiveSplits.TARGET_MS / 4)
    assert p.splits == int(least * 1.5)
    p.measured({"pending": False}, 1.0)
    assert p.splits == int(least * 1.5)
    p.measured({"pending": True}, ProgressiveSplits.TARGET_MS * 1.2)
    assert p.splits == int(int(least * 1.5) / 1.2)
    p.measured({"pending": True}, ProgressiveSplits.TARGET_MS * 10)
    assert p.splits == least
    assert ProgressiveSplits(7, 8000).splits == 16  # large templates: the least
