"""Cube maps: seamless sampling across edges and corners, the min/max pyramid,
cross/faces layouts and image I/O round trips."""
import os
import random
import struct

import numpy as np
import pytest

# Face frames of the FITS / WCSLIB cube (centre axis, +u axis, +v axis).
X, Y, Z = (1, 0, 0), (0, 1, 0), (0, 0, 1)


def neg(a):
    return tuple(-c for c in a)


FRAMES = {
    0: (Z, Y, neg(X)),
    1: (X, Y, Z),
    2: (Y, neg(X), Z),
    3: (neg(X), neg(Y), Z),
    4: (neg(Y), X, Z),
    5: (neg(Z), Y, X),
}
CUBE = ("tsc", "csc", "qsc")


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def same_point_on_other_faces(face, u, v):
    """(g, u', v') of every other face holding the edge/corner point (face, u, v).

    On an edge the along-edge coordinate is the same (or mirrored) for every
    cube projection by symmetry, so the gnomonic construction, exact in
    integers and +-1 here, gives the partner in every projection."""
    c, au, av = FRAMES[face]
    d = tuple(c[k] + u * au[k] + v * av[k] for k in range(3))
    out = []
    for g, (cg, aug, avg) in FRAMES.items():
        if g != face and dot(d, cg) == 1:
            out.append((g, dot(d, aug), dot(d, avg)))
    return out


def random_cubemap(planetlod, projection, size, dtype="f32", channels=1, seed=1):
    rng = np.random.default_rng(seed)
    cube = planetlod.CubeMap(projection, size, channels, dtype)
    for f in range(cube.face_count):
        w, h = cube.face_shape
        if dtype == "f32":
            data = rng.uniform(0.0, 1.0, w * h * channels).astype(np.float32)
        elif dtype == "u16":
            data = rng.integers(0, 65536, w * h * channels).astype(np.uint16)
        else:
            data = rng.integers(0, 256, w * h * channels).astype(np.uint8)
        cube.set_face(f, data.tobytes())
    return cube


def face_array(cube, f):
    buf = cube.face(f)
    dtype = {"B": np.uint8, "H": np.uint16, "f": np.float32}[buf.format]
    w, h = cube.face_shape
    return np.frombuffer(bytes(memoryview(buf).cast("B")), dtype=dtype).reshape(h, w, cube.channels)


def close(a, b, rel=1e-6):
    return all(abs(x - y) <= rel * max(1.0, abs(x), abs(y)) for x, y in zip(a, b))


def close_rel(a, b, rel=1e-6):
    """Strictly relative (values of 0 must match exactly)."""
    return len(a) == len(b) and all(abs(x - y) <= rel * max(abs(x), abs(y)) for x, y in zip(a, b))


def test_frames_match_projection(planetlod):
    if not hasattr(planetlod, "face_to_dir"):
        pytest.skip("projection stage not merged")
    for projection in CUBE:
        for f, (c, au, av) in FRAMES.items():
            centre = planetlod.face_to_dir(projection, f, 0.0, 0.0)
            assert np.allclose(centre, c, atol=1e-12)
            mid_u = np.array(planetlod.face_to_dir(projection, f, 1.0, 0.0))
            assert np.allclose(mid_u, (np.array(c) + au) / np.sqrt(2), atol=1e-12)
            mid_v = np.array(planetlod.face_to_dir(projection, f, 0.0, 1.0))
            assert np.allclose(mid_v, (np.array(c) + av) / np.sqrt(2), atol=1e-12)


@pytest.mark.parametrize("projection", CUBE)
def test_edges_agree_from_both_faces(planetlod, projection):
    cube = random_cubemap(planetlod, projection, 9, channels=2)
    rng = random.Random(3)
    checked = 0
    for f in range(6):
        for edge in range(4):
            for _ in range(40):
                t = rng.uniform(-1.0, 1.0)
                u, v = [(-1.0, t), (1.0, t), (t, -1.0), (t, 1.0)][edge]
                partners = same_point_on_other_faces(f, u, v)
                assert len(partners) == 1
                g, gu, gv = partners[0]
                a = cube.sample_face(f, u, v)
                b = cube.sample_face(g, gu, gv)
                assert close(a, b), (f, u, v, g, gu, gv, a, b)
                checked += 1
    assert checked == 6 * 4 * 40


