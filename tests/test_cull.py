"""Camera conventions and conservative culling, checked against brute force:
nothing a camera could see is ever culled."""
import math

import numpy as np
import pytest

from conftest import data_path
from test_refine import EARTH_R, look_at, space_camera, surface_camera


def window(desc):
    """Independent view window (left, right, bottom, top) from Blender's rules."""
    ax = desc["resolution_x"] * desc.get("pixel_aspect_x", 1.0)
    ay = desc["resolution_y"] * desc.get("pixel_aspect_y", 1.0)
    fit = desc.get("sensor_fit", "AUTO")
    horizontal = fit == "HORIZONTAL" or (fit == "AUTO" and ax >= ay)
    if desc.get("type") == "ORTHO":
        size = desc["ortho_scale"] / 2
    elif fit == "VERTICAL":
        size = desc["sensor_height"] / 2 / desc["lens"]
    else:
        size = desc["sensor_width"] / 2 / desc["lens"]
    hx, hy = (size, size * ay / ax) if horizontal else (size * ax / ay, size)
    sx, sy = 2 * size * desc.get("shift_x", 0.0), 2 * size * desc.get("shift_y", 0.0)
    return sx - hx, sx + hx, sy - hy, sy + hy


def inside_frustum(desc, points, tol=1e-9):
    """Boolean mask of points inside the camera's view volume (numpy, independent)."""
    m = np.array(desc["matrix_world"], float)
    rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
    local = (points - m[:3, 3]) @ rot
    depth = -local[:, 2]
    left, right, bottom, top = window(desc)
    if desc.get("type") == "ORTHO":
        x, y = local[:, 0], local[:, 1]
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            x, y = local[:, 0] / depth, local[:, 1] / depth
    ok = (depth >= desc["clip_start"] * (1 - tol)) & (depth <= desc["clip_end"] * (1 + tol))
    return ok & (x >= left - tol) & (x <= right + tol) & (y >= bottom - tol) & (y <= top + tol)


def occluded(eye, points, rho):
    """Segment eye->point passes strictly inside the ball of radius rho."""
    d = points - eye
    t = np.clip(-(d @ eye) / np.einsum("ij,ij->i", d, d), 0.0, 1.0)
    closest = eye + t[:, None] * d
    return np.linalg.norm(closest, axis=1) < rho


def prism_samples(tri, hmin, hmax, radius, rng, n=40):
    """Points of a sector's prism: geodesic triangle directions x radii."""
    w = rng.dirichlet((1, 1, 1), size=n)
    w = np.vstack([w, np.eye(3), [[0.5, 0.5, 0], [0, 0.5, 0.5], [0.5, 0, 0.5]]])
    dirs = w @ tri
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    r = radius + rng.uniform(hmin, hmax, size=len(dirs))
    r[: 3] = radius + hmax
    r[3:6] = radius + hmin
    return dirs * r[:, None]


def make_camera(planetlod, **desc):
    return planetlod.Camera(**desc), desc


def random_cameras(radius, rng, count):
    out = []
    for k in range(count):
        alt = radius * 10 ** rng.uniform(-6, 0.7)
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        eye = d * (radius + alt)
        target = rng.normal(size=3) * radius * rng.uniform(0, 1.2)
        desc = dict(matrix_world=look_at(eye, target), lens=float(rng.uniform(15, 120)),
                    sensor_width=36.0, sensor_height=24.0,
                    sensor_fit=["AUTO", "HORIZONTAL", "VERTICAL"][k % 3],
                    resolution_x=int(rng.integers(200, 2000)),
                    resolution_y=int(rng.integers(200, 2000)),
                    shift_x=float(rng.uniform(-0.3, 0.3)), shift_y=float(rng.uniform(-0.3, 0.3)),
                    clip_start=float(alt * 0.01), clip_end=float(radius * 3))
        if k % 4 == 3:
            desc.update(type="ORTHO", ortho_scale=float(alt * rng.uniform(0.5, 3)))
        out.append(desc)
    return out


