"""HRTMR refinement: base mesh, conformity, determinism, depth, stats, budget,
clip correction and bad input (planetlod.Planet / planetlod.Camera)."""
import math
import os
import signal
from collections import defaultdict

import numpy as np
import pytest

from conftest import data_path
from planetlod.flyby import look_matrix

EARTH_R = 6371000.0


def look_at(eye, target, up=(0.0, 0.0, 1.0)):
    """Blender-style matrix_world (4x4 nested list): camera at eye looking at target
    (planetlod.flyby.look_matrix; up turned away from a view along it)."""
    e = np.asarray(eye, float)
    f = np.asarray(target, float) - e
    u = np.asarray(up, float)
    if abs(np.dot(f / np.linalg.norm(f), u)) > 0.99:
        u = np.array([1.0, 0.0, 0.0]) if abs(f[0]) < 0.9 * np.linalg.norm(f) else \
            np.array([0.0, 1.0, 0.0])
    return [list(row) for row in look_matrix(e.tolist(), f.tolist(), u.tolist())]


def surface_camera(planetlod, radius, altitude, lat=0.3, lon=0.2, pitch=-0.2, **kw):
    """Camera at `altitude` above the sphere looking roughly along the surface."""
    d = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    east = np.array([-math.sin(lon), math.cos(lon), 0.0])
    eye = d * (radius + altitude)
    view = east * math.cos(pitch) + d * math.sin(pitch)
    kw.setdefault("clip_start", 0.01)
    kw.setdefault("clip_end", 1e9)
    return planetlod.Camera(look_at(eye, eye + view, up=d), **kw)


def space_camera(planetlod, distance, direction=(1.0, 0.3, 0.2), **kw):
    d = np.asarray(direction, float)
    d /= np.linalg.norm(d)
    kw.setdefault("clip_start", 1.0)
    kw.setdefault("clip_end", 1e10)
    return planetlod.Camera(look_at(d * distance, (0, 0, 0)), **kw)


def corners(planet, visible_only=False):
    return np.array(planet.sector_corners(visible_only=visible_only).tolist()).reshape(-1, 3, 3)


def check_conforming(planet):
    """Every edge is shared by exactly two leaves with identical endpoints and
    the two leaves' levels differ by at most one."""
    c = corners(planet)
    levels = planet.sector_levels(visible_only=False).tolist()
    edges = defaultdict(list)
    for s, tri in enumerate(c):
        pts = [tuple(p) for p in tri]
        for e in range(3):
            key = tuple(sorted((pts[e], pts[(e + 1) % 3])))
            edges[key].append(s)
    bad = [k for k, v in edges.items() if len(v) != 2]
    assert not bad, f"{len(bad)} edges not shared by exactly two sectors"
    for a, b in edges.values():
        assert abs(levels[a] - levels[b]) <= 1
    # Euler characteristic of a closed sphere: V - E + F = 2
    verts = {tuple(p) for tri in c for p in tri}
    assert len(verts) - len(edges) + len(c) == 2
    assert planet.check_invariants()


@pytest.mark.parametrize("projection,count", [("qsc", 12), ("tsc", 12), ("csc", 12), ("car", 8)])
def test_base_mesh(planetlod, projection, count):
    p = planetlod.Planet(1000.0, projection=projection)
    assert p.sector_count == count
    assert set(p.sector_levels(visible_only=False).tolist()) == {0}
    c = corners(p)
    for tri in c:
        # counter-clockwise seen from outside
        assert np.dot(np.cross(tri[1] - tri[0], tri[2] - tri[0]), tri.sum(0)) > 0
    check_conforming(p)
    # base sectors tile the sphere: spherical excesses sum to 4 pi
    area = 0.0
    for a, b, cc in c:
        num = abs(np.dot(a, np.cross(b, cc)))
        den = 1 + np.dot(a, b) + np.dot(b, cc) + np.dot(cc, a)
        area += 2 * math.atan2(num, den)
    assert area == pytest.approx(4 * math.pi, rel=1e-12)


@pytest.mark.parametrize("projection", ["qsc", "tsc", "car"])
def test_conforming_after_refine(planetlod, projection):
    p = planetlod.Planet(EARTH_R, projection=projection)
    for cam in (space_camera(planetlod, 2e7), surface_camera(planetlod, EARTH_R, 3e5),
                surface_camera(planetlod, EARTH_R, 2e3)):
        s = p.refine(cam, criterion="side_distance", max_level=22)
        assert s["sectors_total"] == p.sector_count > 12
        check_conforming(p)
    # and after coming back out (merges)
    s = p.refine(space_camera(planetlod, 4e7), criterion="side_distance", max_level=22)
    assert s["merges"] > 0
    check_conforming(p)


def test_conforming_with_heightmap(planetlod, earth):
    for alt in (2e6, 5e3, 20.0):
        earth.refine(surface_camera(planetlod, EARTH_R, alt, lat=0.5, lon=1.4))
        check_conforming(earth)


@pytest.fixture(scope="module")
def earth(planetlod):
    return planetlod.Planet(EARTH_R, projection="qsc",
                            heightmap=data_path("earth-topology.png"),
                            height_scale=8848.0, sea_level=0.0, heightmap_size=256)


def sorted_ids(planet):
    return sorted(planet.sector_ids(visible_only=False).tolist())


@pytest.mark.parametrize("criterion", ["pixel", "side_distance"])
def test_deterministic_history(planetlod, criterion):
    a = surface_camera(planetlod, EARTH_R, 500.0, lat=0.1, lon=-0.4)
    b = surface_camera(planetlod, EARTH_R, 8e5, lat=0.9, lon=2.0, pitch=-0.6)
    c = space_camera(planetlod, 3e7)
    kw = dict(criterion=criterion, max_level=40)
    fresh = planetlod.Planet(EARTH_R)
    fresh.refine(a, **kw)
    want = sorted_ids(fresh)
    p = planetlod.Planet(EARTH_R)
    for cam in (b, a, c, b, a):
        p.refine(cam, **kw)
    assert sorted_ids(p) == want
    # refining again at the same camera changes nothing
    s = p.refine(a, **kw)
    assert s["splits"] == 0 and s["merges"] == 0