@pytest.mark.parametrize("projection", CUBE)
def test_corners_agree_and_average_three_texels(planetlod, projection):
    n = 7
    cube = random_cubemap(planetlod, projection, n, dtype="u16")
    faces = [face_array(cube, f)[:, :, 0] / 65535.0 for f in range(6)]
    for f in range(6):
        for u in (-1.0, 1.0):
            for v in (-1.0, 1.0):
                partners = same_point_on_other_faces(f, u, v)
                assert len(partners) == 2
                value = cube.sample_face(f, u, v)[0]
                corner_texels = []
                for g, gu, gv in [(f, u, v)] + partners:
                    assert close((cube.sample_face(g, gu, gv)[0],), (value,))
                    i = 0 if gu < 0 else n - 1
                    j = 0 if gv < 0 else n - 1
                    corner_texels.append(faces[g][j, i])
                assert value == pytest.approx(np.mean(corner_texels), rel=1e-6)


@pytest.mark.parametrize("projection", CUBE)
def test_sampling_is_continuous_across_edges(planetlod, projection):
    cube = random_cubemap(planetlod, projection, 8)
    rng = random.Random(5)
    eps = 1e-9
    for _ in range(300):
        f = rng.randrange(6)
        edge = rng.randrange(4)
        t = rng.uniform(-1.0, 1.0)
        u, v = [(-1.0, t), (1.0, t), (t, -1.0), (t, 1.0)][edge]
        (g, gu, gv), = same_point_on_other_faces(f, u, v)
        inside_f = (u * (1 - eps), v) if edge < 2 else (u, v * (1 - eps))
        inside_g = (gu * (1 - eps), gv) if abs(gu) == 1.0 else (gu, gv * (1 - eps))
        a = cube.sample_face(f, *inside_f)[0]
        b = cube.sample_face(g, *inside_g)[0]
        # values lie in [0, 1]; the slope is at most ~size per unit of u
        assert abs(a - b) < 1e-6


def test_interior_sample_is_bilinear(planetlod):
    cube = random_cubemap(planetlod, "qsc", 6)
    a = face_array(cube, 2)[:, :, 0].astype(np.float64)
    # point between texel centres (i=1..2, j=3..4) at fractions 0.25, 0.75
    s, t = 1.25, 3.75
    u = (s + 0.5) * 2 / 6 - 1
    v = (t + 0.5) * 2 / 6 - 1
    expect = (a[3, 1] * 0.75 * 0.25 + a[3, 2] * 0.25 * 0.25 + a[4, 1] * 0.75 * 0.75 + a[4, 2] * 0.25 * 0.75)
    assert cube.sample_face(2, u, v)[0] == pytest.approx(expect, rel=1e-6)


@pytest.mark.parametrize("projection", CUBE)
def test_direction_on_edges_and_corners(planetlod, projection):
    if not hasattr(planetlod, "face_to_dir"):
        pytest.skip("projection stage not merged")
    cube = random_cubemap(planetlod, projection, 10)
    rng = random.Random(9)
    for f in range(6):
        for _ in range(30):
            t = rng.choice([rng.uniform(-1, 1), -1.0, 1.0])
            u, v = rng.choice([(-1.0, t), (1.0, t), (t, -1.0), (t, 1.0)])
            d = planetlod.face_to_dir(projection, f, u, v)
            by_dir = cube.sample(*d)[0]
            # CSC's inverse is an approximation (~1e-5): go back through the
            # forward map, which keeps the point exactly on the edge
            f2, u2, v2 = planetlod.dir_to_face(projection, *d)
            assert 1.0 in (abs(u2), abs(v2))
            assert close((by_dir,), cube.sample_face(f2, u2, v2))
            partners = same_point_on_other_faces(f2, u2, v2)
            assert len(partners) == (2 if abs(u2) == abs(v2) == 1.0 else 1)
            for g, gu, gv in partners:
                assert close((by_dir,), cube.sample_face(g, gu, gv))


