"""surface.preview_data (what the GPU preview draws) describes the same surface
as surface.vertex_data (what the planet's Blender mesh gets): the same
vertices relative to the anchor, the same sea, the same normals; sectors and
levels as the mesh has them.  bpy-free: planetlod.surface."""
import math

import numpy as np
import pytest

from conftest import data_path
from test_mesh import refiner_available
from test_refine import look_at


@pytest.fixture(scope="module")
def surface():
    from planetlod import surface as module
    return module


def coast_mesh(planetlod, sea_level, detail=None):
    """A refined Earth mesh 3 km above a coast (Genoa), every leaf sector."""
    radius = 6371000.0
    planet = planetlod.Planet(radius, heightmap=data_path("earth-topology.png"),
                              height_scale=8848.0, sea_level=sea_level, detail=detail)
    lat, lon = math.radians(44.4), math.radians(8.9)
    up = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    eye = up * (radius + 3000.0)
    north = np.array([0.0, 0.0, 1.0]) - up * up[2]
    planet.refine(planetlod.Camera(look_at(eye, eye + 1e4 * north - 2e3 * up),
                                   clip_start=1.0, clip_end=1e8), max_level=30)
    return planet.mesh(template_level=3, visible_only=False), radius, eye


def test_preview_crests_are_the_render_mesh_detail(planetlod, surface):
    """The crest code the viewport's ground types read is the render mesh's
    detail field in units of its amplitude (clamped), 0 on the sea; sea flags
    and levels beside it unchanged."""
    refiner_available(planetlod)
    amplitude = 300.0
    mesh, radius, eye = coast_mesh(planetlod, 0.0, detail=dict(amplitude=amplitude, smallest=1.0))
    preview = surface.preview_data(mesh, tuple(eye), radius, 0.0, detail_amplitude=amplitude)
    render = surface.vertex_data(mesh, tuple(eye), radius, 0.0)
    expected = np.clip(render.attributes["planet_detail"] / amplitude, -1.0, 0.98)
    assert np.abs(preview.crest - expected).max() < 1e-4
    assert np.array_equal(preview.sea, render.attributes["planet_sea"])
    assert preview.sea.any() and np.all(preview.crest[preview.sea > 0] == 0.0)
    assert (preview.crest > 0.05).any() and (preview.crest < -0.05).any()
    tris_per_sector = mesh.triangle_count // mesh.sector_count
    levels = np.frombuffer(mesh.sector_level, np.int32)[::tris_per_sector]
    assert np.array_equal(preview.levels, np.repeat(levels, preview.vertices_per_sector))
    assert np.all(surface.preview_data(mesh, tuple(eye), radius, 0.0).crest == 0.0)


@pytest.mark.parametrize("sea_level", [None, 0.0, 40.0])
def test_preview_data_is_the_render_mesh_surface(planetlod, surface, sea_level):
    refiner_available(planetlod)
    mesh, radius, anchor = coast_mesh(planetlod, sea_level or 0.0)
    sea = sea_level if sea_level is not None else None
    preview = surface.preview_data(mesh, tuple(anchor), radius, sea)
    render = surface.vertex_data(mesh, tuple(anchor), radius, sea)
    n = mesh.vertex_count
    assert preview.vertex_count == n and preview.sector_count == mesh.sector_count
    positions = np.asarray(render.positions).reshape(-1, 3)
    distance = np.linalg.norm(positions, axis=1)
    error = np.linalg.norm(preview.positions - positions, axis=1)
    # float32 rounding of a sum instead of a float64 sum rounded once
    assert np.all(error <= 1e-3 + distance * 2.0 ** -22), error.max()
    assert np.array_equal(preview.normals, np.asarray(render.normals).reshape(-1, 3))
    assert np.array_equal(preview.sea, render.attributes["planet_sea"])
    if sea is not None:
        assert preview.sea.any() and not preview.sea.all()  # a coast
    # heights for colours: float32 planet-space lengths, within a metre
    assert np.abs(preview.heights - render.attributes["planet_height"]).max() < 1.0
    tris_per_sector = mesh.triangle_count // mesh.sector_count
    levels = np.frombuffer(mesh.sector_level, np.int32)[::tris_per_sector]
    assert np.array_equal(preview.levels, np.repeat(levels, preview.vertices_per_sector))
    template = np.frombuffer(mesh.triangles, np.int32).reshape(mesh.sector_count, -1)
    assert np.array_equal(template[0], preview.template_triangles.ravel())
    # the texture's padding draws nothing: whole rows, zero past the vertices
    assert len(preview.texels) % preview.row_texels == 0
    assert not preview.texels[2 * n:].any()