def random_camera(planetlod, rng):
    """A camera where refinement is hardest to get right: near the ground,
    in orbit, over a pole, on the date line or a cube edge/corner."""
    kind = rng.choice(["ground", "low", "orbit", "pole", "seam", "corner"])
    altitude = {"ground": lambda: rng.uniform(2.0, 3e3), "low": lambda: rng.uniform(3e3, 3e5),
                "orbit": lambda: rng.uniform(3e5, 3e7)}.get(kind, lambda: 10 ** rng.uniform(0.5, 6.5))()
    lat, lon = rng.uniform(-1.4, 1.4), rng.uniform(-math.pi, math.pi)
    if kind == "pole":
        lat = rng.choice([-1, 1]) * (math.pi / 2 - rng.uniform(0.0, 1e-3))
    elif kind == "seam":
        lon = rng.choice([math.pi, -math.pi, math.pi / 4, -3 * math.pi / 4])
    elif kind == "corner":
        lat, lon = math.atan(1 / math.sqrt(2)), math.pi / 4
    if altitude > 3e5 and rng.random() < 0.5:
        return space_camera(planetlod, EARTH_R + altitude, direction=(
            math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)))
    return surface_camera(planetlod, EARTH_R, altitude, lat=lat, lon=lon,
                          pitch=rng.uniform(-1.5, 0.4))


def random_settings(rng):
    return dict(criterion=rng.choice(["pixel", "side_distance"]),
                max_pixel_error=rng.choice([1.0, 2.0, 4.0]), split_border=rng.choice([0.5, 1.0]),
                backface=rng.random() < 0.7, frustum=rng.random() < 0.7,
                budget=rng.choice([0, 0, 200]), skip_sea=rng.random() < 0.3,
                max_level=rng.choice([20, 48]), template_level=rng.choice([3, 4, 5]),
                threads=rng.choice([1, 2]), max_sectors=1 << 16)


def frame_state(planet):
    """Everything a frame's refinement decides: the leaf set with each
    leaf's flags, and the visible sectors in their emission order."""
    ids = planet.sector_ids(visible_only=False).tolist()
    flags = planet.sector_flags(visible_only=False).tolist()
    return sorted(zip(ids, flags)), planet.sector_ids(visible_only=True).tolist()


@pytest.mark.parametrize("projection", ["qsc", "tsc", "csc", "spherified", "car"])
def test_refinement_does_not_depend_on_history(planetlod, projection):
    """Seeded random camera sequences (ground, orbit, poles, seams, cube
    corners; culling on/off, both criteria, budget, threads): refining the
    last camera after the others gives exactly the leaves, flags and
    emission order of a fresh refine at that camera."""
    import random
    rng = random.Random(f"history-{projection}")
    heightmap = planetlod.CubeMap.from_image(data_path("earth-topology.png"),
                                             projection=projection, size=256)
    incremental = planetlod.Planet(EARTH_R, projection=projection, heightmap=heightmap,
                                   height_scale=8848.0, sea_level=0.0)
    fresh = planetlod.Planet(EARTH_R, projection=projection, heightmap=heightmap,
                             height_scale=8848.0, sea_level=0.0)
    merged = compared = 0
    for sequence in range(20):
        settings = random_settings(rng)
        cameras = [random_camera(planetlod, rng) for _ in range(rng.randint(2, 4))]
        for camera in cameras:
            s = incremental.refine(camera, **settings)
            merged += s["merges"]
        fresh.reset()
        f = fresh.refine(cameras[-1], **settings)
        if f["truncated"]:  # max_sectors stopped the split pass: a partial,
            continue        # order-dependent set by definition
        compared += 1
        assert frame_state(incremental) == frame_state(fresh), (sequence, settings)
        for key in ("sectors_total", "sectors_after_backface", "sectors_after_frustum",
                    "sectors_after_budget", "sectors_sea_skipped", "max_level"):
            assert s[key] == f[key], (sequence, key)
        assert incremental.check_invariants()
        again = incremental.refine(cameras[-1], **settings)
        assert again["splits"] == again["merges"] == 0
    assert merged > 0 and compared >= 15


def test_meshes_do_not_depend_on_history(planetlod, earth):
    """A mesh emitted after any earlier frames is byte-identical to one
    emitted from a fresh planet at the same camera (canonical sector order)."""
    a = surface_camera(planetlod, EARTH_R, 2e3, lat=0.8, lon=0.15)   # over the Alps
    b = surface_camera(planetlod, EARTH_R, 3e5, lat=-0.3, lon=-1.2)  # over the Andes
    incremental = planetlod.Planet(EARTH_R, heightmap=earth.heightmap, height_scale=8848.0,
                                   sea_level=0.0)
    for camera in (a, b, a):
        incremental.refine(camera, frustum=False)
    fresh = planetlod.Planet(EARTH_R, heightmap=earth.heightmap, height_scale=8848.0,
                             sea_level=0.0)
    fresh.refine(a, frustum=False)
    one, two = incremental.mesh(morph=True), fresh.mesh(morph=True)
    assert one.vertex_count == two.vertex_count > 0
    for name in ("positions", "normals", "uv", "triangles", "sector_level", "face", "morph"):
        assert bytes(getattr(one, name)) == bytes(getattr(two, name)), name
    ids = incremental.sector_ids().tolist()
    assert ids != sorted(ids) or len(ids) < 3  # depth-first, not numeric order
    assert incremental.instances()["corners"].tolist() == fresh.instances()["corners"].tolist()


