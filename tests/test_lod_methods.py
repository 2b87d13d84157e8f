"""The LOD methods beside HRTMR: chunked LOD on cube-face quadtrees (Ulrich
2002) and geomipmapping (de Boer 2000), through Planet.refine(method=...) and
Planet.mesh(): watertight meshes from orbit to 2 m, determinism, identical
output for any thread count, bad parameters refused, HRTMR the default.
"""
import numpy as np
import pytest

from conftest import data_path
from test_mesh import arrays, edge_report
from test_refine import look_at

RADIUS = 1737.4e3
ALTITUDES = (1.0e6, 30.0e3, 2.0)
STITCHED = [("chunked", {}), ("geomipmap", {})]


@pytest.fixture(scope="module")
def moon_planet(planetlod):
    moon = planetlod.CubeMap.from_image(data_path("lunar_bumpmap.jpg"), projection="qsc",
                                        size=64)
    return planetlod.Planet(RADIUS, heightmap=moon, height_scale=10e3,
                            detail=dict(amplitude=40.0, smallest=0.5, seed=3))


def camera(planetlod, planet, altitude, sideways=0.0):
    up = (1.0, sideways, 0.0)
    d = np.asarray(up) / np.linalg.norm(up)
    ground = RADIUS + planet.height(*d)
    eye = d * (ground + altitude)
    target = d * ground + np.array([0.0, 0.0, 0.7 * altitude + 10.0])
    matrix = look_at(tuple(eye), tuple(target))
    near, far = planet.recommended_clip(planetlod.Camera(matrix, clip_end=1e9))
    return planetlod.Camera(matrix, clip_start=near, clip_end=far)


def mesh_bytes(mesh):
    return tuple(bytes(getattr(mesh, name)) for name in
                 ("positions", "normals", "uv", "morph", "detail", "triangles",
                  "sector_level", "face", "sector_ids")) + (mesh.origin,)


@pytest.mark.parametrize("method,options", STITCHED)
@pytest.mark.parametrize("altitude", ALTITUDES)
def test_stitched_methods_watertight_orbit_to_ground(planetlod, moon_planet, method, options,
                                                    altitude):
    cam = camera(planetlod, moon_planet, altitude)
    stats = moon_planet.refine(cam, backface=False, frustum=False, max_level=44,
                               method=method, **options)
    assert stats["method"] == method and stats["state_bytes"] > 0
    for morph in (False, True):
        mesh = moon_planet.mesh(morph=morph, threads=2)
        assert mesh.triangle_count > 0
        # welded on float32 positions: a closed sphere, no crack anywhere
        assert edge_report(*arrays(mesh)) == (0, 0, 0, 2), (method, altitude, morph)
    assert mesh.sector_count == stats["sectors_after_budget"]
    assert mesh.vertex_count <= stats["vertices"] and mesh.triangle_count <= stats["triangles"]


def test_chunked_levels_follow_the_camera(planetlod, moon_planet):
    deepest = []
    for altitude in ALTITUDES:
        stats = moon_planet.refine(camera(planetlod, moon_planet, altitude), method="chunked")
        mesh = moon_planet.mesh()
        levels = np.frombuffer(mesh.sector_level, np.int32)
        assert levels.max() == stats["max_level"]
        deepest.append(stats["max_level"])
    assert deepest == sorted(deepest) and deepest[-1] >= deepest[0] + 8
    # near the ground the chunks reach metre scale: face edge / 2^level / cells
    cell = 2.0 * RADIUS / 2 ** deepest[-1] / 16
    assert cell < 2.0


