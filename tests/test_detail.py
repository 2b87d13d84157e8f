"""The detail field (cext/detail.c): Planet(detail=...) heights and normals,
seams, determinism, sector bounds, refinement and meshes with detail on,
and detail off giving the map's surface bit for bit."""
import math

import numpy as np
import pytest

from conftest import UNDER_SANITIZER, data_path
from test_mesh import arrays, edge_report
from test_refine import (check_conforming, corners, frame_state, look_at, surface_camera,
                         worst_pixel_gap)

EARTH_R = 6371000.0
MOON_R = 1737400.0
WEIGHTS = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [.5, .5, 0], [0, .5, .5], [.5, 0, .5],
                    [1 / 3, 1 / 3, 1 / 3], [.7, .2, .1], [.1, .2, .7], [.05, .9, .05]])
ALPS = (46.5, 8.0)


def unit(lat_deg, lon_deg):
    la, lo = math.radians(lat_deg), math.radians(lon_deg)
    return np.array([math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)])


def earth_planet(planetlod, detail=None, **kw):
    kw.setdefault("heightmap_size", 256)
    return planetlod.Planet(EARTH_R, heightmap=data_path("earth-topology.png"),
                            height_scale=8848.0, sea_level=0.0, detail=detail, **kw)


MOUNTAINS = dict(style="mountains", amplitude=400.0, seed=3)


@pytest.fixture(scope="module")
def earth_detail(planetlod):
    return earth_planet(planetlod, MOUNTAINS)


@pytest.fixture(scope="module")
def earth_plain(planetlod):
    return earth_planet(planetlod)


def ground_camera(planetlod, planet, lat, lon, altitude, pitch=-0.25, radius=EARTH_R, **kw):
    d = unit(lat, lon)
    ground = planet.height(*d)
    return surface_camera(planetlod, radius + ground, altitude, lat=math.radians(lat),
                          lon=math.radians(lon), pitch=pitch, **kw)


def check_bounds(planet, sample_limit=3000, rng=None):
    """Every sampled point of every (or a spread of) sector(s) lies inside
    its height bounds; returns the number of points checked."""
    c = corners(planet)
    h = np.array(planet.sector_heights(visible_only=False).tolist()).reshape(-1, 2)
    pick = np.arange(len(c))
    if len(pick) > sample_limit:
        rng = rng or np.random.default_rng(0)
        pick = rng.choice(len(c), size=sample_limit, replace=False)
    checked = 0
    for k in pick:
        lo, hi = h[k]
        for w in WEIGHTS:
            p = w @ c[k]
            z = planet.height(*(p / np.linalg.norm(p)))
            assert lo <= z <= hi, (k, lo, z, hi)
            checked += 1
    return checked


def test_detail_off_is_the_map_bit_for_bit(planetlod, earth_plain):
    """detail=None, detail=dict(enabled=False) and no detail argument give
    the same heights, sectors and mesh, bit for bit."""
    off = earth_planet(planetlod, dict(MOUNTAINS, enabled=False))
    assert off.detail is None and earth_plain.detail is None
    cam = ground_camera(planetlod, earth_plain, *ALPS, 3000.0)
    meshes = []
    for planet in (earth_plain, off):
        planet.refine(cam)
        meshes.append(planet.mesh(template_level=3))
    assert bytes(earth_plain.sector_ids()) == bytes(off.sector_ids())
    for name in ("positions", "normals", "uv", "triangles"):
        assert bytes(getattr(meshes[0], name)) == bytes(getattr(meshes[1], name)), name
    rng = np.random.default_rng(1)
    for d in rng.normal(size=(200, 3)):
        assert earth_plain.height(*d) == off.height(*d)
    assert earth_plain.height_range() == off.height_range()


def test_relief_follows_the_map(planetlod, earth_detail, earth_plain):
    """Detail is flat on the sea, gentle on plains, rugged in mountains:
    the spread of (height - map height) over a 5 km patch."""
    rng = np.random.default_rng(2)

    def spread(lat, lon):
        base = unit(lat, lon)
        east = np.cross([0, 0, 1.0], base)
        east /= np.linalg.norm(east)
        north = np.cross(base, east)
        diffs = []
        for a, b in rng.uniform(-0.5, 0.5, size=(300, 2)) * (5000.0 / EARTH_R):
            d = base + a * east + b * north
            d /= np.linalg.norm(d)
            diffs.append(earth_detail.height(*d) - earth_plain.height(*d))
        return np.std(diffs)

    sea = spread(-30.0, -140.0)     # South Pacific
    plains = spread(52.0, 30.0)     # Eastern European plain
    mountains = spread(*ALPS)
    assert sea == 0.0
    assert 0.0 < plains < 0.6 * mountains, (plains, mountains)
    assert mountains > 10.0, mountains


