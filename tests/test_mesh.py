"""Mesh stage through Python: planetlod.Mesh buffers, watertightness after
welding, threads, origin, uv seams, geomorphing, the instanced form, and the
full path Planet.refine() -> Planet.mesh() once the refiner is present.

numpy is used only here, to weld and count edges.
"""
import math

import numpy as np
import pytest

from conftest import data_path
from test_refine import look_at


# ---- hand-made conforming sectors -----------------------------------------

def normalise(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.sqrt(v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1] + v[..., 2] * v[..., 2])[..., None]


def cube_sectors():
    """12 base sectors (two per face on the diagonal p0-p2), CCW from outside."""
    sectors, faces = [], []
    for face in range(6):
        axis, sign = face % 3, (1.0 if face < 3 else -1.0)
        n = np.zeros(3); n[axis] = sign
        u = np.zeros(3); u[(axis + 1) % 3] = 1.0
        v = np.cross(n, u)
        p = [normalise(n + su * u + sv * v) for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        sectors += [[p[0], p[1], p[2]], [p[2], p[3], p[0]]]
        faces += [face, face]
    return np.array(sectors), np.array(faces), np.zeros(len(faces))


def bisect_all(sectors, faces, levels):
    """Uniform longest-edge bisection (edge 0-2), children CCW, apex at 1."""
    c0, c1, c2 = sectors[:, 0], sectors[:, 1], sectors[:, 2]
    m = normalise(c0 + c2)
    left = np.stack([c1, m, c0], axis=1)
    right = np.stack([c2, m, c1], axis=1)
    return (np.concatenate([left, right]), np.concatenate([faces, faces]),
            np.concatenate([levels + 1, levels + 1]))


def uniform_sectors(bisections):
    s, f, l = cube_sectors()
    for _ in range(bisections):
        s, f, l = bisect_all(s, f, l)
    return s, f, l


def emit(planetlod, sectors, faces=None, levels=None, **kw):
    return planetlod._mesh_from_corners(
        sectors.reshape(-1).tolist(), kw.pop("radius", 1000.0),
        levels=None if levels is None else levels.tolist(),
        faces=None if faces is None else faces.tolist(), **kw)


def arrays(mesh):
    return (np.frombuffer(mesh.positions, dtype=np.float32).reshape(-1, 3),
            np.frombuffer(mesh.triangles, dtype=np.int32).reshape(-1, 3))


def edge_report(positions, triangles):
    """(boundary edges, non-manifold edges, flipped edges, euler) after welding
    equal float32 positions."""
    _, remap = np.unique(positions, axis=0, return_inverse=True)
    remap = remap.reshape(-1)
    tri = remap[triangles]
    assert np.all(tri[:, 0] != tri[:, 1]) and np.all(tri[:, 1] != tri[:, 2]) \
        and np.all(tri[:, 2] != tri[:, 0]), "degenerate triangle after welding"
    directed = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    undirected = np.sort(directed, axis=1)
    _, counts = np.unique(undirected, axis=0, return_counts=True)
    _, dcounts = np.unique(directed, axis=0, return_counts=True)
    boundary = int(np.sum(counts == 1))
    nonmanifold = int(np.sum(counts > 2))
    flipped = int(np.sum(dcounts > 1))
    euler = remap.max() + 1 - len(counts) + len(tri)
    return boundary, nonmanifold, flipped, int(euler)


@pytest.fixture(scope="module")
def moon(planetlod):
    return planetlod.CubeMap.from_image(data_path("lunar_bumpmap.jpg"), projection="qsc",
                                        size=64)


# ---- Mesh object ------------------------------------------------------------

def test_mesh_buffers_and_counts(planetlod):
    s, f, l = uniform_sectors(1)
    mesh = emit(planetlod, s, f, l, template_level=3, radius=500.0)
    assert isinstance(mesh, planetlod.Mesh)
    S, V, T = 24, 45, 64
    assert (mesh.vertex_count, mesh.triangle_count, mesh.sector_count) == (S * V, S * T, S)
    for name, fmt, per in (("positions", "f", 3 * V), ("normals", "f", 3 * V),
                           ("uv", "f", 2 * V), ("morph", "f", V), ("triangles", "i", 3 * T),
                           ("sector_level", "i", T), ("face", "i", T)):
        buf = getattr(mesh, name)
        assert isinstance(buf, planetlod.Buffer)
        assert buf.format == fmt and len(buf) == S * per, name
    assert mesh.origin == (0.0, 0.0, 0.0)
    p, t = arrays(mesh)
    assert np.allclose(np.linalg.norm(p, axis=1), 500.0, rtol=1e-6)
    assert t.min() == 0 and t.max() == mesh.vertex_count - 1
    assert np.array_equal(np.frombuffer(mesh.face, np.int32), np.repeat(f, T))
    assert np.array_equal(np.frombuffer(mesh.sector_level, np.int32), np.repeat(l, T))
    # CCW seen from outside: the triangle normal points away from the centre
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    assert np.all(np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c) > 0)
    assert not np.any(np.frombuffer(mesh.morph, np.float32))