def test_deterministic_with_heightmap(planetlod, earth):
    a = surface_camera(planetlod, EARTH_R, 3000.0, lat=0.5, lon=1.4)
    b = surface_camera(planetlod, EARTH_R, 3e5, lat=0.2, lon=1.0)
    earth.reset()
    earth.refine(a)
    want = sorted_ids(earth)
    earth.refine(b)
    earth.refine(a)
    assert sorted_ids(earth) == want
    # after splits and merges, every leaf's cached corners (directions,
    # heights, canonical points) still equal freshly computed ones
    assert earth.check_invariants()


def test_cached_corners_survive_merges_on_every_projection(planetlod):
    near = surface_camera(planetlod, EARTH_R, 2e3, lat=0.3, lon=0.7)
    far = space_camera(planetlod, 3e7)
    for projection in ("qsc", "csc", "car"):
        p = planetlod.Planet(EARTH_R, projection=projection)
        counts = []
        for cam in (near, far, near):
            s = p.refine(cam, criterion="side_distance", max_level=24)
            counts.append(s["sectors_total"])
            assert p.check_invariants()
        assert s["merges"] == 0 and s["splits"] > 0  # split again after merging
        assert counts[0] == counts[2] > counts[1]


def test_reserve_keeps_results_and_capacity(planetlod):
    """reserve() allocates ahead without changing what refine() computes;
    it never shrinks, survives reset() and mid-flight growth past it, and
    refuses a size beyond its cap without changing anything."""
    near = surface_camera(planetlod, EARTH_R, 2e3, lat=0.3, lon=0.7)
    far = space_camera(planetlod, 3e7)
    plain = planetlod.Planet(EARTH_R)
    plain.reserve(0)  # nothing to grow, no split queue yet (UBSan in tools/sanitize.sh)
    reserved = planetlod.Planet(EARTH_R)
    before = reserved.memory_bytes
    reserved.reserve(4096)
    grown = reserved.memory_bytes
    assert grown > before + 4096 * 48
    reserved.reserve(100)  # below the capacity: nothing changes
    assert reserved.memory_bytes == grown
    for cam in (near, far, near):
        a = plain.refine(cam, max_level=30)
        b = reserved.refine(cam, max_level=30)
        assert sorted_ids(plain) == sorted_ids(reserved)
        assert (a["splits"], a["merges"]) == (b["splits"], b["merges"])
        assert reserved.check_invariants()
    assert a["sectors_total"] < 4096 and reserved.memory_bytes == grown  # no growth
    reserved.reset()
    assert reserved.memory_bytes == grown and reserved.sector_count == 12
    small = planetlod.Planet(EARTH_R)
    small.reserve(200)
    deep = surface_camera(planetlod, EARTH_R, 3.0, lat=0.3, lon=0.7)
    for planet in (small, plain):
        s = planet.refine(deep, criterion="side_distance", max_level=48)
    assert s["sectors_total"] > 200  # grew past the reservation mid-refine
    assert sorted_ids(plain) == sorted_ids(small) and small.check_invariants()
    small.reserve(16)  # fewer than it holds: nothing changes
    assert sorted_ids(plain) == sorted_ids(small)
    held = small.memory_bytes
    for bad in (-1, 2 ** 27):
        with pytest.raises(planetlod.PlanetLODError):
            small.reserve(bad)
    with pytest.raises(TypeError):
        small.reserve("many")
    assert sorted_ids(plain) == sorted_ids(small) and small.memory_bytes == held


def test_threads_identical(planetlod, earth):
    """threads=2 evaluates the per-frame predicates in parallel: same sectors,
    same flags (budget ranking included) as one thread, frame after frame."""
    cams = [surface_camera(planetlod, EARTH_R, alt, lat=0.5, lon=1.4) for alt in (3e5, 300.0, 5.0, 2e4)]
    one = planetlod.Planet(EARTH_R, projection="qsc", heightmap=earth.heightmap,
                           height_scale=8848.0, sea_level=0.0)
    two = planetlod.Planet(EARTH_R, projection="qsc", heightmap=earth.heightmap,
                           height_scale=8848.0, sea_level=0.0)
    parallel = 0
    for budget in (0, 3000, 300):  # 3000: coarsened, still threaded (>= 2048 sectors)
        for cam in cams:
            s1 = one.refine(cam, budget=budget, max_pixel_error=0.5)
            s2 = two.refine(cam, budget=budget, max_pixel_error=0.5, threads=2)
            assert s1["sectors_total"] > 12
            parallel += s1["sectors_total"] >= 2048  # large: the threaded path runs
            for key in ("sectors_total", "sectors_after_frustum", "sectors_after_budget",
                        "splits", "merges"):
                assert s1[key] == s2[key]
            assert one.sector_ids(visible_only=False).tolist() == \
                two.sector_ids(visible_only=False).tolist()
            assert one.sector_flags(visible_only=False).tolist() == \
                two.sector_flags(visible_only=False).tolist()
    assert parallel >= 4
    assert two.check_invariants()
    for bad in (0, 17):
        with pytest.raises(planetlod.InvalidArgument):
            two.refine(cams[0], threads=bad)


def test_refine_workers_follow_thread_count_and_fork(planetlod, earth):
    """A planet keeps its worker threads from one refine to the next and
    starts them again when the count changes: any count gives one thread's
    sectors and flags.  After fork() the child has no workers (threads are
    not copied): it refines alone, to the same result, without waiting for
    them."""
    def planet():
        return planetlod.Planet(EARTH_R, projection="qsc", heightmap=earth.heightmap,
                                height_scale=8848.0, sea_level=0.0)
    cams = [surface_camera(planetlod, EARTH_R, alt, lat=0.5, lon=1.4 + 0.001 * k)
            for k, alt in enumerate((3e5, 2000.0, 300.0, 40.0, 5.0, 300.0, 2e4))]
    one, many = planet(), planet()
    for cam, threads in zip(cams, (2, 3, 2, 1, 16, 2, 2)):
        s1 = one.refine(cam, max_pixel_error=0.5)
        s2 = many.refine(cam, max_pixel_error=0.5, threads=threads)
        assert (s1["sectors_total"], s1["sectors_after_frustum"]) == \
            (s2["sectors_total"], s2["sectors_after_frustum"])
        assert bytes(one.sector_ids(visible_only=False)) == bytes(many.sector_ids(visible_only=False))
        assert bytes(one.sector_flags(visible_only=False)) == \
            bytes(many.sector_flags(visible_only=False))
    assert one.refine(cams[3], max_pixel_error=0.5)["sectors_total"] >= 2048  # threaded
    expected = bytes(one.sector_ids())
    pid = os.fork()
    if pid == 0:  # the child: report through the exit status only
        code = 3
        try:
            signal.alarm(60)
            many.refine(cams[3], max_pixel_error=0.5, threads=2)
            code = 0 if bytes(many.sector_ids()) == expected else 1
        except BaseException:
            code = 2
        os._exit(code)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    many.refine(cams[3], max_pixel_error=0.5, threads=2)  # the parent's workers still serve
    assert bytes(many.sector_ids()) == expected