def test_detail_is_deterministic_and_seeded(planetlod, earth_detail):
    again = earth_planet(planetlod, MOUNTAINS)
    other = earth_planet(planetlod, dict(MOUNTAINS, seed=4))
    rng = np.random.default_rng(5)
    same = differ = 0
    for d in rng.normal(size=(300, 3)):
        h = earth_detail.height(*d)
        assert h == again.height(*d)
        same += 1
        differ += h != other.height(*d)
    assert differ > 60  # land points (~30 %) move with the seed, sea ones stay
    info = earth_detail.detail
    assert info["style"] == "mountains" and info["octaves"] >= 15
    assert 0.05 <= info["finest_wavelength"] <= 0.1 * 2 + 1e-9


@pytest.mark.parametrize("where", ["date_line", "pole", "cube_edge", "cube_corner"])
def test_detail_is_seamless(planetlod, earth_detail, where):
    """Across the date line, at the poles and across cube face edges and
    corners the surface is continuous: heights 1 mm apart differ by no
    more than the field's slope allows there."""
    if where == "date_line":
        a, b = unit(45.3, 179.99999999), unit(45.3, -179.99999999)
        planet = earth_detail
    elif where == "pole":
        a, b = unit(89.99999999, 10.0), unit(89.99999999, -170.0)
        planet = earth_detail
    else:  # a map-free planet: the field alone, no map seams
        planet = planetlod.Planet(1000e3, detail=dict(MOUNTAINS, amplitude=300.0))
        base = np.array([1.0, 1.0, 0.3]) if where == "cube_edge" else np.array([1.0, 1.0, 1.0])
        base /= np.linalg.norm(base)
        a = base + np.array([1e-9, -1e-9, 0.0])
        b = base - np.array([1e-9, -1e-9, 0.0])
    gap = np.linalg.norm(a - b) * planet.radius
    assert gap < 0.01
    dh = abs(planet.height(*a) - planet.height(*b))
    assert dh < 5.0 * gap + 1e-6, (where, dh, gap)