def test_bad_directions_and_arguments(planetlod):
    cube = planetlod.CubeMap("qsc", 4)
    for bad in [(0.0, 0.0, 0.0), (float("nan"), 0.0, 1.0), (float("inf"), 1.0, 0.0)]:
        with pytest.raises(planetlod.InvalidArgument):
            cube.sample(*bad)
    with pytest.raises(planetlod.InvalidArgument):
        cube.sample_face(6, 0.0, 0.0)
    with pytest.raises(planetlod.InvalidArgument):
        planetlod.CubeMap("mercator", 4)
    with pytest.raises(planetlod.InvalidArgument):
        planetlod.CubeMap("qsc", 0)
    with pytest.raises(planetlod.InvalidArgument):
        planetlod.CubeMap("qsc", 100000)
    with pytest.raises(planetlod.InvalidArgument):
        planetlod.CubeMap("qsc", 4, channels=5)
    with pytest.raises(planetlod.InvalidArgument):
        planetlod.CubeMap("qsc", 4, dtype="f64")
    with pytest.raises(planetlod.InvalidArgument):
        cube.set_face(0, b"\0" * 3)


def footprint_range(faces, f, n, u0, v0, u1, v1):
    """Brute-force min/max of every texel (incl. ghosts via the seam rule) that a
    bilinear tap inside the rectangle can read, from dense sampling of taps."""
    values = []
    i0 = int(np.floor((u0 + 1) * n / 2 - 0.5))
    i1 = int(np.floor((u1 + 1) * n / 2 - 0.5)) + 1
    j0 = int(np.floor((v0 + 1) * n / 2 - 0.5))
    j1 = int(np.floor((v1 + 1) * n / 2 - 0.5)) + 1
    for j in range(j0, j1 + 1):
        for i in range(i0, i1 + 1):
            values.extend(ghost_values(faces, f, n, i, j))
    return min(values), max(values)


def ghost_values(faces, f, n, i, j):
    """Texel values that tap (i, j) of face f (i, j in [-1, n]) depends on."""
    if 0 <= i < n and 0 <= j < n:
        return [faces[f][j, i]]
    # texel centre just beyond the edge, mapped to the neighbour's texel
    u = -1 + (i + 0.5) * 2 / n
    v = -1 + (j + 0.5) * 2 / n
    uc, vc = max(-1.0, min(1.0, u)), max(-1.0, min(1.0, v))
    out = []
    for g, gu, gv in same_point_on_other_faces(f, uc, vc) + [(f, uc, vc)]:
        gi = min(n - 1, max(0, int(np.floor((gu + 1) * n / 2))))
        gj = min(n - 1, max(0, int(np.floor((gv + 1) * n / 2))))
        out.append(faces[g][gj, gi])
    return out


@pytest.mark.parametrize("projection", ["qsc", "tsc"])
def test_range_is_conservative(planetlod, projection):
    n = 16
    cube = random_cubemap(planetlod, projection, n, dtype="u8", seed=4)
    faces = [face_array(cube, f)[:, :, 0] / 255.0 for f in range(6)]
    rng = random.Random(11)
    gmin, gmax = cube.range()
    assert gmin == pytest.approx(min(a.min() for a in faces), rel=1e-12)
    assert gmax == pytest.approx(max(a.max() for a in faces), rel=1e-12)
    for trial in range(150):
        f = rng.randrange(6)
        w = rng.choice([0.02, 0.1, 0.4, 1.2, 2.0])
        u0 = rng.uniform(-1, 1 - min(w, 1.99))
        v0 = rng.uniform(-1, 1 - min(w, 1.99))
        u1, v1 = min(1.0, u0 + w), min(1.0, v0 + w)
        lo, hi = cube.range(f, u0, v0, u1, v1)
        blo, bhi = footprint_range(faces, f, n, u0, v0, u1, v1)
        assert lo <= blo + 1e-12 and hi >= bhi - 1e-12, (trial, f, u0, v0, u1, v1)
        assert gmin <= lo and hi <= gmax
        # dense samples inside the rectangle stay inside the bounds
        for _ in range(20):
            s = cube.sample_face(f, rng.uniform(u0, u1), rng.uniform(v0, v1))[0]
            assert lo - 1e-6 <= s <= hi + 1e-6
    # a tiny interior rectangle is tight: exactly its 2x2 footprint
    u = -1 + (5 + 0.5) * 2 / n + 0.01
    v = -1 + (7 + 0.5) * 2 / n + 0.01
    lo, hi = cube.range(3, u, v, u + 0.001, v + 0.001)
    block = faces[3][7:9, 5:7]
    assert (lo, hi) == pytest.approx((block.min(), block.max()), rel=1e-12)


