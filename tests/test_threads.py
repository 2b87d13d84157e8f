"""Thread safety of planetlod.  refine() and mesh() release
the GIL, so a render thread and the viewport (or any two Python threads) can be
inside one Planet at once: each Planet serialises its methods with its own
lock.  Separate planets share no mutable state and run in parallel."""
import threading

import pytest
from conftest import data_path

RADIUS = 6371000.0


def _camera(planetlod, distance, azimuth_row):
    # looking at the centre from `distance` along -Y rotated by a row choice
    rows = {
        0: [[1, 0, 0, 0], [0, 0, -1, -distance], [0, 1, 0, 0], [0, 0, 0, 1]],
        1: [[0, 0, 1, distance], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1]],
    }
    return planetlod.Camera(matrix_world=rows[azimuth_row], resolution_x=640,
                            resolution_y=360, clip_start=1.0, clip_end=1e9)


def _hammer(planet, cameras, rounds, errors, results):
    try:
        for i in range(rounds):
            cam = cameras[i % len(cameras)]
            planet.refine(cam, template_level=2, max_pixel_error=1.0, hysteresis=bool(i % 2),
                          budget=4000)
            mesh = planet.mesh(template_level=2, morph=True)
            planet.instances(template_level=2)
            assert mesh.triangle_count == mesh.sector_count * 16
            if i % 7 == 0:
                planet.reset()
            if i % 5 == 0:  # capacity and surface queries under the same lock
                planet.reserve(100 * i)
                heights, normals = planet.surface([1.0, 0.0, 0.0, 0.0, 2.0, 0.0])
                assert len(heights) == 2 and len(normals) == 6
            results.append((planet.sector_count, planet.visible_count))
    except BaseException as exc:  # reported by the main thread
        errors.append(exc)


def test_two_threads_one_planet(planetlod):
    """Two threads refining, emitting and resetting the same Planet: no crash, no
    error, the refiner's invariants hold afterwards (ASan checks it in sanitize.sh)."""
    planet = planetlod.Planet(RADIUS, heightmap=None)
    near = [_camera(planetlod, RADIUS + 2.0e4, 0), _camera(planetlod, RADIUS + 5.0e3, 1)]
    far = [_camera(planetlod, 3 * RADIUS, 1), _camera(planetlod, RADIUS + 1.0e5, 0)]
    errors, results = [], []
    threads = [threading.Thread(target=_hammer, args=(planet, cams, 60, errors, results))
               for cams in (near, far)]
    for t in threads:
        t.start()
    for _ in range(200):  # the main thread reads while they work
        # (one call each: two attribute reads can straddle another thread's
        # reset, so the invariants are checked under the planet's lock)
        assert planet.check_invariants()
        planet.sector_levels()
    for t in threads:
        t.join()
    assert not errors, errors
    assert len(results) == 120
    assert planet.check_invariants()


def test_separate_planets_parallel_equal_sequential(planetlod):
    """One planet per thread (what a render job and the viewport get when they do
    not share): same sectors and mesh bytes as the same work done sequentially."""
    path = data_path("earth-topology.png")
    cams = [_camera(planetlod, RADIUS + d, k % 2) for k, d in enumerate((3e6, 2e5, 2e4, 5e3))]

    def work(planet, out):
        for cam in cams * 3:
            planet.refine(cam, template_level=3, budget=2000)
            mesh = planet.mesh(template_level=3)
            out.append((planet.visible_count, bytes(memoryview(mesh.positions).cast("B"))))

    sequential = []
    work(planetlod.Planet(RADIUS, heightmap=path, height_scale=8848.0), sequential)
    outs = [[], []]
    planets = [planetlod.Planet(RADIUS, heightmap=path, height_scale=8848.0) for _ in outs]
    threads = [threading.Thread(target=work, args=(p, o)) for p, o in zip(planets, outs)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert outs[0] == sequential and outs[1] == sequential


@pytest.mark.parametrize("rounds", [3])
def test_planet_lock_does_not_deadlock_on_errors(planetlod, rounds):
    """A method that raises releases the planet's lock (the next call proceeds)."""
    planet = planetlod.Planet(RADIUS)
    centre = planetlod.Camera(matrix_world=[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0],
                                            [0, 0, 0, 1]], clip_start=1.0, clip_end=1e9)
    good = _camera(planetlod, 3 * RADIUS, 0)
    for _ in range(rounds):
        with pytest.raises(planetlod.InvalidArgument):
            planet.refine(centre)
        with pytest.raises(planetlod.InvalidArgument):
            planet.refine(good, template_level=99)
        planet.refine(good)
        assert planet.visible_count > 0
