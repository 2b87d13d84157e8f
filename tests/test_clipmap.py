"""Geometry clipmaps (cext/clipmap.c): a closed planet from orbit to 2 m,
deterministic, identical for any thread count, incremental updates equal
to builds from scratch, bad parameters refused -- in C and through
Planet.refine(method="clipmap")."""
import math
import re
from array import array

import pytest

import planetlod as pl

SOURCES = [
    "clipmap.c", "mesh.c", "session.c", "base.c", "status.c", "planet.c", "camera.c",
    "bound.c", "cubemap.c", "projection.c", "detail.c", "heighttiles.c", "insets.c",
    "lodtree.c", "lodupdate.c", "image_buffer.c", "image_raw.c", "geotiff.c", "resample.c",
    "chunked.c", "geomipmap.c", "facetiles.c",
]

RADIUS = 6371000.0


def test_c_closed_deterministic_incremental_and_bad_parameters(run_c_test):
    """One build of tests/c/test_clipmap.c: the whole planet closed at frames
    of a descent from 20,000 km to 2 m on every cube projection (morph and
    detail fade on and off); a culled flight whose open edges all lie out of
    view, incremental updates equal to fresh builds, 1 and 3 threads alike;
    bad parameters refused."""
    out = run_c_test("test_clipmap", SOURCES)
    assert out.strip().endswith("passed"), out
    rows = [line for line in out.splitlines() if line.startswith("closed ")]
    assert {row.split()[1] for row in rows} == {"qsc", "tsc", "csc", "spherified"}
    assert all(row.endswith("open 0") for row in rows), out
    # the descent reaches the finest level the 2 m camera asks for
    assert max(int(re.search(r"finest +(\d+)", row).group(1)) for row in rows) == 24
    kept = re.search(r"levels kept (\d+) rebuilt (\d+)", out)
    assert kept and int(kept.group(1)) > 0, out
    # frames where the nadir stays in its cells rebuild nothing
    assert any("first_rebuilt 25" in line for line in out.splitlines()), out


# ---- through the binding ---------------------------------------------------------------

def _camera(alt, pitch_deg=-30.0, lon_deg=44.0, lat_deg=34.0, top=0.0):
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    d = (math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat))
    east = (-math.sin(lon), math.cos(lon), 0.0)
    north = (-math.sin(lat) * math.cos(lon), -math.sin(lat) * math.sin(lon), math.cos(lat))
    pitch = math.radians(pitch_deg)
    eye = [d[i] * (RADIUS + top + alt) for i in range(3)]
    fwd = [east[i] * math.cos(pitch) + d[i] * math.sin(pitch) for i in range(3)]
    back = [-f for f in fwd]
    up = d if abs(pitch_deg) < 89.0 else north
    right = [up[1] * back[2] - up[2] * back[1], up[2] * back[0] - up[0] * back[2],
             up[0] * back[1] - up[1] * back[0]]
    n = math.sqrt(sum(x * x for x in right))
    right = [x / n for x in right]
    upv = [back[1] * right[2] - back[2] * right[1], back[2] * right[0] - back[0] * right[2],
           back[0] * right[1] - back[1] * right[0]]
    m = [[right[r], upv[r], back[r], eye[r]] for r in range(3)] + [[0.0, 0.0, 0.0, 1.0]]
    return pl.Camera(m, clip_start=0.5, clip_end=1e9)


def _planet():
    return pl.Planet(RADIUS, projection="qsc",
                     detail=dict(amplitude=800.0, seed=5, style="mountains"))


def _mesh_bytes(mesh):
    return tuple(bytes(getattr(mesh, name)) for name in (
        "positions", "normals", "uv", "morph", "detail", "triangles", "sector_level", "face"))