def check_conservative(planetlod, planet, desc, rng, rho):
    cam = planetlod.Camera(**desc)
    planet.refine(cam, criterion="side_distance", max_level=30)
    flags = np.array(planet.sector_flags(visible_only=False).tolist())
    tris = np.array(planet.sector_corners(visible_only=False).tolist()).reshape(-1, 3, 3)
    heights = np.array(planet.sector_heights(visible_only=False).tolist()).reshape(-1, 2)
    eye = np.array(cam.position)
    culled = 0
    for k in np.nonzero(flags & 6)[0]:
        pts = prism_samples(tris[k], heights[k, 0], heights[k, 1], planet.radius, rng)
        if flags[k] & 4:
            assert not inside_frustum(desc, pts).any(), "frustum-culled sector is visible"
        if flags[k] & 2:
            assert occluded(eye, pts, rho).all(), "horizon-culled sector is visible"
        culled += 1
    # and the visible set is not empty when the camera looks at the planet
    return culled, int(np.sum((flags & 1) != 0))


def test_camera_conventions(planetlod):
    base = dict(matrix_world=look_at((0, 0, 10), (0, 0, 0), up=(0, 1, 0)),
                clip_start=0.1, clip_end=100.0, resolution_x=1920, resolution_y=1080)
    cam, desc = make_camera(planetlod, **base)
    assert cam.forward == pytest.approx((0, 0, -1))
    assert cam.up == pytest.approx((0, 1, 0))
    assert cam.contains(0, 0, 0) and not cam.contains(0, 0, 20)
    assert cam.contains(3.5, 0, 0) and not cam.contains(3.7, 0, 0)  # 18/50 * 10
    assert cam.contains(0, 2.0, 0) and not cam.contains(0, 2.05, 0)  # * 1080/1920
    assert cam.pixels_per_radian >= 1920 / (2 * 0.36)
    variants = [dict(sensor_fit="VERTICAL"), dict(resolution_x=1080, resolution_y=1920),
                dict(shift_x=0.1, shift_y=-0.2), dict(pixel_aspect_x=2.0),
                dict(type="ORTHO", ortho_scale=7.0), dict(sensor_fit="HORIZONTAL", lens=20.0)]
    rng = np.random.default_rng(1)
    pts = rng.uniform(-12, 12, size=(4000, 3))
    pts[:, 2] = rng.uniform(-100, 9.95, size=4000)
    for v in variants:
        d = dict(base, **v)
        for key, val in (("lens", 50.0), ("sensor_width", 36.0), ("sensor_height", 24.0)):
            d.setdefault(key, val)
        cam = planetlod.Camera(**d)
        want = inside_frustum(d, pts, tol=0.0)
        got = np.array([cam.contains(*p) for p in pts])
        # allow disagreement only within 1e-9 of a plane
        assert np.sum(want != got) <= 2, v
        assert want.any()
    flat = [x for row in base["matrix_world"] for x in row]
    assert planetlod.Camera(flat).position == pytest.approx((0, 0, 10))


@pytest.mark.parametrize("projection", ["qsc", "tsc", "car"])
def test_culling_conservative_sphere(planetlod, projection):
    rng = np.random.default_rng(7)
    planet = planetlod.Planet(EARTH_R, projection=projection)
    total_culled = 0
    for desc in random_cameras(EARTH_R, rng, 10):
        culled, _ = check_conservative(planetlod, planet, desc, rng, EARTH_R)
        total_culled += culled
    assert total_culled > 50  # the test exercised culling


@pytest.mark.parametrize("projection", ["qsc", "car"])
def test_culling_conservative_terrain(planetlod, projection):
    rng = np.random.default_rng(11)
    planet = planetlod.Planet(1737400.0, projection=projection, heightmap=data_path("lunar_bumpmap.jpg"),
                              height_scale=20000.0, heightmap_size=64)
    hmin, hmax = planet.height_range()
    assert hmax - hmin > 1000
    total_culled = 0
    for desc in random_cameras(planet.radius, rng, 10):
        culled, _ = check_conservative(planetlod, planet, desc, rng, planet.radius + hmin)
        total_culled += culled
    assert total_culled > 50


def test_culling_switches(planetlod):
    planet = planetlod.Planet(EARTH_R)
    cam = surface_camera(planetlod, EARTH_R, 1e4)
    s = planet.refine(cam, criterion="side_distance")
    assert s["sectors_after_backface"] < s["sectors_total"]
    assert s["sectors_after_frustum"] < s["sectors_after_backface"]
    s = planet.refine(cam, criterion="side_distance", backface=False)
    flags = np.array(planet.sector_flags(visible_only=False).tolist())
    assert s["sectors_after_backface"] == s["sectors_total"] and not np.any(flags & 2)
    s = planet.refine(cam, criterion="side_distance", backface=False, frustum=False)
    flags = np.array(planet.sector_flags(visible_only=False).tolist())
    assert s["sectors_after_frustum"] == s["sectors_total"] == planet.visible_count
    assert not np.any(flags & 6)