def test_chunked_budget_coarsens_the_whole_view(planetlod, moon_planet):
    cam = camera(planetlod, moon_planet, 2e3)
    free = moon_planet.refine(cam, method="chunked", backface=False, frustum=False)
    capped = moon_planet.refine(cam, method="chunked", backface=False, frustum=False,
                                budget=free["sectors_total"] // 3)
    assert capped["sectors_total"] <= free["sectors_total"] // 3 < free["sectors_total"]
    assert 0 < capped["max_level"] <= free["max_level"]
    assert edge_report(*arrays(moon_planet.mesh())) == (0, 0, 0, 2)


def test_geomipmap_levels_are_mip_levels(planetlod, moon_planet):
    moon_planet.refine(camera(planetlod, moon_planet, 1e6), method="geomipmap",
                       template_level=5, geomipmap_tiles=8, backface=False, frustum=False)
    mesh = moon_planet.mesh()
    levels = np.frombuffer(mesh.sector_level, np.int32)
    # near tiles at full resolution, the far side at the coarsest levels
    assert levels.min() == 0 and levels.max() >= 3 and levels.max() <= 5
    assert edge_report(*arrays(mesh)) == (0, 0, 0, 2)


@pytest.mark.parametrize("altitude", ALTITUDES)
def test_chunked_skirts_close_every_crack_from_below(planetlod, moon_planet, altitude):
    """With skirts the chunks' edges do not meet where levels differ; what is
    measured: after welding, every open edge is a skirt's bottom edge (below
    the surface), so no crack opens onto the sky."""
    cam = camera(planetlod, moon_planet, altitude)
    moon_planet.refine(cam, backface=False, frustum=False, max_level=44, method="chunked",
                       chunk_cracks="skirts")
    mesh = moon_planet.mesh()
    pos, tri = arrays(mesh)
    welded, remap = np.unique(pos, axis=0, return_inverse=True)
    t = remap.reshape(-1)[tri]
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    open_vertices = np.unique(unique[counts == 1])
    assert len(open_vertices) > 0
    world = welded[open_vertices].astype(np.float64) + np.asarray(mesh.origin)
    r = np.linalg.norm(world, axis=1)
    heights, _ = moon_planet.surface(world.reshape(-1).tolist())
    below = RADIUS + np.frombuffer(heights, np.float64) - r
    assert np.all(below > 0.0), below.min()


@pytest.mark.parametrize("method,options", STITCHED + [("chunked", {"chunk_cracks": "skirts"})])
def test_methods_deterministic_and_thread_identical(planetlod, moon_planet, method, options):
    near, far = camera(planetlod, moon_planet, 2e3), camera(planetlod, moon_planet, 3e5, 0.2)
    moon_planet.refine(near, method=method, **options)
    first = mesh_bytes(moon_planet.mesh(threads=1, morph=True))
    moon_planet.refine(far, method=method, threads=4, **options)
    moon_planet.refine(near, method=method, threads=4, **options)
    for threads in (1, 2, 5):
        assert mesh_bytes(moon_planet.mesh(threads=threads, morph=True)) == first
    fresh = planetlod.Planet(RADIUS, heightmap=moon_planet.heightmap, height_scale=10e3,
                             detail=dict(amplitude=40.0, smallest=0.5, seed=3))
    fresh.refine(near, method=method, **options)
    assert mesh_bytes(fresh.mesh(threads=3, morph=True)) == first


def test_hrtmr_stays_the_default(planetlod, moon_planet):
    cam = camera(planetlod, moon_planet, 5e3)
    stats = moon_planet.refine(cam)
    assert "method" not in stats  # HRTMR's stats as they always were
    default = mesh_bytes(moon_planet.mesh())
    moon_planet.refine(cam, method="chunked")
    assert "method" not in moon_planet.refine(cam, method="hrtmr")
    assert mesh_bytes(moon_planet.mesh()) == default
    moon_planet.refine(cam, method="chunked")
    moon_planet.refine(cam)  # no method: HRTMR again
    assert mesh_bytes(moon_planet.mesh()) == default


def test_culling_and_lower_bound(planetlod):
    moon = planetlod.CubeMap.from_image(data_path("lunar_bumpmap.jpg"), projection="qsc",
                                        size=64)
    lo, hi = moon.range()
    sea = 0.5 * (lo + hi) * 10e3
    planet = planetlod.Planet(RADIUS, heightmap=moon, height_scale=10e3, sea_level=sea)
    cam = camera(planetlod, planet, 3e5)
    counts = {}
    for method in ("chunked", "geomipmap"):
        planet.refine(cam, backface=False, frustum=False, method=method)
        whole = planet.mesh().triangle_count
        planet.refine(cam, method=method)
        culled = planet.mesh().triangle_count
        assert 0 < culled < whole
        planet.refine(cam, method=method, skip_sea=True)
        mesh = planet.mesh()
        counts[method] = (whole, culled, mesh.triangle_count)
        assert 0 < mesh.triangle_count < culled
    # geomipmapping's lower-bound culling also drops the triangles on the sea
    # inside drawn tiles: every triangle left has a vertex above it
    planet.refine(cam, method="geomipmap", skip_sea=True)
    mesh = planet.mesh()
    pos, tri = arrays(mesh)
    r = np.linalg.norm(pos.astype(np.float64) + np.asarray(mesh.origin), axis=1)
    assert np.all((r[tri] > RADIUS + sea - 1e-3 * RADIUS * 1e-3).any(axis=1))


def test_bad_parameters(planetlod, moon_planet):
    cam = camera(planetlod, moon_planet, 1e4)
    with pytest.raises(ValueError, match="hrtmr.*chunked.*geomipmap.*clipmap"):
        moon_planet.refine(cam, method="roam")
    with pytest.raises(ValueError, match="stitch.*skirts"):
        moon_planet.refine(cam, method="chunked", chunk_cracks="glue")
    for tiles in (0, 3, 512, -4):
        with pytest.raises(ValueError, match="geomipmap_tiles"):
            moon_planet.refine(cam, method="geomipmap", geomipmap_tiles=tiles)
    with pytest.raises(ValueError, match="template_level"):
        moon_planet.refine(cam, method="chunked", template_level=0)
    with pytest.raises(ValueError, match="max_pixel_error"):
        moon_planet.refine(cam, method="geomipmap", max_pixel_error=0.0)
    with pytest.raises(ValueError, match="threads"):
        moon_planet.refine(cam, method="chunked", threads=0)
    moon_planet.refine(cam, method="chunked", template_level=3)
    with pytest.raises(ValueError, match="template_level"):
        moon_planet.mesh(template_level=4)
    with pytest.raises(ValueError, match="changed_only"):
        moon_planet.mesh(changed_only=True)
    with pytest.raises(ValueError, match="hrtmr"):
        moon_planet.instances()
    car = planetlod.Planet(1000.0, projection="car")
    with pytest.raises(planetlod.PlanetLODError, match="cube projection"):
        car.refine(planetlod.Camera(look_at((3000.0, 0, 0), (0, 0, 0))), method="geomipmap")
    # a refused refine leaves nothing half-built: the mesh is empty
    assert car.mesh().triangle_count == 0


@pytest.mark.parametrize("method", ["CHUNKED", "GEOMIPMAP"])
def test_the_addon_work_draws_a_method(planetlod, method):
    """The add-on's refresh (planetlod.refresh.SurfaceWork) refines with the
    settings' method and draws its whole mesh as one preview patch, each
    vertex coloured by the finest level of its triangles."""
    from planetlod import planets, surface
    from planetlod.refresh import SurfaceWork
    from test_refresh import RADIUS as EARTH, camera_params, settings
    planets.forget_planets()
    values = settings(lod_method=method, chunk_cracks="SKIRTS", geomipmap_tiles=8)
    planet = planets.build_planet(values)
    anchor = tuple(float(v) for v in np.asarray(camera_params(0.0)["matrix_world"])[:3, 3])
    for key in (None, "kept"):  # a patch method's preview is emitted whole every time
        work = SurfaceWork(planet, values, camera_params(3000.0), refine=True, for_render=False,
                           check_size=True, preview=(anchor, EARTH, None, False, key, None))
        work.run()
        assert work.preview_key[0] == method.lower() and work.preview_key[1] != key
        data = work.preview_data
        assert data.serial is None  # never taken for a cached HRTMR preview
        mesh = planet.mesh(template_level=values["template_level"])
        assert work.stats["visible"] == mesh.sector_count > 0
        assert data.sector_count == 1 and data.vertex_count == mesh.vertex_count
        assert data.whole  # drawn once, with its own triangles (no template copies)
        assert len(data.template_triangles) == mesh.triangle_count
        assert data.levels.max() == np.frombuffer(mesh.sector_level, np.int32).max()
    whole = surface.preview_data(mesh, anchor, EARTH, whole=True,
                                 detail_amplitude=planets.detail_amplitude(planet))
    assert np.array_equal(whole.texels, data.texels)
    # the add-on's legend text and menu come from the same table
    assert {key for key, _, _ in planets.LOD_METHOD_ITEMS} == set(planets.LEVEL_MEANING)