def test_template_counts(planetlod):
    s, _, _ = cube_sectors()
    for level in range(planetlod.MAX_TEMPLATE_LEVEL + 1):
        n = 2 ** level
        mesh = emit(planetlod, s[:1], template_level=level)
        assert mesh.triangle_count == 4 ** level
        assert mesh.vertex_count == (n + 1) * (n + 2) // 2


@pytest.mark.parametrize("bisections", [0, 1, 3])
@pytest.mark.parametrize("template_level", [0, 1, 2, 3, 4])
def test_watertight_uniform_with_heights(planetlod, moon, bisections, template_level):
    s, f, l = uniform_sectors(bisections)
    mesh = emit(planetlod, s, f, l, template_level=template_level, radius=1737.4e3,
                heightmap=moon, height_scale=20e3, threads=2,
                origin=[0.0, 0.0, 1737.4e3])
    assert edge_report(*arrays(mesh)) == (0, 0, 0, 2)


def test_shared_vertices_share_normals(planetlod, moon):
    s, f, l = uniform_sectors(2)
    mesh = emit(planetlod, s, f, l, template_level=3, radius=1737.4e3, heightmap=moon,
                height_scale=20e3)
    p, _ = arrays(mesh)
    n = np.frombuffer(mesh.normals, np.float32).reshape(-1, 3)
    _, first, remap = np.unique(p, axis=0, return_index=True, return_inverse=True)
    assert np.array_equal(n, n[first[remap.reshape(-1)]])
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)
    # relief tilts normals away from the radial direction, but not past 90 degrees
    radial = p / np.linalg.norm(p, axis=1)[:, None]
    cos = np.einsum("ij,ij->i", n, radial)
    assert cos.min() > 0.5 and cos.min() < 0.99999


def test_threads_bit_identical(planetlod, moon):
    s, f, l = uniform_sectors(4)
    kw = dict(template_level=3, radius=1737.4e3, heightmap=moon, height_scale=20e3,
              eye=[0.0, 1737.4e3 + 3000.0, 0.0], morph_lod_scale=3e5,
              origin=[0.0, 1737.4e3, 0.0])
    one = emit(planetlod, s, f, l, threads=1, **kw)
    assert np.any(np.frombuffer(one.morph, np.float32) > 0)
    for threads in (2, 3, 8):
        other = emit(planetlod, s, f, l, threads=threads, **kw)
        for name in ("positions", "normals", "uv", "morph", "triangles", "sector_level", "face"):
            assert bytes(getattr(one, name)) == bytes(getattr(other, name)), (threads, name)


def test_origin_precision(planetlod):
    """Near the origin the float32 positions keep millimetres on an Earth."""
    radius = 6371e3
    s, f, l = uniform_sectors(0)
    eye_dir = normalise(s[0].mean(axis=0))
    origin = (eye_dir * radius).tolist()
    base = emit(planetlod, s[:1], template_level=7, radius=radius, threads=1)
    rel = emit(planetlod, s[:1], template_level=7, radius=radius, threads=1, origin=origin)
    p_abs = np.frombuffer(base.positions, np.float32).reshape(-1, 3).astype(np.float64)
    p_rel = np.frombuffer(rel.positions, np.float32).reshape(-1, 3).astype(np.float64)
    assert rel.origin == tuple(origin)
    assert np.allclose(p_rel + origin, p_abs, rtol=0, atol=1.0)
    near = np.linalg.norm(p_rel, axis=1) < 2e5
    assert near.sum() > 10
    # exact double positions of the near vertices are on the sphere
    assert np.allclose(np.linalg.norm(p_rel[near] + origin, axis=1), radius, rtol=0, atol=0.05)
    # without the origin the same vertices are off by float32 steps of 0.5 m
    assert np.abs(np.linalg.norm(p_abs[near], axis=1) - radius).max() > 0.05


