"""Helpers of the UI tests (tests/blender/ui_*.py), which run in Blender's real
interface under xvfb-run (tests/test_ui.py): a test is a generator that yields
the seconds to wait (the UI redraws and the add-on's timer runs meanwhile);
screenshots come back as numpy arrays; panel draws are recorded.

Waits end on the event they wait for (a redraw counted by a draw handler, a
refresh of the planet, a panel drawn), never after a fixed time: on a busy
machine under llvmpipe a redraw can take seconds.  Their limit, WAIT_LIMIT_S
($PLOD_UI_WAIT_LIMIT_S, default 600 s), only stops a test that would hang.

Blender runs with --enable-event-simulate, so the tests can click (the sidebar
tabs have no Python API) and real input cannot interfere."""
import os
import sys
import traceback

import bpy
import numpy as np

import plod_testlib as lib


def run(test):
    """Runs the generator `test()` from a timer; exits 0 with PLOD-TEST PASS at its end,
    1 with the traceback on any error."""
    state = {}

    def step():
        try:
            if "gen" not in state:
                state["gen"] = test()
            wait = next(state["gen"])
            return max(float(wait), 0.01)
        except StopIteration:
            print("PLOD-TEST PASS", flush=True)
            sys.stdout.flush()
            os._exit(0)
        except BaseException:
            traceback.print_exc()
            print("PLOD-TEST FAIL", flush=True)
            sys.stdout.flush()
            os._exit(1)
    bpy.context.preferences.view.show_splash = False
    bpy.app.timers.register(step, first_interval=0.5)


WAIT_LIMIT_S = float(os.environ.get("PLOD_UI_WAIT_LIMIT_S", "600"))


def wait_until(condition, timeout=None, what="condition", step=0.1):
    """Generator: waits (letting the UI run) until condition() is true; fails
    after `timeout` seconds (default WAIT_LIMIT_S)."""
    import time
    limit = WAIT_LIMIT_S if timeout is None else timeout
    start = time.monotonic()
    while not condition():
        assert time.monotonic() - start < limit, f"timed out waiting for {what} ({limit:.0f} s)"
        yield step


_draws = {"count": 0, "handle": None, "sidebar": 0, "sidebar_handle": None}


def _count_draw():
    _draws["count"] += 1


def _count_sidebar_draw():
    _draws["sidebar"] += 1


def _sidebar_draws():
    """The sidebar's draws so far (counted from the first call on)."""
    if _draws["sidebar_handle"] is None:
        _draws["sidebar_handle"] = bpy.types.SpaceView3D.draw_handler_add(
            _count_sidebar_draw, (), 'UI', 'POST_PIXEL')
    return _draws["sidebar"]


def redraw(times=2, pause=0.3):
    """Generator: tags the 3D viewport and waits until it has really drawn `times`
    times more (llvmpipe is slow; a fixed sleep is not enough on a busy machine),
    with the add-on's timer running in between (at least `pause` s each)."""
    if _draws["handle"] is None:
        _draws["handle"] = bpy.types.SpaceView3D.draw_handler_add(_count_draw, (), 'WINDOW',
                                                                  'POST_PIXEL')
    for _ in range(times):
        yield pause
        target = _draws["count"] + 1
        view3d()[1].tag_redraw()
        yield from wait_until(lambda: _draws["count"] >= target, what="a viewport redraw",
                              step=0.05)


def refreshed(planet, since=None):
    """Generator: waits until the live refresh of `planet` is done and its
    preview drawn, then for two real redraws.  A change of the planet's
    settings marks it for a refresh at once; a change of the view only when
    the add-on's timer notices it: then pass `since`, the state's refresh
    serial read before the change, and the wait also needs a refresh begun
    after it."""
    from planet_lod import runtime
    st = runtime.state(planet)
    yield from wait_until(lambda: (since is None or st.serial > since) and st.settled()
                          and st.preview is not None, what="the viewport refresh")
    yield from redraw(2)


def serial(planet):
    """The planet's refresh serial now (for refreshed(planet, since=...))."""
    from planet_lod import runtime
    return runtime.state(planet).serial


