"""A refresh's work in the core, free of bpy: refine for the LOD camera,
then the GPU preview's surface where the sectors in view changed.

The add-on runs it on Blender's main thread (renders, operators) or, for
the viewport's GPU preview, on a worker thread while the UI goes on; it
applies the results to Blender itself.  Here:

* `SurfaceWork`: one refresh's work and its results;
* `ProgressiveSplits`: how many splits one progressive viewport refresh
  may make, from how long the last ones took;
* `preview_key`: what a preview was emitted from (a preview with the same
  key is updated sector by sector instead of emitted anew);
* `mesh_digest`: a short digest of an emitted mesh, for tests and reports.
"""
import hashlib
import time

import numpy

from . import planets, surface


class ProgressiveSplits:
    """How many splits one progressive refresh of the viewport may make, so
    that a jump to a new place fills in over refreshes of about TARGET_MS
    each instead of one long one.  The least is START_NEW_VERTICES new
    vertices (2 sectors per split): cheap next to a refresh's fixed part
    (finding the sectors that changed, copying the preview).  A refresh
    that used its allowance and took less than TARGET_MS raises the next
    one by the ratio (at most 1.5 times), one that took longer lowers it
    (down to the least).  Without a budget (a view as large as it asks for) refreshes
    are not limited."""
    TARGET_MS = 12.0
    START_NEW_VERTICES = 16_000

    def __init__(self, template_level, budget):
        self.key = (int(template_level), int(budget))
        n = 2 ** int(template_level)
        per_sector = (n + 1) * (n + 2) // 2
        self.least = max(16, self.START_NEW_VERTICES // (2 * per_sector))
        self.splits = 0 if budget <= 0 else self.least

    def measured(self, stats, ms):
        """A refresh with this limit took `ms` (its refine's stats)."""
        if self.splits and stats.get("pending") and ms > 0.0:
            scale = min(1.5, max(0.5, self.TARGET_MS / ms))
            self.splits = max(self.least, int(self.splits * scale))


def preview_key(planet, template_level, origin, radius, sea_level, morph):
    """What a preview is emitted from: a later refresh with the same key may
    replace only the sectors that changed in it."""
    return (planet, template_level, origin, radius, sea_level, morph)


class SurfaceWork:
    """A refresh's work in the core -- refine for the LOD camera, then the
    preview's surface when the sectors in view changed -- touching nothing of
    bpy, so it can run on a worker thread while Blender's UI goes on; the
    caller applies the results on the main thread.

    preview: None, or (origin, radius, sea_level, morph, key, data): the
    anchor, the planet's radius and sea level (None: no sea), morphing, and
    the key and surface.PreviewData of the preview drawn now (None: none)."""

    def __init__(self, planet, settings, params, refine, for_render, check_size, preview,
                 max_splits=0):
        self.planet, self.settings, self.params = planet, settings, params
        self.refine, self.for_render, self.check_size = refine, for_render, check_size
        self.max_splits = max_splits  # > 0: a progressive refresh, later ones carry on
        self.ms = 0.0                 # the time run() took
        self.preview = preview
        self.stats = None       # the refine's stats (None when frozen)
        self.inside = False     # the LOD camera is below the terrain
        self.preview_key = None
        self.preview_data = None  # a new surface.PreviewData, or None when unchanged
        self.preview_serial = None  # unchanged: the mesh-cache emission it stays current at

    def run(self):
        t0 = time.perf_counter()
        try:
            self._run()
        finally:
            self.ms = (time.perf_counter() - t0) * 1000.0

    def _run(self):
        planet, settings = self.planet, self.settings
        if self.refine:
            camera = planets.make_camera(self.params)
            # without hysteresis (renders) the sector set and the order meshes
            # are emitted in depend on this camera only, never on earlier frames
            stats = planets.refine(planet, camera, settings, hysteresis=not self.for_render,
                                   max_splits=self.max_splits)
            if self.check_size:  # refuse before the mesh (or anything in bpy) is touched
                planets.check_mesh_size(stats, settings["template_level"])
            self.stats = stats
            self.inside = planets.camera_inside(planet, self.params["matrix_world"])
        if self.preview is None:
            return
        # the sectors in view (without morphing, which follows the eye) are
        # kept from refresh to refresh: a view that moves without a change
        # of what it sees keeps its preview, and one that changes some
        # sectors replaces those.  (Drawing every leaf instead, for turns
        # without a refresh, doubled the vertices to emit:
        # bench_viewport_detail.py)
        origin, radius, sea_level, morph, old_key, old_data = self.preview
        level = settings["template_level"]
        amplitude = planets.detail_amplitude(planet)
        if planets.lod_method(settings) != "hrtmr":
            # the other methods' patches are not copies of one template and
            # keep no cache: their whole mesh, drawn as one patch, under a key
            # no HRTMR preview has (which then starts whole again)
            self.preview_key = (planets.lod_method(settings),
                                preview_key(planet, level, origin, radius, sea_level, morph))
            visible = planet.mesh(template_level=level, morph=morph)
            self.preview_data = surface.preview_data(visible, origin, radius, sea_level,
                                                     whole=True, detail_amplitude=amplitude)
            return
        ids = numpy.frombuffer(planet.sector_ids(visible_only=True), numpy.uint64)
        self.preview_key = preview_key(planet, level, origin, radius, sea_level, morph)
        if morph:  # the morph moves every vertex with the eye
            visible = planet.mesh(template_level=level, morph=True)
            self.preview_data = surface.preview_data(visible, origin, radius, sea_level,
                                                     detail_amplitude=amplitude)
        elif (self.preview_key == old_key and old_data is not None and
              old_data.serial == planet.mesh_cache_info["emissions"]):
            # the planet's last mesh was this preview's: only what changed
            # since (new sectors, corner normals of another band) is
            # emitted, and replaced in a copy of the preview
            changed = planet.mesh(template_level=level, changed_only=True)
            serial = planet.mesh_cache_info["emissions"]
            if changed.sector_count or len(ids) != old_data.sectors:
                self.preview_data = surface.preview_update(old_data, changed, ids, origin,
                                                           radius, sea_level, amplitude)
                self.preview_data.serial = serial
            else:  # (applied on the main thread: the viewport may be drawing it)
                self.preview_serial = serial
        else:
            visible = planet.mesh(template_level=level)
            self.preview_data = surface.preview_data(visible, origin, radius, sea_level,
                                                     detail_amplitude=amplitude)
            self.preview_data.serial = planet.mesh_cache_info["emissions"]


def mesh_digest(mesh):
    """16 hex digits of a mesh's positions, triangles, sector levels and origin."""
    h = hashlib.sha1()
    for part in (mesh.positions, mesh.triangles, mesh.sector_level):
        h.update(bytes(memoryview(part).cast("B")))
    h.update(repr(tuple(mesh.origin)).encode())
    return h.hexdigest()[:16]
