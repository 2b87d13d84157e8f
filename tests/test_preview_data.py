"""surface.preview_data (what the GPU preview draws) describes the same surface
as surface.vertex_data (what the planet's Blender mesh gets): the same
vertices relative to the anchor, the same sea, the same normals; sectors and
levels as the mesh has them.  bpy-free: planetlod.surface."""
import math

import numpy as np
import pytest

from conftest import data_path
from test_mesh import look_at, refiner_available


@pytest.fixture(scope="module")
def surface():
    from planetlod import surface as module
    return module


def coast_mesh(planetlod, sea_level):
    """A refined Earth mesh 3 km above a coast (Genoa), every leaf sector."""
    radius = 6371000.0
    planet = planetlod.Planet(radius, heightmap=data_path("earth-topology.png"),
                              height_scale=8848.0, sea_level=sea_level)
    lat, lon = math.radians(44.4), math.radians(8.9)
    up = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    eye = up * (radius + 3000.0)
    north = np.array([0.0, 0.0, 1.0]) - up * up[2]
    planet.refine(planetlod.Camera(look_at(eye, eye + 1e4 * north - 2e3 * up),
                                   clip_start=1.0, clip_end=1e8), max_level=30)
    return planet.mesh(template_level=3, visible_only=False), radius, eye


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
