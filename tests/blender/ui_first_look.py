"""In the real UI (xvfb), a newcomer's first minutes on the factory-startup
scene: Add > Mesh > Planet shows the planet framed in the viewport at once
(camera, view and clip range outside it, a sun); looking through the camera,
F12 renders what the viewport shows, lit."""
import math
import os

import bpy
import numpy as np
from mathutils import Vector

import plod_testlib as lib
import plod_uilib as ui


def test():
    lib.enable()
    win, area, region, _ = ui.view3d()
    space = ui.clean_view()
    scene = bpy.context.scene
    camera, light = scene.camera, bpy.data.objects["Light"]
    with ui.override():
        assert bpy.ops.mesh.planet_add(preset='EARTH') == {'FINISHED'}
    planet = bpy.context.object
    radius = planet.planet_lod.radius
    from planet_lod import runtime
    st = runtime.state(planet)
    yield from ui.redraw(3)
    # the view, the camera and their clip ranges are outside / around the planet
    eye = space.region_3d.view_matrix.inverted().translation
    assert eye.length > 1.5 * radius, eye.length
    assert camera.matrix_world.translation.length > 1.5 * radius
    print("view", eye.length, "clip", space.clip_start, space.clip_end, "camera", camera.location.length, camera.data.clip_start, camera.data.clip_end, flush=True)
    assert space.clip_start < eye.length - radius < space.clip_end
    assert camera.data.clip_start < camera.location.length - radius < camera.data.clip_end
    assert space.clip_end < eye.length + radius, "far hemisphere inside the clip range"
    assert light.hide_render, "the point light inside the planet still renders"
    sun = [o for o in scene.objects if o.type == 'LIGHT' and o.data.type == 'SUN']
    assert sun, "no sun"
    # a sensible object: the dimensions and the viewport's LOD
    assert min(planet.dimensions) > radius, planet.dimensions
    assert st.stats.get("visible", 0) > 8 and st.preview is not None and not st.error, st.stats
    shot = ui.screenshot("first_look.png")
    mask = ui.foreground(shot)
    h, w = mask.shape
    cx, cy, r = ui.disk(mask)
    print(f"after Add > Planet: planet covers {mask.mean():.1%} of the view, centre "
          f"({cx / w:.2f}, {cy / h:.2f}), radius {r / h:.2f} of the height, "
          f"{len(np.unique((shot[mask] * 8).astype(int), axis=0))} colours", flush=True)
    assert 0.15 < mask.mean() < 0.8
    assert abs(cx / w - 0.5) < 0.1 and abs(cy / h - 0.5) < 0.1
    assert len(np.unique((shot[mask] * 8).astype(int), axis=0)) > 30, "flat planet"

    # navigating (the view turning a little at every step, like a drag; under
    # llvmpipe a step is a redraw, up to a second): the LOD follows during the
    # motion, not only once it stops
    from planet_lod import handlers
    r3d = space.region_3d
    # (the refiner's frame count: a refresh whose leaves did not change keeps
    # the preview's surface)
    before, steps = st.stats["frame"], 8
    for _ in range(steps):
        r3d.view_rotation = (r3d.view_rotation @ Vector((0.0, 0.0, 1.0)).rotation_difference(
            Vector((0.01, 0.0, 1.0)))).normalized()
        yield max(0.05, handlers.REFRESH_INTERVAL_S)
    during = st.stats["frame"] - before
    print(f"navigation: {during} viewport refreshes during {steps} steps of motion", flush=True)
    assert during >= steps // 2, "the LOD does not follow while navigating"

    # frame a shot: look through the camera, move it closer, render F12
    r3d.view_perspective = 'CAMERA'
    camera.location = camera.location * 0.6
    scene.render.resolution_x, scene.render.resolution_y = 960, 540
    scene.render.resolution_percentage = 50
    scene.render.engine = 'BLENDER_EEVEE'
    scene.eevee.taa_render_samples = 4
    with ui.override():
        bpy.ops.view3d.view_center_camera()
    yield from ui.wait_until(st.settled, what="the viewport refresh")
    yield from ui.redraw(4)
    view = ui.screenshot("framed_view.png")
    x0, y0, x1, y1 = ui.camera_frame_rect(scene, camera, region, r3d)
    framed = view[y0:y1, x0:x1]
    preview_before = st.preview
    with ui.override():
        bpy.ops.render.render()
    assert st.preview is preview_before, "the render's LOD leaked into the viewport's"
    path = os.path.join(lib.out_dir(), "framed_render.png")
    bpy.data.images["Render Result"].save_render(filepath=path)
    render = ui.load_png(path)
    rh, rw = render.shape[:2]
    # the viewport's camera frame resampled to the render's size
    ys = (np.arange(rh) * framed.shape[0] / rh).astype(int)
    xs = (np.arange(rw) * framed.shape[1] / rw).astype(int)
    framed = framed[ys][:, xs]
    a, b = ui.foreground(framed), ui.foreground(render)
    iou = (a & b).sum() / max((a | b).sum(), 1)
    da, db = ui.disk(a), ui.disk(b)
    lit = render[b].mean(axis=1)
    print(f"F12 {rw}x{rh}: planet {b.mean():.1%} of the image, viewport frame {a.mean():.1%}, "
          f"IoU {iou:.3f}; disk viewport {da}, render {db}; lit pixels "
          f"{(lit > 0.1).mean():.1%}, mean {lit.mean():.3f}", flush=True)
    assert b.mean() > 0.2, "F12 shows (almost) nothing of the planet"
    assert iou > 0.9, "F12 does not show what the viewport framed"
    assert abs(da[2] - db[2]) < 0.05 * rh
    assert (lit > 0.1).mean() > 0.3, "the render is dark (no sun)"


ui.run(test)