def test_uv_unwrapped_per_sector(planetlod):
    s, f, l = uniform_sectors(3)
    mesh = emit(planetlod, s, f, l, template_level=3)
    uv = np.frombuffer(mesh.uv, np.float32).reshape(-1, 2)
    p, t = arrays(mesh)
    u = uv[:, 0][t]
    assert (u.max(axis=1) - u.min(axis=1)).max() < 0.25
    assert uv[:, 1].min() >= 0.0 and uv[:, 1].max() <= 1.0
    d = p / np.linalg.norm(p, axis=1)[:, None]
    lat = np.arcsin(np.clip(d[:, 2], -1, 1))
    assert np.allclose(uv[:, 1], lat / math.pi + 0.5, atol=1e-6)
    lon = (uv[:, 0] - 0.5) * 2 * math.pi
    off_pole = np.hypot(d[:, 0], d[:, 1]) > 1e-6
    # same direction as the vertex, modulo the unwrapping by whole turns
    assert np.allclose(np.cos(lon[off_pole]), d[off_pole, 0] / np.cos(lat[off_pole]), atol=1e-5)
    assert np.allclose(np.sin(lon[off_pole]), d[off_pole, 1] / np.cos(lat[off_pole]), atol=1e-5)


def test_morph_watertight_and_bounded(planetlod, moon):
    s, f, l = uniform_sectors(3)
    radius = 1737.4e3
    eye = normalise(s[5].mean(axis=0)) * (radius + 50e3)
    for tl in (1, 2, 4):
        mesh = emit(planetlod, s, f, l, template_level=tl, radius=radius, heightmap=moon,
                    height_scale=20e3, eye=eye.tolist(), morph_lod_scale=2e6, threads=2,
                    origin=(eye * radius / (radius + 50e3)).tolist())
        m = np.frombuffer(mesh.morph, np.float32)
        assert m.min() >= 0.0 and m.max() <= 1.0 and (m > 0).sum() > 0
        assert edge_report(*arrays(mesh)) == (0, 0, 0, 2)


def test_instanced_form_matches_mesh(planetlod):
    s, f, l = uniform_sectors(2)
    radius = 1000.0
    inst = emit(planetlod, s, f, l, template_level=3, radius=radius, instances=True)
    mesh = emit(planetlod, s, f, l, template_level=3, radius=radius)
    bary = np.frombuffer(inst["template_barycentrics"], np.float32).reshape(-1, 3)
    tris = np.frombuffer(inst["template_triangles"], np.int32).reshape(-1, 3)
    corners = np.frombuffer(inst["corners"], np.float32).reshape(-1, 3, 3).astype(np.float64)
    assert np.array_equal(np.frombuffer(inst["levels"], np.float32), l.astype(np.float32))
    assert inst["origin"] == (0.0, 0.0, 0.0) and inst["template_level"] == 3
    assert np.allclose(bary.sum(axis=1), 1.0)
    # the GPU path: normalise(w . corners) * radius reproduces the CPU mesh
    dirs = np.einsum("vk,skx->svx", bary, corners)
    gpu = normalise(dirs) * radius
    cpu, ctri = arrays(mesh)
    assert np.allclose(gpu.reshape(-1, 3), cpu, atol=1e-3)
    V = len(bary)
    assert np.array_equal(ctri[:len(tris)], tris)
    assert np.array_equal(ctri[len(tris):2 * len(tris)], tris + V)


def test_bad_input(planetlod):
    s, _, _ = cube_sectors()
    flat = s.reshape(-1).tolist()
    with pytest.raises(planetlod.InvalidArgument):
        planetlod._mesh_from_corners(flat, 1000.0, template_level=8)
    with pytest.raises(planetlod.InvalidArgument):
        planetlod._mesh_from_corners(flat, 1000.0, threads=0)
    with pytest.raises(planetlod.InvalidArgument):
        planetlod._mesh_from_corners(flat[:-1], 1000.0)
    with pytest.raises(planetlod.InvalidArgument):
        planetlod._mesh_from_corners(flat, -1.0)
    bad = list(flat)
    bad[4] = float("nan")
    with pytest.raises(planetlod.InvalidArgument):
        planetlod._mesh_from_corners(bad, 1000.0)
    with pytest.raises(planetlod.InvalidArgument):
        planetlod._mesh_from_corners(flat, 1000.0, eye=[0.0, 0.0])
    empty = planetlod._mesh_from_corners([], 1000.0)
    assert empty.vertex_count == 0 and len(empty.positions) == 0