def test_surface_normals_follow_the_heights(planetlod):
    """planet.surface() normals match central differences of planet.height
    in the tangent plane (no map: the field alone, hills style)."""
    planet = planetlod.Planet(50e3, detail=dict(style="hills", amplitude=200.0, seed=9,
                                                smallest=5.0))
    rng = np.random.default_rng(4)
    dirs = rng.normal(size=(60, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    heights, normals = planet.surface(dirs.reshape(-1).tolist())
    normals = np.array(normals.tolist()).reshape(-1, 3)
    worst = 0.0
    tilt = 0.0
    step = 1e-6
    for d, n in zip(dirs, normals):
        t1 = np.cross(d, [0.3, 0.5, 0.8])
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(d, t1)
        slope = []
        for t in (t1, t2):
            p, q = d + step * t, d - step * t
            slope.append((planet.height(*(p / np.linalg.norm(p))) -
                          planet.height(*(q / np.linalg.norm(q)))) / (2 * step))
        r = planet.radius + planet.height(*d)
        exact = r * d - slope[0] * t1 - slope[1] * t2
        exact /= np.linalg.norm(exact)
        worst = max(worst, math.degrees(math.acos(min(1.0, float(exact @ n)))))
        tilt = max(tilt, math.degrees(math.acos(min(1.0, float(d @ n)))))
    assert tilt > 5.0, tilt
    assert worst < 0.05, worst


@pytest.mark.parametrize("lat,lon,altitude", [(46.5, 8.0, 2000.0), (46.5, 8.0, 100.0),
                                              (27.9, 86.9, 10.0), (52.0, 30.0, 1500.0),
                                              (89.9, 0.0, 3000.0)])
def test_sector_bounds_hold_with_detail(planetlod, earth_detail, lat, lon, altitude):
    """Sector height bounds hold the detailed surface at points spread over
    each sector, from 2 km down to 10 m above the ground, and stay useful:
    the refinement does not run to max_level."""
    cam = ground_camera(planetlod, earth_detail, lat, lon, altitude)
    stats = earth_detail.refine(cam, max_level=48)
    assert stats["max_level"] < 48, stats
    assert check_bounds(earth_detail) > 1000
    check_conforming(earth_detail)


def test_mesh_vertices_inside_their_sector_bounds(planetlod, earth_detail):
    """Band-limited mesh vertices (fewer octaves than planet.height) lie in
    their sectors' bounds too."""
    cam = ground_camera(planetlod, earth_detail, *ALPS, 500.0)
    earth_detail.refine(cam)
    mesh = earth_detail.mesh(template_level=3)
    pos = np.frombuffer(mesh.positions, np.float32).reshape(-1, 3).astype(np.float64)
    pos += np.array(mesh.origin)
    h = np.linalg.norm(pos, axis=1) - EARTH_R
    per = len(h) // mesh.sector_count
    bounds = np.array(earth_detail.sector_heights(visible_only=True).tolist()).reshape(-1, 2)
    lo = np.repeat(bounds[:, 0], per)
    hi = np.repeat(bounds[:, 1], per)
    dist = np.linalg.norm(pos - np.array(mesh.origin), axis=1)
    tol = 2e-7 * dist + 1e-3
    assert np.all(h >= lo - tol) and np.all(h <= hi + tol)


def test_refinement_splits_where_detail_shows(planetlod, earth_detail, earth_plain):
    """Over mountains detail adds sectors; over the sea it adds none.  (The
    criterion counts the detail's expected error, and no octave finer than
    a couple of pixels: a fifth more sectors here.)"""
    counts = {}
    for name, lat, lon in (("sea", -30.0, -140.0), ("mountains", 46.5, 8.0)):
        cam = ground_camera(planetlod, earth_plain, lat, lon, 1500.0, pitch=-0.4)
        counts[name] = [p.refine(cam)["sectors_total"] for p in (earth_plain, earth_detail)]
    assert counts["sea"][1] == counts["sea"][0], counts
    assert counts["mountains"][1] > 1.15 * counts["mountains"][0], counts


@pytest.mark.parametrize("altitude", [2000.0, 30.0])
def test_mesh_within_a_pixel_of_the_detailed_surface(planetlod, earth_detail, altitude):
    """The criterion holds the detail's expected error (its octaves' errors
    as independent, root of the sum of squares) to the pixel: the worst of
    1,600 points stays within a quarter more."""
    cam = ground_camera(planetlod, earth_detail, *ALPS, altitude)
    earth_detail.refine(cam, max_pixel_error=1.0, template_level=4)
    worst = worst_pixel_gap(earth_detail, cam, EARTH_R, np.random.default_rng(8),
                            sampled=1000, nearest=600)
    assert worst <= 1.25, worst


def test_detail_mesh_watertight_threads_cache_morph(planetlod, earth_detail):
    """Shared edge vertices are bit-identical (welded mesh has no open
    edges), output is the same for 1 and 2 threads, cached or not, with
    and without morph, frame after frame along a descent."""
    hits = 0
    altitudes = (20000.0, 6000.0, 2000.0, 700.0)
    for k, altitude in enumerate(altitudes[1::2] if UNDER_SANITIZER else altitudes):
        cam = ground_camera(planetlod, earth_detail, 46.5, 8.0 + 0.002 * k, altitude)
        earth_detail.refine(cam, backface=False, frustum=False, max_sectors=60000)
        base = earth_detail.mesh(template_level=3, threads=1, cache=False)
        assert edge_report(*arrays(base)) == (0, 0, 0, 2), k  # a closed sphere
        for morph, threads in ((False, 2), (True, 2), (True, 1)):
            ref = earth_detail.mesh(template_level=3, threads=1, cache=False, morph=morph)
            got = earth_detail.mesh(template_level=3, threads=threads, cache=True, morph=morph)
            for name in ("positions", "normals", "uv", "morph", "triangles", "detail"):
                assert bytes(getattr(ref, name)) == bytes(getattr(got, name)), (k, name, morph)
        hits += earth_detail.mesh_cache_info["hits"]
    assert hits > 0


def test_changed_only_mesh_keeps_a_copy_current(planetlod):
    """mesh(changed_only=True) emits only what changed since the previous
    cached mesh(): new sectors, and kept sectors whose corner normals the
    eye moved to another band.  A copy kept per sector id from those
    emissions (as the GPU preview keeps one) equals an uncached mesh of
    the same sectors, frame after frame along a descent; any other cached
    mesh() in between shows in mesh_cache_info's emission count."""
    planet = earth_planet(planetlod, MOUNTAINS)
    kept, emitted, visible, renewed = {}, 0, 0, 0
    serial = planet.mesh_cache_info["emissions"]
    for k in range(10):
        altitude = 30000.0 * 0.55 ** k
        cam = ground_camera(planetlod, planet, 46.5, 8.0 + 0.0004 * k, altitude)
        planet.refine(cam, hysteresis=True)
        assert planet.mesh_cache_info["emissions"] == serial
        mesh = planet.mesh(template_level=3, changed_only=True)
        serial += 1
        assert planet.mesh_cache_info["emissions"] == serial
        ids = np.frombuffer(mesh.sector_ids, np.uint64)
        assert len(ids) == mesh.sector_count == mesh.vertex_count // 45
        pos = np.frombuffer(mesh.positions, np.float32).reshape(-1, 45, 3)
        normals = np.frombuffer(mesh.normals, np.float32).reshape(-1, 45, 3)
        detail = np.frombuffer(mesh.detail, np.float32).reshape(-1, 45)
        renewed += sum(1 for i in ids.tolist() if i in kept)
        for j, sector in enumerate(ids.tolist()):
            kept[sector] = (pos[j].astype(np.float64) + mesh.origin, normals[j], detail[j])
        now = np.frombuffer(planet.sector_ids(), np.uint64).tolist()
        kept = {sector: kept[sector] for sector in now}
        emitted += len(ids)
        visible += len(now)
        ref = planet.mesh(template_level=3, cache=False)
        assert len(kept) == ref.sector_count
        ref_pos = np.frombuffer(ref.positions, np.float32).reshape(-1, 45, 3)
        ref_normals = np.frombuffer(ref.normals, np.float32).reshape(-1, 45, 3)
        ref_detail = np.frombuffer(ref.detail, np.float32).reshape(-1, 45)
        for j, sector in enumerate(np.frombuffer(ref.sector_ids, np.uint64).tolist()):
            p, n, d = kept[sector]
            near = ref_pos[j].astype(np.float64)
            gap = np.abs(p - (near + ref.origin)).max()
            assert gap <= 2.0 ** -22 * (np.abs(near).max() + np.abs(p - mesh.origin).max()), k
            assert np.array_equal(n, ref_normals[j]) and np.array_equal(d, ref_detail[j]), k
    assert emitted < 0.6 * visible  # most sectors were kept, not emitted again
    assert renewed > 0  # kept sectors whose corner normals changed band came again
    planet.mesh(template_level=3)  # another emission: the copy's caller can tell
    assert planet.mesh_cache_info["emissions"] == serial + 1
    for bad in (dict(morph=True), dict(cache=False)):
        with pytest.raises(planetlod.InvalidArgument):
            planet.mesh(template_level=3, changed_only=True, **bad)


def test_mesh_detail_output_is_the_fields_part_of_the_height(planetlod, earth_detail,
                                                             earth_plain):
    """mesh.detail: per vertex, the vertex's height above the radius minus the
    map's height there (the octaves the vertex keeps, times the modulation);
    0 on the sea and without detail; the other outputs unchanged by it."""
    cam = ground_camera(planetlod, earth_detail, *ALPS, 3000.0)
    earth_detail.refine(cam)
    mesh = earth_detail.mesh(template_level=3)
    detail = np.frombuffer(mesh.detail, np.float32).astype(np.float64)
    assert len(detail) == mesh.vertex_count
    pos = np.frombuffer(mesh.positions, np.float32).reshape(-1, 3).astype(np.float64)
    pos += np.array(mesh.origin)
    distance = np.linalg.norm(pos, axis=1)
    pick = np.random.default_rng(5).choice(len(pos), size=3000, replace=False)
    dirs = pos[pick] / distance[pick, None]
    map_heights, _ = earth_plain.surface(dirs.ravel().tolist())
    expected = distance[pick] - EARTH_R - np.array(map_heights)
    tol = 2e-7 * np.linalg.norm(pos[pick] - np.array(mesh.origin), axis=1) + 1e-2
    assert np.all(np.abs(detail[pick] - expected) <= tol), np.abs(detail[pick] - expected).max()
    assert np.abs(detail).max() > 10.0 and (detail > 0).any() and (detail < 0).any()
    # the sea (modulation 0) has none
    sea_cam = ground_camera(planetlod, earth_detail, -30.0, -140.0, 3000.0)
    earth_detail.refine(sea_cam)
    assert not np.frombuffer(earth_detail.mesh(template_level=3).detail, np.float32).any()
    # without detail: zeros, and the same positions as the detail planet's map part
    earth_plain.refine(cam)
    plain = earth_plain.mesh(template_level=3)
    assert not np.frombuffer(plain.detail, np.float32).any()


def test_detail_refinement_is_history_free_and_thread_identical(planetlod, earth_detail):
    cams = [ground_camera(planetlod, earth_detail, 46.5, 8.0 + 0.05 * k, a)
            for k, a in enumerate((50000.0, 800.0, 3000.0, 40.0))]
    for cam in cams:
        earth_detail.refine(cam)
    history = bytes(earth_detail.sector_ids())
    fresh = earth_planet(planetlod, MOUNTAINS)
    fresh.refine(cams[-1], threads=2)
    assert bytes(fresh.sector_ids()) == history


def test_small_moves_refine_as_a_fresh_planet(planetlod, earth_detail):
    """The refiner keeps each sector's distance decision while the eye
    cannot have moved far enough to change it.  Along a descent over the
    Alps in metre steps (where a decision kept 1.5 times too long already
    changes most frames), with the eye standing still, stepping by less than
    a rounding unit, jumping, and the thresholds changing and changing back
    (pixel error, template level, criterion, lens, orthographic), every
    frame has exactly the leaves, flags and order of a fresh refine."""
    fresh = earth_planet(planetlod, MOUNTAINS)
    earth_detail.reset()
    steps = [1.0] * 8 + [0.0, 0.0, 1e-9, 1e-9] + [2.0] * 4 + [300.0] + [1.0] * 4
    changes = {20: dict(max_pixel_error=2.0), 22: dict(template_level=3),
               24: dict(criterion="side_distance"), 26: dict(lens=35.0), 28: dict(ortho=True)}
    along = 0.0
    for k in range(32):
        along += steps[k % len(steps)]
        kw = dict(changes.get(k, {}))
        lens = kw.pop("lens", 50.0)
        ortho = kw.pop("ortho", False)
        cam = ground_camera(planetlod, earth_detail, 46.5, 8.0 + along * 1.3e-5, 60.0 - k,
                            lens=lens, type="ORTHO" if ortho else "PERSP", ortho_scale=200.0)
        s = earth_detail.refine(cam, **kw)
        fresh.reset()
        f = fresh.refine(cam, **kw)
        assert frame_state(earth_detail) == frame_state(fresh), (k, kw)
        assert s["sectors_after_frustum"] == f["sectors_after_frustum"], k
    assert f["sectors_total"] > 1000
    assert earth_detail.check_invariants()


@pytest.mark.parametrize("style", ["hills", "mountains", "craters"])
def test_heights_are_the_same_with_and_without_normals(planetlod, style):
    """height() sums the field without its gradient; surface() (normals,
    as mesh vertices) with it: the same heights bit for bit, at every
    direction, for every style and the crater layer."""
    planet = planetlod.Planet(20e3, detail=dict(style=style, amplitude=300.0, seed=5,
                                                largest=8000.0, smallest=0.5, craters=1.0))
    rng = np.random.default_rng(12)
    dirs = rng.normal(size=(3000, 3))
    heights, _normals = planet.surface(dirs.reshape(-1).tolist())
    # surface() divides by the length first, as here; height() does not
    x, y, z = dirs[:, 0], dirs[:, 1], dirs[:, 2]
    dirs = dirs / np.sqrt(x * x + y * y + z * z)[:, None]
    alone = [planet.height(*d) for d in dirs]
    assert list(heights) == alone
    assert np.std(alone) > 10.0


@pytest.mark.parametrize("style", ["hills", "mountains", "craters"])
def test_batched_surface_is_the_point_path_on_a_map(planetlod, style):
    """surface() over many directions evaluates the field a batch at a
    time, octave by octave across SIMD lanes; every point's height and
    normal are those of surface() at that point alone, bit for bit (land,
    sea, every style and the crater layer)."""
    planet = earth_planet(planetlod, dict(style=style, amplitude=800.0, seed=7, craters=1.0,
                                          smallest=0.05))
    rng = np.random.default_rng(21)
    # clusters of nearby directions interleaved, runs of them (as a
    # sector's vertices: whole batches in one lattice cell of the coarse
    # octaves) and scattered ones
    centres = rng.normal(size=(40, 3))
    centres /= np.linalg.norm(centres, axis=1)[:, None]
    near = np.array([centres[k % 40] + 1e-6 * (1 + k % 50) * rng.normal(size=3)
                     for k in range(1500)])
    runs = np.array([centres[k // 150] + 10.0 ** -(5 + k // 150 % 4) * rng.normal(size=3)
                     for k in range(750)])
    dirs = np.concatenate([near, runs, rng.normal(size=(500, 3))])
    flat = dirs.reshape(-1).tolist()
    heights, normals = planet.surface(flat)
    normals = list(normals)
    for k in range(0, len(dirs), 3):
        h, n = planet.surface(flat[3 * k:3 * k + 3])
        assert (h[0], list(n)) == (heights[k], normals[3 * k:3 * k + 3]), k
    assert np.std(list(heights)) > 10.0


def renormalised(d):
    """d divided by its length until that changes nothing (None if it
    keeps changing): a unit direction as surface() would compute it."""
    for _ in range(6):
        length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        e = (d[0] / length, d[1] / length, d[2] / length)
        if e == d:
            return d
        d = e
    return None


def test_batched_map_samples_are_the_point_path(planetlod, earth_plain, earth_detail):
    """surface() samples the height and normal maps a block at a time
    (texel weights and blends in SIMD lanes, the taps gathered; points on a
    face's last texel row or column one by one): every height is height()'s,
    the point path, bit for bit, on face edges and corners, on the border
    texels and inside."""
    rng = np.random.default_rng(8)
    size = earth_plain.heightmap.size
    border = [1.0, 1.0 - 0.5 / size, 1.0 - 1.0 / size, 1.0 - 1.5 / size, 1.0 - 3.0 / size]
    edge_uv = [(f * a, g * b) for a in border for b in border + [0.0, 0.37]
               for f in (-1, 1) for g in (-1, 1)]
    dirs = [planetlod.face_to_dir("qsc", face, a, b) for face in range(6) for a, b in edge_uv]
    dirs += [tuple(d) for d in rng.normal(size=(600, 3))]
    # surface() renormalises what it is given (height() does not): feed
    # directions its renormalisation leaves as they are
    dirs = [d for d in map(renormalised, dirs) if d]
    assert len(dirs) > 1200
    flat = [c for d in dirs for c in d]
    for planet in (earth_plain, earth_detail):
        heights, _normals = planet.surface(flat)
        for k, d in enumerate(dirs):
            assert heights[k] == planet.height(*d), (k, d)


@pytest.mark.parametrize("style", ["hills", "mountains", "craters"])
def test_styles_on_a_map_free_body(planetlod, style):
    """Without a map the field alone makes the relief (modulation 1); the
    crater style digs bowls: its lowest points sit deeper below the mean
    than its highest rise above it."""
    planet = planetlod.Planet(20e3, detail=dict(style=style, amplitude=300.0, seed=1,
                                                largest=8000.0, smallest=2.0))
    rng = np.random.default_rng(6)
    dirs = rng.normal(size=(4000, 3))
    h = np.array([planet.height(*d) for d in dirs])
    lo, hi = planet.height_range()
    assert lo <= h.min() and h.max() <= hi
    assert h.std() > 10.0
    if style == "craters":
        assert np.mean(h) - h.min() > 1.5 * (h.max() - np.mean(h)), (h.min(), h.mean(), h.max())
    ground = planet.height(*unit(math.degrees(0.3), math.degrees(0.2)))
    cam = surface_camera(planetlod, 20e3 + ground, 300.0, lat=0.3, lon=0.2)
    planet.refine(cam)
    assert check_bounds(planet, sample_limit=1500) > 1000


def test_bad_detail_arguments(planetlod):
    bad = [dict(style="blobs"), dict(amplitude=-1.0), dict(roughness=1.0), dict(smallest=0.0),
           dict(plains=2.0), dict(amplitude="tall"), dict(colour=1), dict(seed=1.5),
           dict(craters=9.0), dict(amplitude=1e5, largest=100.0)]
    for detail in bad:
        with pytest.raises(planetlod.InvalidArgument):
            planetlod.Planet(1000.0, detail=detail)
    with pytest.raises(planetlod.InvalidArgument):
        planetlod.Planet(1000.0, detail=[("amplitude", 1.0)])


def test_planet_presets_detail_is_valid(planetlod):
    """Every planet preset turns detail on with parameters the core accepts
    on its own map, and the style fits the body (craters on airless ones)."""
    import os
    from planetlod import presets
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    styles = {}
    for key, values in presets.PLANETS.items():
        detail = presets.detail_settings(key)
        assert detail and detail["amplitude"] > 0.0, key
        styles[key] = detail["style"]
        planet = planetlod.Planet(values["radius"],
                                  heightmap=os.path.join(root, "data", values["heightmap"]),
                                  height_scale=values["height_scale"], heightmap_size=128,
                                  detail=detail)
        assert planet.detail["octaves"] >= 8, key
    assert styles["EARTH"] == "mountains"
    assert styles["MOON"] == "craters" and styles["ASTEROID"] == "craters"


def test_crater_normals_do_not_speckle_a_whole_body(planetlod):
    """The asteroid preset's craters seen whole (2.6 radii away, 1 px): the
    normals of neighbouring vertices stay within 40 degrees of each other.
    Craters far smaller than a mesh cell, sampled at single vertices, once
    tilted 0.5 % of the triangles' normals that far (black and white specks
    in the preview and renders); their slopes now join the normals four
    octaves after their heights."""
    from planetlod import presets
    settings = presets.PLANETS["ASTEROID"]
    radius = settings["radius"]
    planet = planetlod.Planet(radius, projection=settings["projection"].lower(),
                              height_scale=settings["height_scale"],
                              detail=presets.detail_kwargs(settings))
    eye = np.array([0.5, -1.0, 0.4])
    eye *= 2.6 * radius / np.linalg.norm(eye)
    camera = planetlod.Camera(look_at(eye, (0.0, 0.0, 0.0)), lens=50.0, sensor_width=36.0, resolution_x=640,
                              resolution_y=360, clip_start=1.0, clip_end=1e9)
    for _ in range(20):
        stats = planet.refine(camera, template_level=3, max_pixel_error=1.0)
        if not stats["splits"] and not stats["merges"]:
            break
    mesh = planet.mesh(template_level=3)
    triangles = np.frombuffer(mesh.triangles, np.int32).reshape(-1, 3)
    n = np.frombuffer(mesh.normals, np.float32).reshape(-1, 3)[triangles]
    cosine = np.minimum(np.minimum((n[:, 0] * n[:, 1]).sum(1), (n[:, 1] * n[:, 2]).sum(1)),
                        (n[:, 2] * n[:, 0]).sum(1))
    apart = float((cosine < math.cos(math.radians(40.0))).mean())
    assert len(triangles) > 10000 and apart < 1e-3, (len(triangles), apart)


# The hills' band: octaves of 2.5 km down to 500 m take their own modulation,
# up to 4 times the rest's on hills (the Earth preset's law, plod_detail.h).
HILLS_LAW = dict(style="mountains", amplitude=4000.0, roughness=0.65, plains=0.01,
                 relief=150.0, hills=0.25, highlands=3500.0, fine_roughness=0.43,
                 fine_below=9000.0, seed=1)
HILLS_BAND = dict(HILLS_LAW, hills_fine=4.0, hills_fine_below=2500.0, hills_fine_to=500.0)
JACKSBORO = (36.47, -84.35)
KANSAS = (38.5, -98.5)


@pytest.fixture(scope="module")
def earth_band(planetlod):
    # the map's full size: its local relief sorts plains from hills
    return earth_planet(planetlod, HILLS_BAND, heightmap_size=512)


def window_std(planet, lat, lon, size=1000.0, n=24):
    """Standard deviation of heights on an n x n grid over a window of
    `size` metres centred at (lat, lon)."""
    steps = (np.arange(n) - (n - 1) / 2) * size / (n - 1) / EARTH_R
    dlat, dlon = np.meshgrid(steps, steps / math.cos(math.radians(lat)))
    return float(np.std([planet.height(*unit(lat + math.degrees(a), lon + math.degrees(b)))
                         for a, b in zip(dlat.ravel(), dlon.ravel())]))


def test_hills_band_roughens_hills_not_plains_or_ranges(planetlod, earth_band):
    """The band raises the kilometre relief of hills (the Jacksboro fault,
    Tennessee) and leaves plains (Kansas) and a high range (the Alps) about
    as they were; without a gain the band's keys change nothing, bit for
    bit."""
    law = earth_planet(planetlod, HILLS_LAW, heightmap_size=512)
    off = earth_planet(planetlod, dict(HILLS_BAND, hills_fine=1.0), heightmap_size=512)
    rng = np.random.default_rng(3)
    for d in rng.normal(size=(200, 3)):
        assert off.height(*d) == law.height(*d)
    offsets = [(0.0, 0.0), (0.05, 0.05), (-0.05, 0.03), (0.04, -0.06)]

    def medians(lat, lon):
        return [np.median([window_std(p, lat + a, lon + b) for a, b in offsets])
                for p in (law, earth_band)]
    hills, plains, range_ = medians(*JACKSBORO), medians(*KANSAS), medians(*ALPS)
    assert hills[1] > 2.0 * hills[0], hills
    assert plains[1] < 1.3 * plains[0] + 0.5, plains
    assert range_[1] < 1.1 * range_[0], range_


@pytest.mark.parametrize("lat,lon,altitude", [(*JACKSBORO, 2000.0), (*JACKSBORO, 40.0),
                                              (*ALPS, 300.0)])
def test_hills_band_bounds_hold(planetlod, earth_band, lat, lon, altitude):
    """Sector bounds hold the surface with the band, over hills and a
    range, and the refinement stays bounded."""
    cam = ground_camera(planetlod, earth_band, lat, lon, altitude)
    stats = earth_band.refine(cam, max_level=48)
    assert stats["max_level"] < 48, stats
    assert check_bounds(earth_band) > 1000
    check_conforming(earth_band)


BAND_GAP = ("ridged crests interpolate linearly in the cell where the error model is "
            "quadratic, and the criterion counts a quarter of the band's excess (its slopes "
            "reach the shading through the vertices' normals): over these hills the worst gap "
            "is 2.5-2.8 px with the band, 1.4-1.5 px with the law alone (bench/RESULTS.md)")


@pytest.mark.xfail(strict=True, reason=BAND_GAP)
@pytest.mark.parametrize("altitude", [2000.0, 30.0])
def test_hills_band_mesh_within_a_pixel(planetlod, earth_band, altitude):
    """The mesh holds the band's surface to the pixel as the rest's (the
    worst of 1,600 points within a quarter more)."""
    cam = ground_camera(planetlod, earth_band, *JACKSBORO, altitude)
    earth_band.refine(cam, max_pixel_error=1.0, template_level=4)
    worst = worst_pixel_gap(earth_band, cam, EARTH_R, np.random.default_rng(8),
                            sampled=1000, nearest=600)
    assert worst <= 1.25, worst


def test_hills_band_batches_are_the_point_path(planetlod, earth_band):
    """surface() over many directions (batches, the band's second
    evaluation gathered) gives height()'s and surface()'s single-point
    results bit for bit, and band-limited mesh vertices lie in their
    sectors' bounds."""
    rng = np.random.default_rng(5)
    centre = unit(*JACKSBORO)
    dirs = np.concatenate([centre + 2e-4 * rng.normal(size=(600, 3)), rng.normal(size=(300, 3))])
    dirs = [d for d in map(renormalised, (tuple(d / np.linalg.norm(d)) for d in dirs)) if d]
    flat = [c for d in dirs for c in d]
    heights, normals = earth_band.surface(flat)
    normals = list(normals)
    for k, d in enumerate(dirs):
        assert heights[k] == earth_band.height(*d), k
        h, n = earth_band.surface(list(d))
        assert (h[0], list(n)) == (heights[k], normals[3 * k:3 * k + 3]), k
    cam = ground_camera(planetlod, earth_band, *JACKSBORO, 500.0)
    earth_band.refine(cam)
    emitted = []
    for threads in (1, 2):
        mesh = earth_band.mesh(template_level=3, threads=threads, cache=False)
        emitted.append((bytes(mesh.positions), bytes(mesh.normals)))
        pos = np.frombuffer(mesh.positions, np.float32).reshape(-1, 3).astype(np.float64)
        pos += np.array(mesh.origin)
        h = np.linalg.norm(pos, axis=1) - EARTH_R
        per = len(h) // mesh.sector_count
        bounds = np.array(earth_band.sector_heights(visible_only=True).tolist()).reshape(-1, 2)
        dist = np.linalg.norm(pos - np.array(mesh.origin), axis=1)
        tol = 2e-7 * dist + 1e-3
        assert np.all(h >= np.repeat(bounds[:, 0], per) - tol)
        assert np.all(h <= np.repeat(bounds[:, 1], per) + tol)
    assert emitted[0] == emitted[1]  # the same bytes for any thread count


def test_bad_hills_band_arguments(planetlod):
    for detail in (dict(hills_fine=0.5), dict(hills_fine=20.0), dict(hills_fine_below=-1.0),
                   dict(hills_fine_to=float("nan")), dict(hills_fine="rough")):
        with pytest.raises(planetlod.InvalidArgument):
            planetlod.Planet(1000.0, detail=dict(amplitude=10.0, **detail))
