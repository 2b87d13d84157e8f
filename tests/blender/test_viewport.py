"""Under xvfb-run: the GPU preview draws the planet in a real 3D viewport.
Screenshots of the viewport with the preview on and off must differ over the
planet's disk, the preview must show many colours (texture + light), and no
pixel inside the planet may stand out alone from its neighbours."""
import os
import sys
import traceback

import bpy

import plod_testlib as lib

STATE = {"step": 0}


def view3d():
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == 'VIEW_3D':
                region = next(r for r in area.regions if r.type == 'WINDOW')
                return window, area, region
    raise AssertionError("no 3D viewport")


def screenshot(name):
    window, area, region = view3d()
    path = os.path.join(lib.out_dir(), name)
    with bpy.context.temp_override(window=window, area=area, region=region,
                                   screen=window.screen):
        bpy.ops.screen.screenshot_area(filepath=path)
    image = bpy.data.images.load(path)
    w, h = image.size
    px = list(image.pixels)
    bpy.data.images.remove(image)
    return w, h, px


def isolated_pixels(w, h, on, off):
    """Pixels inside the drawn planet (3 pixels in from its edge) that stand
    out from 8 neighbours which agree among themselves: a colour read from
    the wrong place or level of a texture, not an edge of the picture."""
    import numpy as np
    on = np.asarray(on, dtype=np.float64).reshape(h, w, 4)[:, :, :3]
    off = np.asarray(off, dtype=np.float64).reshape(h, w, 4)[:, :, :3]
    inner = np.abs(on - off).sum(axis=2) > 0.05
    drawn = inner.copy()
    for dy in range(-3, 4):
        for dx in range(-3, 4):
            inner &= np.roll(np.roll(drawn, dy, 0), dx, 1)
    around = np.stack([on[1 + dy:h - 1 + dy, 1 + dx:w - 1 + dx]
                       for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dy, dx) != (0, 0)])
    stands_out = np.abs(on[1:-1, 1:-1] - np.median(around, axis=0)).max(axis=2) > 0.2
    agree = (np.percentile(around, 75, axis=0) -
             np.percentile(around, 25, axis=0)).max(axis=2) < 0.08
    return int(np.sum(stands_out & agree & inner[1:-1, 1:-1]))


def setup():
    bpy.context.preferences.view.show_splash = False
    lib.enable()
    lib.clear_scene()
    window, area, region = view3d()
    space = area.spaces.active
    space.overlay.show_overlays = False
    space.clip_start, space.clip_end = 1000.0, 1.0e9
    space.lens = 50.0
    r3d = space.region_3d
    r3d.view_perspective = 'PERSP'
    r3d.view_location = (0.0, 0.0, 0.0)
    preset = os.environ.get("PLOD_VIEW_PRESET", "EARTH")  # manual checks of other presets
    with bpy.context.temp_override(window=window, area=area, region=region):
        assert bpy.ops.mesh.planet_add(preset=preset, quality='DRAFT') == {'FINISHED'}
    planet = bpy.context.view_layer.objects.active
    planet.name = "Earth"
    r3d.view_distance = 3.0 * planet.planet_lod.radius
    space.clip_start, space.clip_end = planet.planet_lod.radius * 1e-4, planet.planet_lod.radius * 100
    planet.planet_lod.lod_camera = 'VIEWPORT'
    planet.planet_lod.gpu_preview = True
    planet.display_type = 'BOUNDS'
    return planet


def step():
    try:
        STATE["step"] += 1
        from planet_lod import runtime
        planet = bpy.data.objects.get("Earth")
        st = runtime.RUNTIME.get(planet.name_full) if planet else None
        drawn = st is not None and st.preview is not None and st.preview.vertex_count > 0
        if STATE["step"] < 40 and not drawn:
            return 0.1  # wait for the live refresh (refresh timer)
        assert drawn, "live update never refined the planet"
        if STATE["step"] < 45:
            return 0.1  # let the viewport redraw
        if "on" not in STATE:
            STATE["on"] = screenshot("viewport_preview_on.png")
            planet.planet_lod.gpu_preview = False
            planet.hide_viewport = True
            return 0.3
        off = screenshot("viewport_preview_off.png")
        w, h, on = STATE["on"]
        differ, colours = 0, set()
        for i in range(0, w * h * 4, 4):
            if sum(abs(on[i + k] - off[2][i + k]) for k in range(3)) > 0.05:
                differ += 1
                colours.add(tuple(round(on[i + k], 1) for k in range(3)))
        print(f"viewport {w}x{h}: {differ} px drawn by the preview, {len(colours)} colours",
              flush=True)
        assert differ > 0.02 * w * h, "GPU preview drew (almost) nothing"
        assert len(colours) > 20, "GPU preview is flat (no texture/light)"
        stray = isolated_pixels(w, h, on, off[2])
        print(f"isolated pixels inside the planet: {stray}", flush=True)
        assert stray == 0, "GPU preview has stray pixels (dots along lines of the view)"
        print("PLOD-TEST PASS", flush=True)
        os._exit(0)
    except BaseException:
        traceback.print_exc()
        print("PLOD-TEST FAIL", flush=True)
        sys.stdout.flush()
        os._exit(1)


try:
    setup()
except BaseException:
    traceback.print_exc()
    print("PLOD-TEST FAIL", flush=True)
    os._exit(1)
bpy.app.timers.register(step, first_interval=0.5)