def test_horizon_culls_far_side(planetlod):
    planet = planetlod.Planet(EARTH_R)
    cam = space_camera(planetlod, EARTH_R + 1000.0, direction=(1, 0, 0))
    planet.refine(cam, criterion="side_distance", frustum=False)
    flags = np.array(planet.sector_flags(visible_only=False).tolist())
    tris = np.array(planet.sector_corners(visible_only=False).tolist()).reshape(-1, 3, 3)
    # every sector entirely in the far hemisphere is culled by the horizon
    far = np.all(tris[:, :, 0] < -0.01, axis=1)
    assert far.any() and np.all(flags[far] & 2)
    # and the sector under the camera is not
    near = np.all(tris[:, :, 0] > 1 - 1e-5, axis=1)  # within ~28 km; horizon ~113 km
    assert near.any() and not np.any(flags[near] & 2)


def ray_hits(origin, rays, vertices, triangles):
    """Distance along each ray (from `origin`) to the nearest triangle it
    meets, inf where it meets none (Moller-Trumbore, numpy)."""
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    e1, e2 = b - a, c - a
    out = np.full(len(rays), np.inf)
    for i, d in enumerate(rays):
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = origin - a
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = (q @ d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
        hit = ok & (u >= -1e-9) & (v >= -1e-9) & (u + v <= 1.0 + 1e-9) & (t > 0.0)
        if hit.any():
            out[i] = t[hit].min()
    return out


def test_the_sea_under_a_low_camera_is_drawn(planetlod):
    """Ground below the sea is drawn at the sea's surface.  2 m above the sea
    off a coast (the Earth preset: its detail field puts the sea floor ~250
    m down there), every ray of the view that meets the water within 200 m
    meets the lifted mesh: the sectors under the camera are culled and
    refined as the water they show, not as the sea floor far below the
    view."""
    from planetlod import presets, surface
    settings = presets.planet_settings("EARTH", data_path)
    radius = float(settings["radius"])
    planet = planetlod.Planet(radius, heightmap=settings["heightmap"],
                              projection=settings["projection"].lower(),
                              height_scale=float(settings["height_scale"]), sea_level=0.0,
                              detail=presets.detail_kwargs(settings))
    lat, lon = math.radians(36.25), math.radians(-121.75)
    up = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    east = np.array([-math.sin(lon), math.cos(lon), 0.0])
    ahead = np.cross(up, east) * math.cos(math.radians(200.0)) + east * math.sin(
        math.radians(200.0))
    eye = up * (radius + 2.0)
    matrix = look_at(eye, eye + 100.0 * ahead - 9.0 * up, up=up)
    desc = dict(matrix_world=matrix, lens=35.0, sensor_width=36.0, sensor_height=24.0,
                clip_start=0.7, clip_end=1e8, resolution_x=240, resolution_y=135)
    planet.refine(planetlod.Camera(**desc), max_level=48, budget=40000)
    mesh = planet.mesh(template_level=4)
    data = surface.vertex_data(mesh, tuple(eye), radius, 0.0)
    vertices = np.asarray(data.positions, np.float64).reshape(-1, 3)
    triangles = np.frombuffer(mesh.triangles, np.int32).reshape(-1, 3)
    near = np.linalg.norm(vertices, axis=1) < 300.0
    triangles = triangles[near[triangles].all(axis=1)]
    m = np.array(matrix, float)
    rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
    left, right, bottom, top = window(desc)
    xs, ys = np.meshgrid(np.linspace(left, right, 9), np.linspace(bottom, top, 9))
    rays = np.stack([xs.ravel(), ys.ravel(), -np.ones(xs.size)], axis=1) @ rot.T
    rays /= np.linalg.norm(rays, axis=1)[:, None]
    # where each ray meets the sphere of the sea's radius (eye-relative)
    b = rays @ eye
    disc = b * b - (eye @ eye - radius * radius)
    water = np.where((disc > 0.0) & (b < 0.0), -b - np.sqrt(np.maximum(disc, 0.0)), np.inf)
    close = water < 200.0
    assert close.sum() >= 20 and water.min() < 8.0
    hits = ray_hits(np.zeros(3), rays[close], vertices, triangles)
    missed = ~np.isfinite(hits)
    assert not missed.any(), (f"{missed.sum()} of {close.sum()} rays meet the water "
                              f"{np.round(water[close][missed], 1)} m away but no triangle")
    assert np.abs(hits - water[close]).max() < 0.05