# ---- the real refiner --------------------------------------------------------

def refiner_available(planetlod):
    if not hasattr(planetlod, "Planet") or not hasattr(planetlod, "Camera"):
        pytest.skip("refine stage not merged")
    if not hasattr(planetlod.Planet, "mesh"):
        pytest.skip("Planet.mesh not wired")


@pytest.mark.parametrize("projection", ["qsc", "car"])
def test_refined_planet_watertight(planetlod, projection):
    refiner_available(planetlod)
    radius = 1000.0
    planet = planetlod.Planet(radius, projection=projection)
    cam = planetlod.Camera(look_at((radius * 1.02, radius * 0.3, radius * 0.2), (0, 0, 0)))
    planet.refine(cam, backface=False, frustum=False, max_level=14)
    levels = np.frombuffer(planet.sector_levels(visible_only=True), np.int32)
    assert levels.max() - levels.min() >= 3, "expected an adaptive LOD"
    for tl in range(5):
        mesh = planet.mesh(template_level=tl)
        assert mesh.sector_count == planet.visible_count
        assert edge_report(*arrays(mesh)) == (0, 0, 0, 2), (projection, tl)


def test_refined_planet_with_heights_and_morph(planetlod, moon):
    refiner_available(planetlod)
    radius = 1737.4e3
    planet = planetlod.Planet(radius, heightmap=moon, height_scale=10e3)
    eye = (radius + 30e3, 0.0, 0.0)
    cam = planetlod.Camera(look_at(eye, (0, 0, 0)))
    planet.refine(cam, backface=False, frustum=False, max_level=20)
    plain = planet.mesh(template_level=3, threads=1)
    morphed = planet.mesh(template_level=3, morph=True, threads=2)
    assert edge_report(*arrays(plain)) == (0, 0, 0, 2)
    assert edge_report(*arrays(morphed)) == (0, 0, 0, 2)
    assert np.frombuffer(morphed.morph, np.float32).max() > 0
    origin = np.array(plain.origin)
    assert abs(np.linalg.norm(origin) - (radius + planet.height(1.0, 0.0, 0.0))) < 1e-6
    assert origin[1] == 0.0 and origin[2] == 0.0
    inst = planet.instances(template_level=3)
    assert len(inst["corners"]) == 9 * planet.visible_count


# ---- normal maps ------------------------------------------------------------

def analytic_map(planetlod, projection, size):
    """f32 map of h = x (the direction's x) at every texel centre."""
    cube = planetlod.CubeMap(projection=projection, size=size, channels=1, dtype="f32")
    width, height = cube.face_shape
    i, j = np.meshgrid((np.arange(width) + 0.5) * 2 / width - 1,
                       (np.arange(height) + 0.5) * 2 / height - 1)
    for face in range(cube.face_count):
        if cube.face_count == 1:  # CAR: lon/lat grid
            lon, lat = i * np.pi, j * np.pi / 2
            x = np.cos(lat) * np.cos(lon)
        else:
            d = np.frombuffer(planetlod.faces_to_dirs(
                projection, [face] * i.size, i.reshape(-1).tolist(), j.reshape(-1).tolist()),
                np.float64).reshape(-1, 3)
            x = d[:, 0].reshape(i.shape)
        cube.set_face(face, x.astype(np.float32).tobytes())
    return cube