def test_hysteresis_keeps_history(planetlod):
    near = surface_camera(planetlod, EARTH_R, 100.0)
    far = surface_camera(planetlod, EARTH_R, 400.0)
    p = planetlod.Planet(EARTH_R)
    p.refine(near, criterion="side_distance", hysteresis=True)
    p.refine(far, criterion="side_distance", hysteresis=True)
    q = planetlod.Planet(EARTH_R)
    q.refine(far, criterion="side_distance", hysteresis=True)
    assert p.sector_count > q.sector_count  # kept splits above the merge border
    p.refine(far, criterion="side_distance")  # the deterministic mode forgets
    assert sorted_ids(p) == sorted_ids(q)


def test_depth_48_near_the_surface(planetlod):
    p = planetlod.Planet(EARTH_R)
    cam = surface_camera(planetlod, EARTH_R, 0.5, pitch=-0.5)
    s = p.refine(cam, criterion="side_distance", max_level=48)
    assert s["max_level"] == 48
    levels = np.array(p.sector_levels(visible_only=False).tolist())
    c = corners(p)[levels == 48]
    chords = np.linalg.norm(c[:, 0] - c[:, 2], axis=1) * EARTH_R
    assert chords.max() < 1.0  # sub-metre sectors on an Earth-radius planet
    check_conforming(p)
    # deeper than the cap is refused, up to PLOD_MAX_LEVEL = 52 accepted
    s = p.refine(cam, criterion="side_distance", max_level=52)
    assert s["max_level"] > 48
    with pytest.raises(planetlod.InvalidArgument):
        p.refine(cam, max_level=53)


def test_depth_48_over_terrain(planetlod, earth):
    """Depth >= 48 with the Earth map: the height-range queries of sub-metre
    sectors (far below one texel) still give sound bounds, and the leaves
    under a camera 0.5 m above the local terrain are below a metre."""
    lat, lon = 0.5, 1.4
    d = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    ground = earth.height(*d)
    cam = surface_camera(planetlod, EARTH_R + ground, 0.5, lat=lat, lon=lon, pitch=-0.5)
    s = earth.refine(cam, criterion="side_distance", max_level=48)
    assert s["max_level"] == 48
    levels = np.array(earth.sector_levels(visible_only=False).tolist())
    c = corners(earth)[levels == 48]
    chords = np.linalg.norm(c[:, 0] - c[:, 2], axis=1) * EARTH_R
    assert chords.max() < 1.0
    h = np.array(earth.sector_heights(visible_only=False).tolist()).reshape(-1, 2)[levels == 48]
    # the terrain under the deepest sectors lies inside their height bounds
    for tri, (lo, hi) in zip(c[:50], h[:50]):
        centre = tri.mean(0)
        z = earth.height(*(centre / np.linalg.norm(centre)))
        assert lo <= z <= hi
    check_conforming(earth)
    earth.reset()


def test_subtexel_bounds_follow_the_terrain(planetlod, earth):
    """Below one texel a sector's height bounds shrink around its own corner
    heights: a camera 120 m over high ground (Himalaya) refines to sectors of
    hundreds of metres (inside one 39 km bilinear cell the surface is nearly
    flat), not to max_level (with the touched texels' range only, the camera
    sat inside every prism under it: distance 0, level 48).  The bounds stay
    sound: the terrain at sample points spread over each of the deepest
    sectors (corners, edge midpoints, centre) lies inside them."""
    lat, lon = math.radians(27.9), math.radians(86.9)
    d = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    ground = earth.height(*d)
    assert ground > 5000.0
    cam = surface_camera(planetlod, EARTH_R + ground, 120.0, lat=lat, lon=lon, pitch=-0.2)
    s = earth.refine(cam, max_level=48)
    assert s["max_level"] <= 40, s["max_level"]
    levels = np.array(earth.sector_levels(visible_only=False).tolist())
    deep = levels >= s["max_level"] - 4
    assert deep.sum() > 100
    c = corners(earth)[deep]
    h = np.array(earth.sector_heights(visible_only=False).tolist()).reshape(-1, 2)[deep]
    weights = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [.5, .5, 0], [0, .5, .5], [.5, 0, .5],
                        [1 / 3, 1 / 3, 1 / 3], [.7, .2, .1], [.1, .2, .7]])
    for tri, (lo, hi) in zip(c, h):
        for w in weights:
            p = w @ tri
            z = earth.height(*(p / np.linalg.norm(p)))
            assert lo <= z <= hi, (lo, z, hi)
    check_conforming(earth)
    earth.reset()