def sector_texels(preview):
    """sector id -> its (2 * vertices_per_sector, 4) texels."""
    per = 2 * preview.vertices_per_sector
    by_slot = preview.texels[:preview.sector_count * per].reshape(-1, per, 4)
    return {int(i): by_slot[k] for k, i in enumerate(preview.slot_ids) if i}


def test_preview_update_keeps_the_preview_of_the_sectors_in_view(planetlod, surface):
    """Along a descent to a coast with progressive refreshes, a preview kept
    by preview_update (only the sectors planet.mesh(changed_only=True)
    emits are written) holds exactly the sectors in view, each as a
    complete preview_data of the same LOD has it; the previous preview is
    never changed (the viewport may be drawing it); free slots draw nothing
    and are compacted when over half the slots."""
    refiner_available(planetlod)
    radius = 6371000.0
    planet = planetlod.Planet(radius, heightmap=data_path("earth-topology.png"),
                              height_scale=8848.0, sea_level=0.0,
                              detail=dict(style="mountains", amplitude=400.0))
    lat, lon = math.radians(44.4), math.radians(8.9)
    up = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    north = np.array([0.0, 0.0, 1.0]) - up * up[2]
    anchor = tuple(up * radius)
    preview, updates, freed = None, 0, 0
    for k in range(14):
        eye = up * (radius + max(planet.height(*up), 0.0) + 200e3 * 0.5 ** k)
        cam = planetlod.Camera(look_at(eye, eye + 1e4 * north - 2e3 * up), clip_start=1.0,
                               clip_end=1e8)
        planet.refine(cam, template_level=3, hysteresis=True, max_splits=400)
        ids = np.frombuffer(planet.sector_ids(), np.uint64)
        if preview is None:
            preview = surface.preview_data(planet.mesh(template_level=3), anchor, radius, 0.0)
        else:
            assert preview.serial == planet.mesh_cache_info["emissions"]
            before = preview.texels.copy(), preview.slot_ids.copy()
            changed = planet.mesh(template_level=3, changed_only=True)
            updated = surface.preview_update(preview, changed, ids, anchor, radius, 0.0)
            assert np.array_equal(before[0], preview.texels)
            assert np.array_equal(before[1], preview.slot_ids)
            freed += updated.sector_count - updated.sectors
            preview, updates = updated, updates + 1
        preview.serial = planet.mesh_cache_info["emissions"]
        full = surface.preview_data(planet.mesh(template_level=3, cache=False), anchor,
                                    radius, 0.0)
        planet_serial = planet.mesh_cache_info["emissions"]
        assert planet_serial == preview.serial  # an uncached mesh leaves the cache alone
        kept, want = sector_texels(preview), sector_texels(full)
        assert sorted(kept) == sorted(want) == sorted(ids.tolist()), k
        for sector, texels in want.items():
            got = kept[sector]
            assert np.array_equal(got[1::2, 3], texels[1::2, 3]), k  # level, sea
            land = np.mod(texels[1::2, 3], 2.0) == 0.0
            assert np.array_equal(got[1::2][land], texels[1::2][land]), k  # the core's normals
            # the sea's normal is the up of the float32 position: within its rounding
            assert np.abs(got[1::2][~land] - texels[1::2][~land]).max(initial=0.0) < 1e-6, k
            assert np.abs(got[0::2] - texels[0::2]).max() <= 2e-7 * radius, k
        per = 2 * preview.vertices_per_sector
        free = preview.texels[:preview.sector_count * per].reshape(-1, per, 4)[
            preview.slot_ids == 0]
        assert not free.any() and not preview.texels[preview.sector_count * per:].any()
        assert preview.sector_count <= max(64, 2 * preview.sectors)
        assert preview.vertex_count == preview.sector_count * preview.vertices_per_sector
    assert updates == 13 and freed > 0
    # back to orbit: most sectors leave, the slots are compacted
    eye = up * (radius + 3e6)
    planet.refine(planetlod.Camera(look_at(eye, (0.0, 0.0, 0.0)), clip_start=1.0,
                                   clip_end=1e8), template_level=3, hysteresis=True)
    ids = np.frombuffer(planet.sector_ids(), np.uint64)
    changed = planet.mesh(template_level=3, changed_only=True)
    updated = surface.preview_update(preview, changed, ids, anchor, radius, 0.0)
    assert updated.sector_count == updated.sectors == len(ids) < preview.sectors / 2
    full = surface.preview_data(planet.mesh(template_level=3, cache=False), anchor, radius, 0.0)
    kept, want = sector_texels(updated), sector_texels(full)
    assert sorted(kept) == sorted(want)
    assert all(np.array_equal(kept[i][1::2, 3], want[i][1::2, 3]) for i in want)
