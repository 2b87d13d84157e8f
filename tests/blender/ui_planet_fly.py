"""In the real UI (xvfb): Planet Fly (Shift-` over a planet) flies at a pace
that follows the altitude above the ground and never goes through it.

* Level over the sea from 2 km and from 2 m, W held for a second of flight:
  the view covers the same share of its altitude per second at both
  heights (half of it: a kilometre from 2 km, a metre from 2 m), the same
  distance the flight says it flew.
* A fast dive towards the Alps, W and Shift held until the ground is near:
  the eye slows down as the ground comes near and ends above it, never
  under it on the way.
* Esc puts the view back where the flight began; Enter keeps the new place.

A camera placed by longitude and latitude over the sea moves the floating
origin there, as an artist's shot does: the view's float32 location is then
precise to well under a millimetre where the flights are measured."""
import math

import bpy
from mathutils import Vector

import plod_uilib as ui

SEA = (-30.0, 20.0)  # the Atlantic: a flat ground (the sea level) for the level flights
ALPS = (7.9, 46.0)


def go_to(planet, where, altitude, pitch, heading=90.0):
    with ui.override():
        assert bpy.ops.view3d.planet_go_to_surface(
            longitude=where[0], latitude=where[1], altitude=altitude, pitch=pitch,
            heading=heading) == {'FINISHED'}
    yield from ui.refreshed(planet)


def key(win, region, kind, value, **modifiers):
    x, y = region.x + region.width // 2, region.y + region.height // 2
    win.event_simulate(type=kind, value=value, x=x, y=y, **modifiers)


def start_flight(win, region):
    """Generator: Shift-` with the mouse over the view's middle; waits until the flight runs."""
    from planet_lod import planet_fly
    x, y = region.x + region.width // 2, region.y + region.height // 2
    win.event_simulate(type='MOUSEMOVE', value='NOTHING', x=x, y=y)
    yield 0.3
    key(win, region, 'ACCENT_GRAVE', 'PRESS', shift=True)
    key(win, region, 'ACCENT_GRAVE', 'RELEASE', shift=True)
    yield from ui.wait_until(planet_fly.flying, timeout=120, what="Planet Fly to start")


def end_flight(win, region, how='RET'):
    from planet_lod import planet_fly
    key(win, region, how, 'PRESS')
    key(win, region, how, 'RELEASE')
    yield from ui.wait_until(lambda: not planet_fly.flying(), timeout=120,
                             what="Planet Fly to end")


def hold(win, region, kind, seconds, check=None):
    """Generator: holds `kind` until the flight has moved for `seconds`, then
    releases it and waits until the flight stands; `check()` runs meanwhile."""
    import time
    from planet_lod import planet_fly
    log = planet_fly.flight_log()
    key(win, region, kind, 'PRESS')
    began = time.monotonic()
    while log.moving_s < seconds:
        assert planet_fly.flying(), "the flight ended while a key was held"
        assert time.monotonic() - began < ui.WAIT_LIMIT_S, f"no {seconds} s of flight"
        if check is not None:
            check()
        yield 0.05
    key(win, region, kind, 'RELEASE')
    yield from ui.wait_until(lambda: log.speed == 0.0, timeout=120,
                             what="the flight to stop after the key's release")


def level_flight(planet, space, altitude):
    """Generator: one second of level flight from `altitude` m over the sea;
    returns (metres flown per second per metre of altitude, view moved, flown)."""
    from planet_lod import navigation, planet_fly
    r3d = space.region_3d
    win, _, region, _ = ui.view3d()
    yield from go_to(planet, SEA, altitude, pitch=0.0)
    yield from start_flight(win, region)
    start = navigation.eye_of(r3d)
    heights = []  # the altitude of the view, sampled while it flies

    def sample():
        heights.append(navigation.altitude(planet, navigation.eye_of(r3d)))
    yield from hold(win, region, 'W', 1.0, sample)
    log = planet_fly.flight_log()
    moved = (navigation.eye_of(r3d) - start).length
    yield from ui.redraw(2)
    ui.screenshot(f"level_{altitude:g}m.png", region='AREA')
    yield from end_flight(win, region)
    paced = sum(max(h, planet_fly.CLEARANCE) for h in heights) / len(heights)
    share = log.distance / log.moving_s / paced
    print(f"level flight from {altitude:g} m ({min(heights):.3f} to {max(heights):.3f} m while "
          f"it flew, {len(heights)} samples): {log.distance:.3f} m in {log.moving_s:.3f} s of "
          f"flight ({share:.4f} of the altitude a second), the view moved {moved:.3f} m, "
          f"lowest {log.lowest:.3f} m", flush=True)
    assert abs(heights[0] - altitude) < 0.01 * altitude, heights[0]
    assert min(heights) > 0.0 and log.lowest > 0.0
    return share, moved, log.distance