def test_car_sector_bounds_are_local_and_sound(planetlod):
    """The CAR quad-sphere bounds a sector's heights through its cap's
    lon/lat box in the map (not the global range): small sectors get tight
    bounds, every sampled height lies inside them, also for sectors at the
    poles and across the +-180 deg seam."""
    planet = planetlod.Planet(EARTH_R, projection="car", heightmap=data_path("earth-topology.png"),
                              height_scale=8848.0, sea_level=0.0, heightmap_size=256)
    lo_all, hi_all = planet.height_range()
    weights = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [.5, .5, 0], [0, .5, .5], [.5, 0, .5],
                        [1 / 3, 1 / 3, 1 / 3], [.7, .2, .1], [.1, .2, .7]])
    for lat, lon, alt in [(27.9, 86.9, 2000.0), (89.0, 10.0, 5e4), (-88.0, 0.0, 5e4),
                          (10.0, 179.99, 3e4), (46.5, 8.0, 120.0)]:
        la, lo_ = math.radians(lat), math.radians(lon)
        d = np.array([math.cos(la) * math.cos(lo_), math.cos(la) * math.sin(lo_), math.sin(la)])
        ground = max(planet.height(*d), 0.0)
        cam = surface_camera(planetlod, EARTH_R + ground, alt, lat=la, lon=lo_, pitch=-0.3)
        s = planet.refine(cam, max_level=48)
        assert s["max_level"] <= 42, (lat, lon, s["max_level"])
        levels = np.array(planet.sector_levels(visible_only=False).tolist())
        c = corners(planet)
        h = np.array(planet.sector_heights(visible_only=False).tolist()).reshape(-1, 2)
        deep = levels >= 12
        assert deep.sum() >= 10, (lat, lon, deep.sum())
        # local: most small sectors' bounds are far narrower than the whole map's
        widths = h[deep, 1] - h[deep, 0]
        assert np.median(widths) < 0.25 * (hi_all - lo_all)
        for tri, (lo, hi) in zip(c[deep][:300], h[deep][:300]):
            for w in weights:
                p = w @ tri
                z = planet.height(*(p / np.linalg.norm(p)))
                assert lo <= z <= hi, (lat, lon, lo, z, hi)
        check_conforming(planet)
        planet.reset()


def worst_pixel_gap(planet, cam, radius, rng, sampled=2000, nearest=1000):
    """The emitted mesh's largest radial gap to the surface, in pixels (1920 px
    over a 36 mm sensor, 50 mm lens) at the gap's distance: triangle points
    (centroid, edge midpoints) of the triangles nearest the camera and of
    triangles sampled over the view."""
    mesh = planet.mesh(template_level=4)
    pos = np.frombuffer(mesh.positions, np.float32).reshape(-1, 3).astype(np.float64)
    pos += np.array(mesh.origin)
    tri = np.frombuffer(mesh.triangles, np.int32).reshape(-1, 3)
    eye = np.array(cam.position)
    near = np.argsort(np.linalg.norm(pos[tri[:, 0]] - eye, axis=1))[:nearest]
    pick = np.concatenate([near, rng.choice(len(tri), size=min(sampled, len(tri)),
                                            replace=False)])
    pixels_per_radian = 1920 / (2 * 18.0 / 50.0)
    weights = np.array([[1 / 3, 1 / 3, 1 / 3], [.5, .5, 0], [0, .5, .5], [.5, 0, .5]])
    worst = 0.0
    for t in pick:
        for p in weights @ pos[tri[t]]:
            r = np.linalg.norm(p)
            gap = abs(r - (radius + planet.height(*(p / r))))
            worst = max(worst, gap * pixels_per_radian / np.linalg.norm(p - eye))
    return worst


def test_mesh_within_pixel_error_below_a_texel(planetlod, earth):
    """Near the ground every sector is smaller than a texel and most lie
    inside one bilinear cell, where the criterion bounds the template's
    interpolation error by the cell's twist (quadratic in the sector's size)
    instead of its relief (linear): the emitted mesh stays within 1 px."""
    lat, lon = math.radians(27.9), math.radians(86.9)
    d = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    ground = earth.height(*d)
    rng = np.random.default_rng(7)
    for altitude in (5.0, 120.0, 3000.0):
        cam = surface_camera(planetlod, EARTH_R + ground, altitude, lat=lat, lon=lon,
                             pitch=-0.2)
        earth.refine(cam, max_pixel_error=1.0, template_level=4)
        worst = worst_pixel_gap(earth, cam, EARTH_R, rng)
        assert worst <= 1.0, (altitude, worst)
    earth.reset()


def test_mesh_within_pixel_error_on_rough_cells(planetlod):
    """A map whose every cell twists hard (random texels of 100 m on a 1 km
    planet, texels of ~200 m), seen from 2 m to 150 m: sectors inside one
    cell, bounded by its twist, sit beside creases bounded by their relief;
    the mesh stays within 1 px (measured ~0.1 px)."""
    n, radius = 8, 1000.0
    rng = np.random.default_rng(11)
    cube = planetlod.CubeMap("qsc", n, 1, "f32")
    for f in range(6):
        cube.set_face(f, rng.random((n, n), dtype=np.float32).tobytes())
    planet = planetlod.Planet(radius, heightmap=cube, height_scale=100.0)
    for altitude, pitch in ((2.0, -0.3), (20.0, -0.5), (150.0, -0.9)):
        cam = surface_camera(planetlod, radius + 100.0, altitude, lat=0.31, lon=0.23,
                             pitch=pitch)
        planet.refine(cam, max_pixel_error=1.0, template_level=4)
        worst = worst_pixel_gap(planet, cam, radius, rng)
        assert worst <= 1.0, (altitude, worst)


def test_pixel_criterion_scales_with_error_and_resolution(planetlod, earth):
    cam = surface_camera(planetlod, EARTH_R, 2000.0, lat=0.5, lon=1.4)
    counts = []
    for err in (4.0, 1.0, 0.25):
        earth.refine(cam, max_pixel_error=err)
        counts.append(earth.sector_count)
    assert counts[0] < counts[1] < counts[2]
    small = surface_camera(planetlod, EARTH_R, 2000.0, lat=0.5, lon=1.4,
                           resolution_x=480, resolution_y=270)
    earth.refine(small)
    assert earth.sector_count < counts[1]
    # a finer template needs fewer sectors for the same error
    earth.refine(cam, template_level=6)
    assert earth.sector_count < counts[1]