@pytest.mark.parametrize("projection", ["qsc", "tsc", "car"])
def test_normal_map_matches_the_analytic_normal(planetlod, projection):
    """Heights h = H x: the surface normal is r d - H (e_x - x d) normalised.
    Normal-map normals (one sample per vertex) and the difference normals
    (four extra heights) both follow it; they agree with each other."""
    radius, H = 1000.0, 50.0
    cube = analytic_map(planetlod, projection, 96)
    if projection == "car":
        planet = planetlod.Planet(radius, projection="car", heightmap=cube, height_scale=H)
        camera = planetlod.Camera([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 3 * radius,
                                   0, 0, 0, 1])
        planet.refine(camera, backface=False, frustum=False, max_pixel_error=50)
        mesh = planet.mesh(template_level=3)
        positions = np.frombuffer(mesh.positions, np.float32).reshape(-1, 3) + mesh.origin
        normals = {"map": np.frombuffer(mesh.normals, np.float32).reshape(-1, 3)}
    else:
        s, f, l = uniform_sectors(3)
        normals = {}
        for use_map in (True, False):
            mesh = emit(planetlod, s, f, l, template_level=3, radius=radius, heightmap=cube,
                        height_scale=H, projection=projection, normal_map=use_map)
            positions = np.frombuffer(mesh.positions, np.float32).reshape(-1, 3).astype(np.float64)
            normals["map" if use_map else "differences"] = \
                np.frombuffer(mesh.normals, np.float32).reshape(-1, 3)
    r = np.linalg.norm(positions, axis=1)
    d = positions / r[:, None]
    exact = r[:, None] * d - H * (np.array([1.0, 0.0, 0.0]) - d[:, :1] * d)
    exact /= np.linalg.norm(exact, axis=1)[:, None]
    tilt = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", exact, d), -1, 1)))
    assert tilt.max() > 2.0  # the relief does tilt the normals
    worst = {}
    for name, n in normals.items():
        error = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", n, exact), -1, 1)))
        assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6), name
        worst[name] = error.max()
    # central differences over ~1 degree texels: within a tenth of a texel
    # (measured: map 0.11 (qsc) / 0.14 (tsc) degrees, differences 0.18)
    assert max(worst.values()) < 0.25, worst


def test_normal_map_is_seamless_across_face_edges(planetlod, moon):
    """Normals just either side of every cube edge agree (the map's texels
    next to an edge difference across it through the neighbour face)."""
    rng = np.random.default_rng(3)
    s, f, l = uniform_sectors(2)
    mesh = emit(planetlod, s, f, l, template_level=4, radius=1737.4e3, heightmap=moon,
                height_scale=20e3)
    p, _ = arrays(mesh)
    n = np.frombuffer(mesh.normals, np.float32).reshape(-1, 3)
    d = p / np.linalg.norm(p, axis=1)[:, None]
    on_edge = np.sort(np.abs(d), axis=1)[:, 1] / np.sort(np.abs(d), axis=1)[:, 2] > 1 - 1e-6
    assert on_edge.sum() > 100
    # neighbours of edge vertices in the welded mesh lie on both faces; their
    # normals turn smoothly: no jump larger than between interior neighbours
    _, remap = np.unique(p, axis=0, return_inverse=True)
    tri = remap.reshape(-1)[arrays(mesh)[1]]
    first = np.unique(remap.reshape(-1), return_index=True)[1]
    nw, ew = n[first], on_edge[first]
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    turn = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", nw[edges[:, 0]], nw[edges[:, 1]]), -1, 1)))
    across = ew[edges[:, 0]] != ew[edges[:, 1]]
    assert np.percentile(turn[across], 99) < 2.0 * np.percentile(turn[~across], 99) + 0.5
    del rng


# ---- sector cache -------------------------------------------------------------

MESH_OUTPUTS = ("positions", "normals", "uv", "morph", "triangles", "sector_level", "face")


def test_sector_cache_output_identical_along_a_flight(planetlod, moon):
    """mesh() copies the sectors kept from the previous frame; every output
    must equal an uncached emission, frame after frame, while the camera
    descends and turns (splits, merges, a moving origin) and with morph, on
    any number of threads (the refiner's persistent workers when it has
    them, else the planet's own)."""
    refiner_available(planetlod)
    radius = 1737.4e3
    planet = planetlod.Planet(radius, heightmap=moon, height_scale=10e3)
    hits = 0
    for k in range(12):
        alt = 200e3 * 0.6 ** k
        a = 0.02 * k
        eye = (radius + 10e3 + alt, 0.1 * radius * math.sin(a), 0.0)
        target = (radius * math.cos(a + 0.05), radius * math.sin(a + 0.05), 0.0)
        planet.refine(planetlod.Camera(look_at(eye, target), clip_start=1.0, clip_end=1e8),
                      max_level=22, threads=1 + k % 2)
        for morph, threads in ((False, 1), (True, 2), (False, 4)):
            cached = planet.mesh(template_level=3, morph=morph, threads=threads)
            info = planet.mesh_cache_info
            plain = planet.mesh(template_level=3, morph=morph, threads=1, cache=False)
            for name in MESH_OUTPUTS:
                assert bytes(getattr(cached, name)) == bytes(getattr(plain, name)), (k, name)
            assert cached.origin == plain.origin
            assert info["sectors"] == cached.sector_count
            assert info["hits"] + info["misses"] == cached.sector_count
            assert info["bytes"] == cached.vertex_count * 48 + cached.sector_count * 12
            hits += info["hits"]
    assert hits > 0