def test():
    ui.lib.enable()
    from planet_lod import navigation, planet_fly, view_follow
    space = ui.clean_view()
    r3d = space.region_3d
    with ui.override():
        assert bpy.ops.mesh.planet_add(preset='EARTH') == {'FINISHED'}
    planet = bpy.context.object
    yield from ui.refreshed(planet)

    # the floating origin over the sea, as a shot placed there would put it
    cam = bpy.data.objects.new("Shot", bpy.data.cameras.new("Shot"))
    bpy.context.scene.collection.objects.link(cam)
    geo = cam.planet_lod_geo
    geo.planet = planet
    geo.longitude, geo.latitude, geo.altitude = SEA[0], SEA[1], 2.0
    geo.floating_origin = True
    geo.enabled = True
    yield from ui.wait_until(lambda: any(abs(v) > 1e5 for v in planet.get("planet_lod_anchor",
                                                                         (0, 0, 0))),
                             timeout=120, what="the floating origin to move")
    yield from ui.refreshed(planet)

    # ---- level flights: the same share of the altitude a second at 2 km and 2 m
    high, high_moved, high_flown = yield from level_flight(planet, space, 2000.0)
    low, low_moved, low_flown = yield from level_flight(planet, space, 2.0)
    print(f"share of the altitude flown a second: {high:.4f} from 2 km, {low:.4f} from 2 m",
          flush=True)
    for share in (high, low):
        assert abs(share - planet_fly.flight.SPEED_PER_METRE) < 0.02, (high, low)
    assert abs(high / low - 1.0) < 0.03, (high, low)
    # the view went where the flight says (float32 view, the origin a few km away)
    assert abs(high_moved - high_flown) < 0.01 * high_flown, (high_moved, high_flown)
    assert abs(low_moved - low_flown) < 0.05, (low_moved, low_flown)

    # ---- a fast dive towards the Alps: slows down near the ground, never under it
    win, _, region, _ = ui.view3d()
    yield from go_to(planet, ALPS, 2000.0, pitch=-60.0, heading=0.0)
    yield from start_flight(win, region)
    log = planet_fly.flight_log()
    lowest_seen = [math.inf]

    def check():
        height = navigation.altitude(planet, navigation.eye_of(r3d))
        lowest_seen[0] = min(lowest_seen[0], height)
        assert height > -1.0, f"the view went {-height:.1f} m under the ground"
    key(win, region, 'LEFT_SHIFT', 'PRESS')
    yield from hold(win, region, 'W', 5.0, check)
    key(win, region, 'LEFT_SHIFT', 'RELEASE')
    with ui.override():
        text = view_follow.readout(bpy.context)
    print("readout while flying:", text, flush=True)
    assert "Planet Fly" in text, text
    yield from ui.redraw(2)
    ui.screenshot("dive.png", region='AREA')
    yield from end_flight(win, region)
    yield from ui.refreshed(planet)
    ui.screenshot("dive_settled.png", region='AREA')
    end_height = navigation.altitude(planet, navigation.eye_of(r3d))
    print(f"dive from 2 km: {log.distance:.1f} m in {log.moving_s:.2f} s of flight, lowest "
          f"{log.lowest:.2f} m (float64), {lowest_seen[0]:.2f} m (the view), {end_height:.2f} m "
          "above the ground after", flush=True)
    assert log.lowest >= planet_fly.CLEARANCE - 1e-6, log.lowest
    assert log.height < 50.0, "the dive did not come near the ground"
    assert end_height > 0.0

    # ---- Esc: the view back where the flight began
    yield from go_to(planet, SEA, 500.0, pitch=-5.0)
    before = (Vector(r3d.view_location), r3d.view_rotation.copy(), r3d.view_distance)
    yield from start_flight(win, region)
    yield from hold(win, region, 'W', 0.5)
    assert (Vector(r3d.view_location) - before[0]).length > 50.0
    yield from end_flight(win, region, 'ESC')
    assert (Vector(r3d.view_location) - before[0]).length < 1e-3
    assert r3d.view_rotation.rotation_difference(before[1]).angle < 1e-4
    print("Esc: the view back where the flight began", flush=True)


ui.run(test)