def test_stats_consistent(planetlod, earth):
    cam = surface_camera(planetlod, EARTH_R, 5e4, lat=0.5, lon=1.4)
    s = earth.refine(cam, skip_sea=True)
    flags = np.array(earth.sector_flags(visible_only=False).tolist())
    assert s["sectors_total"] == len(flags) == earth.sector_count
    assert s["sectors_after_backface"] == np.sum((flags & 2) == 0)
    assert s["sectors_after_frustum"] == np.sum((flags & 6) == 0)
    assert s["sectors_after_budget"] == np.sum((flags & 1) != 0) == earth.visible_count
    assert s["sectors_after_frustum"] - s["sectors_sea_skipped"] == s["sectors_after_budget"]
    assert (s["sectors_total"] >= s["sectors_after_backface"] >= s["sectors_after_frustum"]
            >= s["sectors_after_budget"])
    assert s["refine_us"] > 0 and s["cull_us"] >= 0
    assert s["max_level"] == max(earth.sector_levels(visible_only=False).tolist())
    # emitted geometry: what planet.mesh() writes for the visible sectors
    assert s["vertices"] == earth.mesh(template_level=4).vertex_count
    assert s["triangles"] == 4 ** 4 * s["sectors_after_budget"]  # default template_level 4
    raw = earth.sectors()
    assert len(raw) == earth.SECTOR_SIZE * earth.sector_count and earth.SECTOR_SIZE <= 64
    assert len(earth.sector_ids()) == earth.visible_count


def test_sea_skipping(planetlod, earth):
    cam = space_camera(planetlod, EARTH_R + 3e5, direction=(-0.72, -0.604, -0.342))  # S Pacific
    s0 = earth.refine(cam, skip_sea=False)
    s1 = earth.refine(cam, skip_sea=True)
    assert s1["sectors_sea_skipped"] > 0
    assert s1["sectors_after_budget"] == s0["sectors_after_budget"] - s1["sectors_sea_skipped"]
    flags = np.array(earth.sector_flags(visible_only=False).tolist())
    h = np.array(earth.sector_heights(visible_only=False).tolist()).reshape(-1, 2)
    sea = (flags & 16) != 0
    assert np.all(h[sea, 1] <= 0.0) and np.all(h[~sea, 1] > 0.0)
    assert not np.any(sea & ((flags & 1) != 0))


def test_budget_coarsens_instead_of_dropping(planetlod, earth):
    """Over the budget the whole view gets coarser (the threshold rises in steps
    of sqrt 2) instead of losing its farther sectors: nothing in view is
    dropped, all sectors kept fit the budget, and the result depends on the
    camera alone (not on the frames before, nor on the thread count)."""
    cam = surface_camera(planetlod, EARTH_R, 2e3, lat=0.8, lon=0.15)
    p = planetlod.Planet(EARTH_R, heightmap=earth.heightmap, height_scale=8848.0)
    full = p.refine(cam, max_pixel_error=0.5)
    budget = full["sectors_total"] // 5
    s = p.refine(cam, max_pixel_error=0.5, budget=budget)
    print(f"unlimited: {full['sectors_total']} sectors ({full['sectors_after_budget']} "
          f"visible, level {full['max_level']}); budget {budget}: {s['sectors_total']} "
          f"({s['sectors_after_budget']} visible, level {s['max_level']})")
    assert s["sectors_total"] <= budget and s["sectors_after_budget"] <= budget
    assert s["sectors_after_budget"] == s["sectors_after_frustum"] > budget // 4
    flags = np.array(p.sector_flags(visible_only=False).tolist())
    assert not np.any(flags & 8), "a sector was dropped for the budget"
    assert s["max_level"] < full["max_level"]
    check_conforming(p)
    # history-free and thread-identical: from a fresh planet, after other
    # cameras, with two threads
    kept = frame_state(p)
    fresh = planetlod.Planet(EARTH_R, heightmap=earth.heightmap, height_scale=8848.0)
    fresh.refine(surface_camera(planetlod, EARTH_R, 50.0, lat=0.1), budget=budget)
    fresh.refine(surface_camera(planetlod, EARTH_R, 3e6), max_pixel_error=0.5, budget=budget)
    f = fresh.refine(cam, max_pixel_error=0.5, budget=budget, threads=2)
    assert frame_state(fresh) == kept
    assert f["sectors_total"] == s["sectors_total"]
    again = fresh.refine(cam, max_pixel_error=0.5, budget=budget, threads=2)
    assert again["splits"] == again["merges"] == 0
    s = p.refine(cam, max_pixel_error=0.5, budget=0)  # 0 = unlimited
    assert s["sectors_after_budget"] == full["sectors_after_budget"]


def test_progressive_refinement_fills_in_over_bounded_updates(planetlod, earth):
    """With max_splits (the viewport's progressive refresh) a jump to a new
    place splits breadth first, at most max_splits per update, each update
    conforming, 'pending' until done; done, the sectors are the unlimited
    refinement's.  With a budget the count never exceeds it.  Bad values
    are refused."""
    far = surface_camera(planetlod, EARTH_R, 3e6)
    near = surface_camera(planetlod, EARTH_R, 2e3, lat=0.8, lon=0.15)
    ref = planetlod.Planet(EARTH_R, heightmap=earth.heightmap, height_scale=8848.0)
    ref.refine(far, max_pixel_error=0.5)
    full = ref.refine(near, max_pixel_error=0.5)
    p = planetlod.Planet(EARTH_R, heightmap=earth.heightmap, height_scale=8848.0)
    p.refine(far, max_pixel_error=0.5)
    limit, updates, levels = 300, 0, []
    while True:
        s = p.refine(near, max_pixel_error=0.5, max_splits=limit)
        updates += 1
        assert s["splits"] <= limit
        check_conforming(p)
        levels.append(s["max_level"])
        if not s["pending"]:
            break
        assert updates < 200
    print(f"{updates} updates of <= {limit} splits; max level per update {levels}")
    assert updates >= 3 and levels == sorted(levels)
    assert not full["pending"]
    assert sorted(p.sector_ids(visible_only=False).tolist()) == \
        sorted(ref.sector_ids(visible_only=False).tolist())
    # breadth first: after the first update the view is uniformly coarse,
    # not finished in one corner and untouched in another
    p.refine(far, max_pixel_error=0.5)
    p.refine(near, max_pixel_error=0.5, max_splits=limit)
    spread = np.array(p.sector_levels(visible_only=True).tolist())
    assert spread.max() - spread.min() <= 4, (spread.min(), spread.max())
    budget = full["sectors_total"] // 4
    for _ in range(100):
        s = p.refine(near, max_pixel_error=0.5, max_splits=limit, budget=budget,
                     hysteresis=True)
        assert s["sectors_total"] <= budget
        check_conforming(p)
        if not s["pending"]:
            break
    assert not s["pending"] and s["sectors_after_budget"] > budget // 4
    with pytest.raises(planetlod.PlanetLODError):
        p.refine(near, max_splits=-1)


