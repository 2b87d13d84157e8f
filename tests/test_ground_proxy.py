"""The viewport ground (planetlod.ground_proxy): the coarse mesh that Blender's
depth-based tools see under a GPU-previewed planet.  It must be closed,
facing out, small from any altitude, and lie at or under the ground, close
to it near the eye."""
import array
import math

import numpy as np
import pytest

from test_refresh import RADIUS, settings


def eye_above(planet, altitude, lat=44.4, lon=8.9):
    lat, lon = math.radians(lat), math.radians(lon)
    up = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    return up * (RADIUS + planet.height(*up) + altitude)


@pytest.fixture(scope="module")
def planet():
    from planetlod import planets
    return planets.build_planet(settings())


@pytest.mark.parametrize("altitude", [2000.0, 5.0e5, 2.0e7])
def test_proxy_lies_under_the_ground(planet, altitude):
    from planetlod import ground_proxy
    eye = eye_above(planet, altitude)
    anchor = tuple(eye)  # the floating origin at the eye, as a geo-placed camera puts it
    positions, triangles = ground_proxy.proxy_mesh(planet.surface, RADIUS, eye, anchor)
    assert positions.dtype == np.float32 and triangles.dtype == np.int32
    assert len(triangles) < 5000, "a coarse mesh from any altitude"
    points = positions.astype(np.float64) + eye
    r = np.linalg.norm(points, axis=1)
    ground = RADIUS + np.frombuffer(planet.surface((points / r[:, None]).ravel().tolist())[0])
    below = ground - r
    distance = np.linalg.norm(points - eye, axis=1)
    assert below.min() >= 0.0, "a vertex above the ground would show through the preview"
    near = distance < 20.0 * altitude
    assert near.any()
    # close to the ground near the eye: tools reading its depth land there
    assert (below[near] <= 0.02 * distance[near] + 50.0).all(), below[near].max()
    # closed: every edge in two triangles, in opposite directions
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    forward = {tuple(e) for e in edges}
    assert len(forward) == len(edges)
    assert all((b, a) in forward for a, b in forward)
    # facing out (counter-clockwise seen from outside)
    p = points[triangles]
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert (np.einsum("ij,ij->i", normals, p.mean(axis=1)) > 0.0).all()


def test_proxy_sea_level(planet):
    """With a sea the ground is the sea over land below it: the proxy does not
    sink to the sea floor."""
    from planetlod import ground_proxy
    eye = eye_above(planet, 2000.0)
    sea = 5000.0  # over every height of this planet near the eye
    positions, _ = ground_proxy.proxy_mesh(planet.surface, RADIUS, eye, sea_level=sea)
    r = np.linalg.norm(positions.astype(np.float64), axis=1)
    distance = np.linalg.norm(positions.astype(np.float64) - eye, axis=1)
    near = distance < 20000.0
    assert ((RADIUS + sea) - r[near] <= 0.002 * distance[near] + 1.0).all()


@pytest.mark.parametrize("radius,distance", [(1.0, 1.0e5), (20000.0, 1.0e9)])
def test_proxy_seen_from_far_away(radius, distance):
    """A viewer hundreds of thousands of radii away still gets a closed mesh
    of a few rings (not an empty or broken one)."""
    from planetlod import ground_proxy

    def flat(directions):  # a smooth sphere
        return array.array("d", [0.0] * (len(directions) // 3)), None
    positions, triangles = ground_proxy.proxy_mesh(flat, radius, (0.0, 0.0, distance))
    assert len(positions) > 2 * ground_proxy.SEGMENTS
    assert triangles.min() >= 0 and triangles.max() == len(positions) - 1
    r = np.linalg.norm(positions.astype(np.float64), axis=1)
    assert (r <= radius * 1.0001).all()


def test_near_patch_follows_the_shown_surface(planet):
    """Near the eye the proxy copies the preview's own triangles, a few metres
    under them: in steep relief a tool's point lands on the ground shown, not
    under the lowest point of a coarse cell.  (The ground shown: the preview's
    vertices, whose detail ends at their sector's resolution.)"""
    from planetlod import ground_proxy, surface
    from planetlod.refresh import SurfaceWork
    from test_refresh import camera_params, settings as planet_settings
    params = camera_params(2000.0, pitch_down=0.35)
    eye = np.array([row[3] for row in params["matrix_world"][:3]])
    anchor = tuple(eye)
    work = SurfaceWork(planet, planet_settings(), params, refine=True, for_render=False,
                       check_size=True, preview=(anchor, RADIUS, None, False, None, None))
    work.run()
    preview = work.preview_data
    assert isinstance(preview, surface.PreviewData) and preview.sectors > 0
    altitude = 2000.0
    positions, triangles = ground_proxy.near_patch(preview, eye, anchor, altitude)
    assert len(triangles) > 0 and positions.dtype == np.float32 and triangles.dtype == np.int32
    assert triangles.min() >= 0 and triangles.max() < len(positions)
    points = positions.astype(np.float64) + eye
    distance = np.linalg.norm(points - eye, axis=1)
    # the sectors copied reach from under the eye to NEAR_REACH altitudes away
    assert distance.min() < 2.0 * altitude
    # each vertex on its preview vertex's radius, NEAR_SINK of its distance under it
    shown = preview.positions.astype(np.float64) + eye
    shown_r = np.linalg.norm(shown, axis=1)
    directions = shown / shown_r[:, None]
    r = np.linalg.norm(points, axis=1)
    cosines = (points / r[:, None]) @ directions.T
    matched = cosines.argmax(axis=1)
    assert (cosines.max(axis=1) > 1.0 - 1e-12).all()
    below = shown_r[matched] - r
    assert (below >= 0.0).all(), below.min()
    assert (np.abs(below - ground_proxy.NEAR_SINK * distance) < 0.05).all()
    # with the coarse rings: one mesh, indices in range
    coarse = ground_proxy.proxy_mesh(planet.surface, RADIUS, eye, anchor)
    both = ground_proxy.joined(coarse, (positions, triangles))
    assert len(both[0]) == len(coarse[0]) + len(positions)
    assert both[1].max() == len(both[0]) - 1 and both[1].dtype == np.int32
    # a preview drawn whole (the other LOD methods) gives no patch
    assert len(ground_proxy.near_patch(None, eye, anchor, altitude)[1]) == 0