def settled(planet):
    """Generator: waits until the planet has no refresh pending or running."""
    from planet_lod import runtime
    st = runtime.state(planet)
    yield from wait_until(st.settled, what="the planet's refresh")


def window():
    return bpy.context.window_manager.windows[0]


def view3d():
    """(window, area, WINDOW region, UI region) of the 3D viewport."""
    win = window()
    for area in win.screen.areas:
        if area.type == 'VIEW_3D':
            regions = {r.type: r for r in area.regions}
            return win, area, regions['WINDOW'], regions.get('UI')
    raise AssertionError("no 3D viewport")


def override(**extra):
    win, area, region, _ = view3d()
    return bpy.context.temp_override(window=win, screen=win.screen, area=area, region=region,
                                     **extra)


def screenshot(name, region='VIEW'):
    """A screenshot as a float array [row 0 = top, column, RGB], also written to the
    test output folder: the 3D viewport's drawing region ('VIEW'), its whole area
    ('AREA') or the whole window ('WINDOW')."""
    path = os.path.join(lib.out_dir(), name)
    with override():
        if region == 'AREA':
            bpy.ops.screen.screenshot_area(filepath=path)
        else:
            bpy.ops.screen.screenshot(filepath=path)
    image = load_png(path)
    return crop_region(image, view3d()[2]) if region == 'VIEW' else image


def camera_frame_rect(scene, cam, region, r3d):
    """(x0, y0, x1, y1) of the camera frame in the region's screenshot (row 0 on top)."""
    # far along the frame's rays: points a metre from a camera 10^7 m out lose
    # their depth in the float32 projection
    far = max(cam.location.length, 1.0e3)
    corners = [cam.matrix_world @ (v * (far / abs(v.z))) for v in cam.data.view_frame(scene=scene)]
    from bpy_extras.view3d_utils import location_3d_to_region_2d
    pts = [location_3d_to_region_2d(region, r3d, c) for c in corners]
    xs, ys = [p.x for p in pts], [region.height - p.y for p in pts]
    return (int(round(min(xs))), int(round(min(ys))), int(round(max(xs))), int(round(max(ys))))


def clean_view():
    """The 3D viewport without overlays, gizmos, toolbar or header: only the scene."""
    _, area, _, _ = view3d()
    space = area.spaces.active
    space.overlay.show_overlays = False
    space.show_gizmo = False
    space.show_region_toolbar = False
    space.show_region_header = False
    space.show_region_tool_header = False
    return space


def load_png(path):
    image = bpy.data.images.load(path)
    try:
        w, h = image.size
        px = np.empty(w * h * 4, dtype=np.float32)
        image.pixels.foreach_get(px)
    finally:
        bpy.data.images.remove(image)
    return px.reshape(h, w, 4)[::-1, :, :3].copy()


def crop_region(window_image, region):
    """The part of a whole-window screenshot that shows `region`."""
    h = window_image.shape[0]
    top = h - (region.y + region.height)
    return window_image[top:top + region.height, region.x:region.x + region.width]


def foreground(image, background=None, threshold=0.06):
    """Mask of the pixels that differ from the background colour (default: the
    median of the image's border) by more than `threshold` (sum over RGB)."""
    if background is None:
        # a few pixels in: the area's outline is darker than the background
        border = np.concatenate([image[4], image[-5], image[:, 4], image[:, -5]])
        background = np.median(border, axis=0)
    return np.abs(image - background).sum(axis=2) > threshold


def disk(mask):
    """(centre x, centre y, equivalent radius) of a mask, in pixels."""
    ys, xs = np.nonzero(mask)
    if len(xs) == 0:
        return None
    return float(xs.mean()), float(ys.mean()), float(np.sqrt(len(xs) / np.pi))