def test_progressive_jump_down_with_a_budget_reaches_the_ground(planetlod, earth):
    """The viewport (progressive, hysteresis) settled at 2 km with a budget
    that binds, then a jump to 2 m above the same ground: the refinement
    does not stay crowded by the 2 km view's sectors, it coarsens the whole
    view as a camera-only update does and reaches the same finest level
    under the eye; refreshed again without a move, nothing changes."""
    high = surface_camera(planetlod, EARTH_R, 2e3, lat=0.8, lon=0.15)
    low = surface_camera(planetlod, EARTH_R, 2.0, lat=0.8, lon=0.15)
    ref = planetlod.Planet(EARTH_R, heightmap=earth.heightmap, height_scale=8848.0)
    budget = ref.refine(low, max_pixel_error=0.5)["sectors_total"] // 4
    alone = ref.refine(low, max_pixel_error=0.5, budget=budget)
    p = planetlod.Planet(EARTH_R, heightmap=earth.heightmap, height_scale=8848.0)
    for cam in (high, low):
        for _ in range(200):
            s = p.refine(cam, max_pixel_error=0.5, max_splits=300, budget=budget,
                         hysteresis=True)
            assert s["sectors_total"] <= budget
            if not s["pending"]:
                break
        assert not s["pending"]
        check_conforming(p)
    print(f"budget {budget}: camera alone level {alone['max_level']}, "
          f"after the jump level {s['max_level']}")
    assert s["max_level"] >= alone["max_level"]
    again = p.refine(low, max_pixel_error=0.5, max_splits=300, budget=budget, hysteresis=True)
    assert again["splits"] == again["merges"] == 0


def test_budget_below_the_base_mesh_keeps_the_nearest(planetlod):
    """A budget that even the coarsest refinement exceeds keeps the nearest
    visible sectors (the only case where sectors in view are left out)."""
    p = planetlod.Planet(EARTH_R)
    cam = surface_camera(planetlod, EARTH_R, 50.0)
    full = p.refine(cam, criterion="side_distance")
    s = p.refine(cam, criterion="side_distance", budget=3)
    assert s["sectors_after_budget"] == p.visible_count == 3
    flags = np.array(p.sector_flags(visible_only=False).tolist())
    assert np.sum((flags & 8) != 0) == s["sectors_after_frustum"] - 3
    eye = np.array(cam.position)
    c = corners(p)
    dist = np.linalg.norm(c.mean(1) * EARTH_R - eye, axis=1)
    kept, dropped = dist[(flags & 1) != 0], dist[(flags & 8) != 0]
    assert np.max(kept) <= np.min(dropped) + 1e-6 * EARTH_R
    assert full["sectors_after_budget"] > 3


def test_max_sectors_caps_memory(planetlod):
    p = planetlod.Planet(EARTH_R)
    s = p.refine(surface_camera(planetlod, EARTH_R, 1.0), criterion="side_distance",
                 split_border=0.01, merge_border=0.005, max_sectors=5000)
    assert s["truncated"] and p.sector_count <= 5000
    check_conforming(p)


def test_truncated_refine_leaves_every_sector_complete(planetlod):
    """A refine that max_sectors stops part-way (splits whose children's
    bounds were still to be computed) leaves a whole tree: every sector has
    its bound and height range, the links and invariants hold, any thread
    count stops at the same sectors, and the next refine carries on from
    there."""
    def planet():
        return planetlod.Planet(EARTH_R, heightmap=data_path("earth-topology.png"),
                                heightmap_size=256, height_scale=8848.0, sea_level=0.0,
                                detail=dict(amplitude=60.0, style="mountains"))
    cam = surface_camera(planetlod, EARTH_R, 4000.0, lat=0.8, lon=0.15)  # over the Alps
    results = []
    for threads in (1, 2):
        p = planet()
        s = p.refine(cam, max_sectors=1200, threads=threads)
        assert s["truncated"] and 1000 < p.sector_count <= 1200
        assert p.check_invariants()
        check_conforming(p)
        heights = np.array(p.sector_heights(visible_only=False).tolist()).reshape(-1, 2)
        assert np.all(np.isfinite(heights)) and np.all(heights[:, 0] <= heights[:, 1])
        assert np.all(heights[:, 1] > -500.0) and np.all(heights[:, 0] < 9500.0)
        assert p.mesh().vertex_count > 0
        results.append((bytes(p.sector_ids(visible_only=False)),
                        bytes(p.sector_flags(visible_only=False)), bytes(heights)))
        full = p.refine(cam, threads=threads)
        assert not full["truncated"] and full["sectors_total"] > 1200
        assert p.check_invariants()
        fresh = planet()
        fresh.refine(cam)
        assert sorted_ids(p) == sorted_ids(fresh)
    assert results[0] == results[1]