def storage_address(buffer):
    """Address of a planetlod.Buffer's storage (through ctypes: writable)."""
    import ctypes
    view = (ctypes.c_char * memoryview(buffer).nbytes).from_buffer(buffer)
    address = ctypes.addressof(view)
    del view
    return address


def test_mesh_storage_reused_after_a_mesh_is_freed(planetlod, moon):
    """A planet's mesh() takes its buffers' storage from the meshes of that
    planet freed before, instead of new pages the kernel must fault in and
    zero each frame; what it emits there equals an emission into new memory
    (nothing left over from the mesh before shows), and a mesh outlives its
    planet."""
    refiner_available(planetlod)
    radius = 1737.4e3

    def camera(alt):
        eye = (radius + alt, 0.0, 0.0)
        return planetlod.Camera(look_at(eye, (radius, 5.0 * alt, 0.0)), clip_start=1.0,
                                clip_end=1e8)

    planet = planetlod.Planet(radius, heightmap=moon, height_scale=10e3)
    planet.refine(camera(30e3), max_level=22)
    first = planet.mesh(template_level=4, cache=False)
    assert first.vertex_count * 12 >= 1 << 16  # large enough to be pooled
    addresses = {storage_address(getattr(first, name)) for name in MESH_OUTPUTS}
    del first
    planet.refine(camera(33e3), max_level=22)
    again = planet.mesh(template_level=4, cache=False)
    reused = {storage_address(getattr(again, name)) for name in MESH_OUTPUTS} & addresses
    assert storage_address(again.positions) in reused
    fresh = planetlod.Planet(radius, heightmap=moon, height_scale=10e3)
    fresh.refine(camera(33e3), max_level=22)
    plain = fresh.mesh(template_level=4, cache=False)
    assert again.vertex_count == plain.vertex_count
    for name in MESH_OUTPUTS + ("detail", "sector_ids"):
        assert bytes(getattr(again, name)) == bytes(getattr(plain, name)), name
    del planet, fresh
    assert bytes(again.positions) == bytes(plain.positions)
    del again, plain


def test_sector_cache_budget_and_template_change(planetlod, moon):
    refiner_available(planetlod)
    radius = 1737.4e3
    planet = planetlod.Planet(radius, heightmap=moon, height_scale=10e3)
    planet.refine(planetlod.Camera(look_at((radius + 50e3, 0.0, 0.0), (0, 0, 0)),
                                   clip_start=1.0, clip_end=1e8))
    assert planet.mesh_cache_max_bytes == 256 << 20
    first = planet.mesh(template_level=2)
    again = planet.mesh(template_level=2)
    assert planet.mesh_cache_info["hits"] == again.sector_count
    finer = planet.mesh(template_level=3)  # another template: recomputed
    assert planet.mesh_cache_info["hits"] == 0
    assert bytes(finer.positions) == bytes(planet.mesh(template_level=3, cache=False).positions)
    per_sector = finer.vertex_count // finer.sector_count * 48
    planet.mesh_cache_max_bytes = 4 * per_sector  # below what it holds: emptied
    assert planet.mesh_cache_info["sectors"] == 0
    small = planet.mesh(template_level=3)
    info = planet.mesh_cache_info
    assert info["bytes"] <= 4 * per_sector and info["max_bytes"] == 4 * per_sector
    assert bytes(small.positions) == bytes(finer.positions)
    planet.mesh_cache_max_bytes = 0  # off
    planet.mesh(template_level=2)
    assert planet.mesh_cache_info["sectors"] == 0
    assert first.sector_count == again.sector_count
    for bad in (-1, "big", 1.5):
        with pytest.raises((ValueError, TypeError)):
            planet.mesh_cache_max_bytes = bad
    assert planet.mesh_cache_max_bytes == 0
    with pytest.raises((AttributeError, TypeError)):
        del planet.mesh_cache_max_bytes