def test_range_sees_a_spike_across_the_edge(planetlod):
    n = 8
    cube = planetlod.CubeMap("qsc", n, 1, "f32")
    spike = np.zeros((n, n), np.float32)
    spike[3, 0] = 5.0  # face 2, first column (edge u = -1 touches face 1)
    cube.set_face(2, spike.tobytes())
    lo, hi = cube.range(1, 0.99, -0.2, 1.0, 0.2)  # face 1 near its u = +1 edge
    assert hi == 5.0 and lo == 0.0
    lo, hi = cube.range(1, -0.5, -0.2, 0.5, 0.2)
    assert hi == 0.0


def test_cross_round_trip(planetlod, tmp_path):
    cube = random_cubemap(planetlod, "csc", 12, dtype="u16", channels=1, seed=7)
    path = str(tmp_path / "cross.png")
    cube.save(path)
    import OpenImageIO as oiio
    spec = oiio.ImageInput.open(path).spec()
    assert (spec.width, spec.height, spec.nchannels) == (48, 36, 1)
    loaded = planetlod.CubeMap.from_image(path, projection="csc")
    assert (loaded.size, loaded.channels, loaded.dtype, loaded.projection) == (12, 1, "u16", "csc")
    for f in range(6):
        assert np.array_equal(face_array(loaded, f), face_array(cube, f))
    assert loaded.range() == cube.range()


def test_cross_layout_places_faces(planetlod, tmp_path):
    n = 4
    cube = planetlod.CubeMap("qsc", n, 1, "u8")
    for f in range(6):
        data = np.full((n, n), 10 * (f + 1), np.uint8)
        data[n - 1, 0] = 200 + f  # row n-1 = v = +1 (top), column 0 = u = -1 (left)
        cube.set_face(f, data.tobytes())
    path = str(tmp_path / "c.png")
    cube.save(path)
    import OpenImageIO as oiio
    img = oiio.ImageInput.open(path).read_image(format="uint8")[:, :, 0]
    cells = {0: (0, 0), 1: (0, 1), 2: (1, 1), 3: (2, 1), 4: (3, 1), 5: (0, 2)}
    for f, (cx, cy) in cells.items():
        block = img[cy * n:(cy + 1) * n, cx * n:(cx + 1) * n]
        assert block[0, 0] == 200 + f  # top-left of the cell
        assert block[n - 1, n - 1] == 10 * (f + 1)
    assert img[0, n:].max() == 0  # empty cells are zero


def test_faces_layout_and_formats(planetlod, tmp_path):
    import OpenImageIO as oiio
    cube = random_cubemap(planetlod, "qsc", 8, dtype="u8", channels=3, seed=2)
    cube.save(str(tmp_path / "f_{face}.png"), layout="faces")
    for f in range(6):
        img = oiio.ImageInput.open(str(tmp_path / f"f_{f}.png")).read_image(format="uint8")
        assert img.shape == (8, 8, 3)
        assert np.array_equal(img[::-1], face_array(cube, f))
    cube.save(str(tmp_path / "g.tif"), layout="faces", format="rgba8")
    img = oiio.ImageInput.open(str(tmp_path / "g_face5.tif")).read_image(format="uint8")
    assert img.shape == (8, 8, 4) and (img[:, :, 3] == 255).all()
    assert np.array_equal(img[::-1, :, :3], face_array(cube, 5))
    cube.save(str(tmp_path / "h.exr"), format="f32")
    img = oiio.ImageInput.open(str(tmp_path / "h.exr")).read_image(format="float")
    assert img.shape == (24, 32, 3)
    assert np.allclose(img[8:16, 0:8][::-1], face_array(cube, 1) / 255.0, atol=1e-6)
    with pytest.raises(planetlod.InvalidArgument):
        cube.save(str(tmp_path / "x.png"), format="r16")  # colour into one channel
    with pytest.raises(planetlod.InvalidArgument):
        cube.save(str(tmp_path / "x.jpg"), format="f32")  # JPEG cannot hold float
    with pytest.raises(planetlod.InvalidArgument):
        cube.save(str(tmp_path / "x.png"), layout="strip")
    with pytest.raises(planetlod.FileError):
        cube.save(str(tmp_path / "no" / "such" / "dir.png"))