def _open_edges(mesh):
    """Edges in one triangle after welding vertices by position."""
    pos = bytes(mesh.positions)
    ids, weld = [], {}
    for v in range(mesh.vertex_count):
        ids.append(weld.setdefault(pos[12 * v:12 * v + 12], len(weld)))
    tri = mesh.triangles.tolist()
    count = {}
    for t in range(0, len(tri), 3):
        for k in range(3):
            a, b = ids[tri[t + k]], ids[tri[t + (k + 1) % 3]]
            if a != b:
                key = (a, b) if a < b else (b, a)
                count[key] = count.get(key, 0) + 1
    return sum(1 for c in count.values() if c != 2)


# altitudes of the descent, with the pitch raised toward the horizon
DESCENT = [(2e7, -90.0), (2e5, -60.0), (2e3, -30.0), (2.0, -10.0)]


@pytest.mark.parametrize("alt,pitch", DESCENT)
def test_whole_planet_is_closed(alt, pitch):
    planet = _planet()
    top = planet.height_range()[1]
    stats = planet.refine(_camera(alt, pitch, top=top), method="clipmap", backface=False,
                          frustum=False, threads=2)
    mesh = planet.mesh(morph=True, threads=2)
    assert stats["method"] == "clipmap"
    assert mesh.triangle_count == stats["triangles"] > 0
    assert _open_edges(mesh) == 0
    levels = mesh.sector_level.tolist()
    assert min(levels) >= 0 and max(levels) == stats["max_level"]


def test_deterministic_incremental_and_thread_identical():
    top = _planet().height_range()[1]
    path = [_camera(300.0 - 10 * k, -20.0, lon_deg=44.0 + 0.0004 * k, top=top)
            for k in range(6)]
    flown = _planet()
    for k, camera in enumerate(path):
        flown.refine(camera, method="clipmap", threads=2)
        got = _mesh_bytes(flown.mesh(morph=True, threads=1))
        fresh = _planet()
        fresh.refine(camera, method="clipmap")
        assert _mesh_bytes(fresh.mesh(morph=True, threads=3)) == got, k
    # the same camera again keeps every level
    again = flown.refine(path[-1], method="clipmap")
    assert again["splits"] == 0


def test_morph_off_still_closed_and_alpha_binary():
    planet = _planet()
    planet.refine(_camera(5000.0, -45.0), method="clipmap", backface=False, frustum=False)
    mesh = planet.mesh(morph=False)
    assert _open_edges(mesh) == 0
    assert set(mesh.morph.tolist()) <= {0.0, 1.0}
    morphed = planet.mesh(morph=True)
    assert any(0.0 < a < 1.0 for a in morphed.morph.tolist())


@pytest.mark.parametrize("kwargs,words", [
    (dict(clipmap_ring_cells=23), "clipmap_ring_cells"),
    (dict(clipmap_ring_cells=2000), "clipmap_ring_cells"),
    (dict(template_level=7), "template_level"),
    (dict(max_pixel_error=0.0), "max_pixel_error"),
])
def test_bad_parameters_refused(kwargs, words):
    planet = _planet()
    with pytest.raises(pl.InvalidArgument, match=words):
        planet.refine(_camera(1000.0), method="clipmap", **kwargs)


def test_car_planet_refused():
    planet = pl.Planet(RADIUS, projection="car")
    with pytest.raises(pl.InvalidArgument, match="cube projection"):
        planet.refine(_camera(1000.0), method="clipmap")


def test_mesh_level_must_be_the_refines():
    planet = _planet()
    planet.refine(_camera(1000.0), method="clipmap", template_level=3)
    with pytest.raises(pl.InvalidArgument):
        planet.mesh(template_level=2)
    assert planet.mesh(template_level=3).triangle_count > 0


def test_the_addon_work_draws_clipmaps(planetlod):
    """The add-on's refresh refines with LOD Method 'Geometry Clipmaps' and
    draws the rings' whole mesh as one preview patch (as for the other
    patch methods)."""
    from test_lod_methods import test_the_addon_work_draws_a_method as draws_a_method
    draws_a_method(planetlod, "CLIPMAP")