def detail(image, mask):
    """Mean absolute Laplacian of the luminance over `mask` (eroded by a pixel):
    how much small-scale relief or texture a picture shows."""
    lum = image @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    lap = np.abs(4 * lum[1:-1, 1:-1] - lum[:-2, 1:-1] - lum[2:, 1:-1]
                 - lum[1:-1, :-2] - lum[1:-1, 2:])
    inner = mask[1:-1, 1:-1] & mask[:-2, 1:-1] & mask[2:, 1:-1] & mask[1:-1, :-2] & mask[1:-1, 2:]
    return float(lap[inner].mean()) if inner.any() else 0.0


# ---- panels ---------------------------------------------------------------------------

class PanelRecorder:
    """Wraps the draw() of every panel of the add-on: counts the draws and keeps
    the exceptions (Blender itself only prints them)."""

    def __init__(self):
        import planet_lod
        self.classes = [cls for cls in planet_lod.classes if issubclass(cls, bpy.types.Panel)]
        self.draws = {cls.__name__: 0 for cls in self.classes}
        self.errors = []
        for cls in self.classes:
            cls.draw = self._wrap(cls.__name__, cls.draw)

    def _wrap(self, name, draw):
        def recorded(panel, context):
            try:
                draw(panel, context)
            except BaseException as exc:
                self.errors.append(f"{name}: {type(exc).__name__}: {exc}")
                raise
            self.draws[name] += 1
        return recorded

    def snapshot(self):
        return dict(self.draws)

    def drawn_since(self, before):
        return {name for name, count in self.draws.items() if count > before.get(name, 0)}


def _sidebar_redraw(area, times=2):
    """Generator: tags the area and waits until its sidebar has drawn `times`
    times more (the first may still show the state before a click)."""
    for _ in range(times):
        target = _sidebar_draws() + 1
        area.tag_redraw()
        yield 0.05
        yield from wait_until(lambda: _draws["sidebar"] >= target, what="a sidebar redraw",
                              step=0.05)


def simulate_click(win, x, y):
    win.event_simulate(type='MOUSEMOVE', value='NOTHING', x=x, y=y)
    win.event_simulate(type='LEFTMOUSE', value='PRESS', x=x, y=y)
    win.event_simulate(type='LEFTMOUSE', value='RELEASE', x=x, y=y)


def press_key(win, region, type_, settle=0.3):
    """Generator: presses and releases a key with the mouse over the middle of
    `region` (events go to the region under the mouse), `settle` seconds
    after the mouse got there."""
    x, y = region.x + region.width // 2, region.y + region.height // 2
    win.event_simulate(type='MOUSEMOVE', value='NOTHING', x=x, y=y)
    yield settle
    win.event_simulate(type=type_, value='PRESS', x=x, y=y)
    yield 0.1
    win.event_simulate(type=type_, value='RELEASE', x=x, y=y)


def shift_right_click(win, x, y):
    """Generator: Shift-RMB at window pixel (x, y)."""
    win.event_simulate(type='MOUSEMOVE', value='NOTHING', x=x, y=y)
    yield 0.3
    win.event_simulate(type='RIGHTMOUSE', value='PRESS', x=x, y=y, shift=True)
    yield 0.1
    win.event_simulate(type='RIGHTMOUSE', value='RELEASE', x=x, y=y, shift=True)


def open_sidebar_tab(recorder, panel="PLOD_PT_planet"):
    """Generator: shows the 3D viewport's sidebar and clicks down its tab strip until
    `panel` draws (tabs have no Python API)."""
    win, area, _, _ = view3d()
    area.spaces.active.show_region_ui = True
    area.tag_redraw()
    yield from wait_until(lambda: view3d()[3] is not None and view3d()[3].width > 1,
                          what="the sidebar to open")
    _, _, _, ui_region = view3d()
    yield from _sidebar_redraw(area)
    before = recorder.snapshot()
    yield from _sidebar_redraw(area)
    if panel in recorder.drawn_since(before):
        return
    x = ui_region.x + ui_region.width - 8
    top = ui_region.y + ui_region.height - 10
    for y in range(top, ui_region.y + ui_region.height // 2, -12):
        before = recorder.snapshot()
        simulate_click(win, x, y)
        yield from _sidebar_redraw(area)
        if panel in recorder.drawn_since(before):
            return
    raise AssertionError(f"no sidebar tab shows {panel}")