def test_car_cubemap_wraps_and_reflects(planetlod, tmp_path):
    n = 8
    cube = planetlod.CubeMap("car", n, 1, "f32")
    assert cube.face_count == 1 and cube.face_shape == (2 * n, n)
    data = np.arange(2 * n * n, dtype=np.float32).reshape(n, 2 * n)
    cube.set_face(0, data.tobytes())
    # lon = +-180 is the seam between the last and first column
    a = cube.sample_face(0, 1.0, 0.0)[0]
    b = cube.sample_face(0, -1.0, 0.0)[0]
    assert a == pytest.approx(b)
    assert a == pytest.approx((data[n // 2 - 1, 0] + data[n // 2 - 1, -1] + data[n // 2, 0] + data[n // 2, -1]) / 4)
    # the pole: row beyond the top is the top row at lon + 180
    top = cube.sample_face(0, -1 + (3 + 0.5) / n, 1.0)[0]
    assert top == pytest.approx((data[n - 1, 3] + data[n - 1, 3 + n]) / 2)


def test_image_errors(planetlod, tmp_path):
    empty = tmp_path / "empty.png"
    empty.write_bytes(b"")
    with pytest.raises(planetlod.ImageError, match="empty"):
        planetlod.CubeMap.from_image(str(empty))
    junk = tmp_path / "junk.png"
    junk.write_bytes(os.urandom(4096))
    with pytest.raises(planetlod.ImageError):
        planetlod.CubeMap.from_image(str(junk))
    with pytest.raises(planetlod.FileError):
        planetlod.CubeMap.from_image(str(tmp_path / "missing.png"))
    with pytest.raises(planetlod.FileError):
        planetlod.CubeMap.from_image(str(tmp_path))
    # a PNG header claiming 40000 x 40000 pixels: refused before allocation
    import zlib

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    huge = tmp_path / "huge.png"
    huge.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 40000, 40000, 8, 0, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b""))
    with pytest.raises(planetlod.ImageError, match="limit"):
        planetlod.CubeMap.from_image(str(huge))


@pytest.mark.parametrize("dtype", ["u8", "u16", "f32"])
@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_seamless_for_every_texel_type_and_channel_count(planetlod, dtype, channels):
    """Every channel of every texel type: a direction on an edge or a corner
    samples the same from each face holding it (1e-6 relative), and the
    values are the stored texels normalised (u8 / 255, u16 / 65535)."""
    if not hasattr(planetlod, "face_to_dir"):
        pytest.skip("projection stage not merged")
    projection = CUBE[(channels + len(dtype)) % 3]  # each projection gets used
    n = 5
    cube = random_cubemap(planetlod, projection, n, dtype=dtype, channels=channels, seed=channels)
    assert (cube.channels, cube.dtype) == (channels, dtype)
    scale = {"u8": 255.0, "u16": 65535.0, "f32": 1.0}[dtype]
    # texel centres read back exactly (normalised)
    raw = face_array(cube, 3)
    u = -1 + (2 + 0.5) * 2 / n
    v = -1 + (1 + 0.5) * 2 / n
    assert cube.sample_face(3, u, v) == pytest.approx(tuple(raw[1, 2] / scale), rel=1e-6)
    ts = (-1.0, -0.6, 0.0, 0.37, 1.0)
    for f in range(6):
        for t in ts:
            for u, v in ((-1.0, t), (1.0, t), (t, -1.0), (t, 1.0)):
                partners = same_point_on_other_faces(f, u, v)
                assert len(partners) == (2 if abs(u) == abs(v) == 1.0 else 1)
                a = cube.sample_face(f, u, v)
                assert len(a) == channels
                for g, gu, gv in partners:
                    assert close_rel(a, cube.sample_face(g, gu, gv)), (f, u, v, g)
                # by direction: the sample of the point the direction lands
                # on (CSC's inverse is approximate, so compare through the
                # forward map), the same from every face holding it
                d = planetlod.face_to_dir(projection, f, u, v)
                f2, u2, v2 = planetlod.dir_to_face(projection, *d)
                by_dir = cube.sample(*d)
                assert 1.0 in (abs(u2), abs(v2))
                for g, gu, gv in [(f2, u2, v2)] + same_point_on_other_faces(f2, u2, v2):
                    assert close_rel(by_dir, cube.sample_face(g, gu, gv)), (projection, f, u, v, g)
