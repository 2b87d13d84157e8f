"""In the real UI (xvfb): the LOD Method setting of the Level of Detail panel.
Each method draws the asteroid's GPU preview with Show LOD levels (several
levels' colours in view, no error), the legend's text comes from the method,
and the render mesh of each method is a closed surface with the method's
levels in its sector_level attribute.  Near the ground (2 km and 2 m) every
method draws the ground under the horizon."""
import bpy
import numpy as np
from mathutils import Vector

import plod_testlib as lib
import plod_uilib as ui


def colours(image, mask):
    """Distinct quantised colours among the planet's pixels."""
    q = np.round(image[mask] * 8.0).astype(np.int32)
    return len(np.unique(q[:, 0] * 81 + q[:, 1] * 9 + q[:, 2]))


def test():
    lib.enable()
    ui.clean_view()
    for obj in [o for o in bpy.data.objects if o.type == 'MESH']:
        bpy.data.objects.remove(obj)
    empty = ui.screenshot("lod_method_empty_view.png")
    background = np.median(empty.reshape(-1, 3), axis=0)
    with ui.override():
        assert bpy.ops.mesh.planet_add(preset='ASTEROID') == {'FINISHED'}
    planet = bpy.context.object
    from planet_lod import legend, refresh, runtime
    s = planet.planet_lod
    _, area, _, _ = ui.view3d()
    r3d = area.spaces.active.region_3d
    r3d.view_distance = 1.6 * s.radius
    r3d.view_rotation = Vector((0.5, -1.0, 0.4)).to_track_quat('Z', 'Y')
    s.show_levels = True
    for method in ('HRTMR', 'CHUNKED', 'GEOMIPMAP', 'CLIPMAP'):
        s.lod_method = method
        yield from ui.refreshed(planet)
        st = runtime.state(planet)
        assert not st.error, st.error
        shot = ui.screenshot(f"lod_method_{method.lower()}.png")
        mask = ui.foreground(shot)
        shown = legend.levels_shown(bpy.context.scene)
        print(f"{method}: {st.stats['visible']} patches, level {st.stats['max_level']}, "
              f"planet {mask.mean():.1%} of the view, {colours(shot, mask)} colours; legend "
              f"{shown[2]!r}", flush=True)
        assert mask.mean() > 0.2 and colours(shot, mask) >= 4
        from planet_lod.core import planets
        assert shown[2] == planets.LEVEL_MEANING[method]
        # the render path: the Blender mesh of the method
        refresh.refresh(planet, bpy.context.scene, build_mesh=True)
        levels = np.zeros(len(planet.data.polygons), dtype=np.int32)
        planet.data.attributes["sector_level"].data.foreach_get("value", levels)
        print(f"{method}: mesh {len(planet.data.vertices)} vertices, "
              f"{len(planet.data.polygons)} triangles, levels {levels.min()}..{levels.max()}",
              flush=True)
        assert len(planet.data.polygons) == st.stats["triangles"] or method != 'HRTMR'
        assert levels.max() > levels.min()
    s.lod_method = 'CHUNKED'
    s.chunk_cracks = 'SKIRTS'
    yield from ui.refreshed(planet)
    assert not runtime.state(planet).error
    ui.screenshot("lod_method_chunked_skirts.png")
    s.chunk_cracks = 'STITCH'

    # near the ground: every method draws the ground under the horizon, without holes
    for altitude, pitch in ((2000.0, -35.0), (2.0, -20.0)):
        for method in ('HRTMR', 'CHUNKED', 'GEOMIPMAP', 'CLIPMAP'):
            st = runtime.state(planet)
            since = st.serial
            s.lod_method = method
            with ui.override():
                assert bpy.ops.view3d.planet_go_to_surface(
                    longitude=20.0, latitude=10.0, altitude=altitude,
                    pitch=pitch) == {'FINISHED'}
            # the view jumped from far away: the refinement takes a few refreshes,
            # the first of them begun after the jump
            yield from ui.wait_until(lambda: st.serial > since and st.settled()
                                     and not st.pending
                                     and st.preview is not None,
                                     what="the refinement near the ground")
            yield from ui.redraw(2)
            assert not st.error, st.error
            shot = ui.screenshot(f"lod_method_{method.lower()}_{altitude:g}m.png")
            ground = ui.foreground(shot, background)[shot.shape[0] * 2 // 3:]
            print(f"{method} {altitude:g} m: {st.stats['visible']} patches, level "
                  f"{st.stats['max_level']}, ground {ground.mean():.1%} of the lowest third",
                  flush=True)
            assert ground.mean() > 0.98, (method, altitude, ground.mean())


ui.run(test)