def typed_map(planetlod, projection, dtype, size=32):
    """A random map of one texel type (u8, u16 or f32), one channel."""
    cube = planetlod.CubeMap(projection=projection, size=size, channels=1, dtype=dtype)
    width, height = cube.face_shape
    rng = np.random.default_rng(5)
    numpy_type = {"u8": np.uint8, "u16": np.uint16, "f32": np.float32}[dtype]
    for face in range(cube.face_count):
        if dtype == "f32":
            texels = rng.random(width * height).astype(np.float32)
        else:
            texels = rng.integers(0, np.iinfo(numpy_type).max, width * height).astype(numpy_type)
        cube.set_face(face, texels.tobytes())
    return cube


@pytest.mark.parametrize("projection,dtype", [("qsc", "u8"), ("qsc", "u16"), ("csc", "f32"),
                                              ("tsc", "u16"), ("car", "f32")])
def test_mesh_vertices_sample_as_planet_height(planetlod, projection, dtype):
    """Mesh vertices are sampled a row at a time (batched projection and
    bilinear loops per texel type); each must still be bit for bit the
    point path: (float)(dir * (R + height(dir)) - origin)."""
    refiner_available(planetlod)
    radius = 1737.4e3
    planet = planetlod.Planet(radius, projection=projection,
                              heightmap=typed_map(planetlod, projection, dtype), height_scale=10e3)
    planet.refine(planetlod.Camera(look_at((radius * 1.3, radius * 0.4, radius * 0.3), (0, 0, 0)),
                                   clip_start=1.0, clip_end=1e8), max_level=12)
    mesh = planet.mesh(template_level=0, threads=1, cache=False)  # vertices = sector corners
    corners = np.array(planet.sector_corners().tolist()).reshape(-1, 3)
    positions = np.array(mesh.positions.tolist(), np.float32).reshape(-1, 3)
    assert len(corners) == len(positions) > 100
    origin = np.array(mesh.origin)
    for corner, got in zip(corners, positions):
        d = corner * (1.0 / math.sqrt(corner[0] * corner[0] + corner[1] * corner[1] +
                                      corner[2] * corner[2]))
        point = d * (radius + planet.height(*d))
        assert np.array_equal((point - origin).astype(np.float32), got)


def test_surface_batch(planetlod, moon):
    """Planet.surface(): heights bit for bit height(); unit normals that
    tilt with the relief; bad input raises and changes nothing."""
    radius = 1737.4e3
    planet = planetlod.Planet(radius, heightmap=moon, height_scale=10e3)
    rng = np.random.default_rng(3)
    dirs = rng.normal(size=(500, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    # unit as C computes the length: then normalising again changes nothing
    exact = [d for d in dirs if math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) == 1.0]
    assert len(exact) > 100
    heights, normals = planet.surface(np.array(exact).reshape(-1).tolist())
    assert heights.format == "d" and normals.format == "d"
    assert len(heights) == len(exact) and len(normals) == 3 * len(exact)
    assert list(heights) == [planet.height(*d) for d in exact]
    n = np.array(normals.tolist()).reshape(-1, 3)
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    tilt = np.einsum("ij,ij->i", n, np.array(exact))
    assert np.all(tilt > 0.5) and np.any(tilt < 0.9999)
    scaled, _ = planet.surface((np.array(exact[:3]) * 7.5).reshape(-1).tolist())
    assert np.allclose(list(scaled), list(heights)[:3], atol=1e-6)
    for bad in ([1.0, 2.0], [0.0, 0.0, 0.0], [1.0, float("nan"), 0.0], "xyz"):
        with pytest.raises((planetlod.PlanetLODError, TypeError, ValueError)):
            planet.surface(bad)
    h, n = planetlod.Planet(5.0).surface([0.0, 0.0, 2.0])
    assert list(h) == [0.0] and list(n) == [0.0, 0.0, 1.0]
    assert list(planet.surface([])[0]) == []