def test_recommended_clip(planetlod, earth):
    for alt in (2.0, 1e3, 1e6):
        cam = surface_camera(planetlod, EARTH_R, alt)
        near, far = planetlod.Planet(EARTH_R).recommended_clip(cam)
        assert 0 < near <= alt
        assert far >= math.sqrt(2 * EARTH_R * alt + alt * alt)
        assert far < 1.1 * math.sqrt(2 * EARTH_R * alt + alt * alt) + 10
        # terrain: mountains beyond the horizon extend the far clip
        near2, far2 = earth.recommended_clip(cam)
        assert far2 > far and near2 <= near


def test_recommended_clip_of_a_camera_near_float_limits(planetlod):
    """Fuzz finding: at 1e200 m the squared distance overflowed, and an
    infinite clearance times a wide view's zero corner factor gave a NaN near
    clip.  Expected: a positive near, and a far beyond it."""
    for coord in (1e200, 1e300):
        for lens in (50.0, 1e-300):
            m = [1, 0, 0, coord, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
            cam = planetlod.Camera(m, lens=lens)
            near, far = planetlod.Planet(EARTH_R).recommended_clip(cam)
            assert near > 0 and not math.isnan(far) and far >= near


def test_camera_below_surface_and_orthographic(planetlod):
    p = planetlod.Planet(EARTH_R)
    cam = surface_camera(planetlod, EARTH_R, -100.0)
    s = p.refine(cam, criterion="side_distance")
    assert s["sectors_total"] > 12
    check_conforming(p)
    ortho = surface_camera(planetlod, EARTH_R, 1000.0, type="ORTHO", ortho_scale=5000.0)
    s = p.refine(ortho)
    assert s["sectors_after_budget"] > 0
    check_conforming(p)


def test_bad_planets(planetlod):
    for radius in (0.0, -1.0, 0.5, 1e9, float("nan"), float("inf")):
        with pytest.raises(planetlod.InvalidArgument):
            planetlod.Planet(radius)
    with pytest.raises(planetlod.InvalidArgument):
        planetlod.Planet(1000.0, projection="mercator")
    with pytest.raises(planetlod.InvalidArgument):
        planetlod.Planet(1000.0, sea_level=float("nan"))
    with pytest.raises(planetlod.InvalidArgument):
        planetlod.Planet(1000.0, height_scale=float("inf"))
    with pytest.raises(TypeError):
        planetlod.Planet(1000.0, heightmap=42)


def test_bad_refine_arguments(planetlod):
    p = planetlod.Planet(1000.0)
    cam = space_camera(planetlod, 5000.0)
    for kw in (dict(criterion="nope"), dict(max_pixel_error=0.0), dict(template_level=8),
               dict(max_level=-1), dict(budget=-1), dict(split_border=0.2, merge_border=0.3),
               dict(max_sectors=3), dict(max_pixel_error=float("nan"))):
        with pytest.raises(planetlod.InvalidArgument):
            p.refine(cam, **kw)
    with pytest.raises(TypeError):
        p.refine("camera")
    centre = planetlod.Camera(look_at((0, 0, 0), (1, 0, 0)))
    with pytest.raises(planetlod.InvalidArgument):
        p.refine(centre)
    assert p.sector_count >= 12  # still usable
    p.refine(cam)


def test_bad_cameras(planetlod):
    good = look_at((10, 0, 0), (0, 0, 0))
    planetlod.Camera(good)
    flat = [x for row in good for x in row]
    planetlod.Camera(flat)  # 16 floats
    nan = [row[:] for row in good]
    nan[0][3] = float("nan")
    singular = [row[:] for row in good]
    singular[0][0] = singular[1][0] = singular[2][0] = 0.0
    cases = [dict(matrix_world=nan), dict(matrix_world=singular),
             dict(matrix_world=[[1, 2, 3]]), dict(matrix_world=[1.0] * 15),
             dict(matrix_world=good, lens=0.0), dict(matrix_world=good, resolution_x=0),
             dict(matrix_world=good, resolution_y=-5), dict(matrix_world=good, clip_start=10.0, clip_end=1.0),
             dict(matrix_world=good, type="ORTHO", ortho_scale=0.0),
             dict(matrix_world=good, shift_x=float("inf")), dict(matrix_world=good, type="FISHEYE"),
             dict(matrix_world=good, sensor_fit="DIAGONAL"), dict(matrix_world=good, sensor_width=-1.0),
             dict(matrix_world=[["a"] * 4] * 4)]
    for kw in cases:
        with pytest.raises(planetlod.InvalidArgument):
            planetlod.Camera(**kw)


def test_extreme_cameras_give_safe_results(planetlod):
    """Documented safe results instead of errors or unbounded work."""
    p = planetlod.Planet(EARTH_R)
    # so far away that the planet is below a pixel: base sectors, nothing visible
    s = p.refine(planetlod.Camera(look_at((1e30, 0, 0), (0, 0, 0))))
    assert s["sectors_total"] == 12 and s["sectors_after_budget"] == 0
    # a scaled camera object (Blender allows it) is a valid camera
    m = look_at((EARTH_R + 100.0, 0, 0), (0, 0, 0))
    for i in range(3):
        for j in range(3):
            m[i][j] *= 1000.0
    s = p.refine(planetlod.Camera(m))
    assert s["sectors_after_budget"] > 0
    # an absurdly wide view asks for millions of sectors: max_sectors caps it
    wide = surface_camera(planetlod, EARTH_R, 10.0, lens=1e-9)
    s = p.refine(wide, max_sectors=20000)
    assert s["truncated"] and p.sector_count <= 20000
    check_conforming(p)
    # clip/pixel-aspect nonsense is refused when the camera is built
    good = look_at((1e7, 0, 0), (0, 0, 0))
    for kw in (dict(pixel_aspect_x=0.0), dict(pixel_aspect_y=float("nan")),
               dict(clip_start=0.0), dict(clip_end=float("inf"))):
        with pytest.raises(planetlod.InvalidArgument):
            planetlod.Camera(good, **kw)
    # and the planet is still usable
    s = p.refine(surface_camera(planetlod, EARTH_R, 10.0))
    assert not s["truncated"] and s["sectors_after_budget"] > 0
