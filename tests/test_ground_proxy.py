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
