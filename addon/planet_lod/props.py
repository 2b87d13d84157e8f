"""object.planet_lod: every planet setting as a bounded, annotated property."""
import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty,
                       IntProperty, PointerProperty, StringProperty)

from . import atmosphere, cameras, mappaths, placement, refresh, runtime
from .core import planets, presets

PROJECTION_ITEMS = [
    ("QSC", "QSC", "Quadrilateralized spherical cube (equal-area)"),
    ("TSC", "TSC", "Tangential spherical cube (gnomonic faces)"),
    ("CSC", "CSC", "COBE quadrilateralized spherical cube"),
    ("SPHERIFIED", "Spherified cube", "Normalised-cube mapping"),
    ("CAR", "Quad-sphere (CAR)", "Plate carree on an octahedral quad-sphere"),
]
TEMPLATE_ITEMS = [(str(4 ** k), f"{4 ** k}", f"{4 ** k} triangles per terrain patch")
                  for k in range(8)]


def _changed(self, context):
    runtime.mark_dirty(self.id_data, geometry=False)


def _geometry_changed(self, context):
    refresh.check_settings(self.id_data)  # a bad path shows in the panel at once
    # the material depends on radius/height scale (ramp) and projection (cube colour maps)
    runtime.mark_dirty(self.id_data, geometry=True, material=True)


def _wavelength(name, description):
    """A detail band's wavelength limit (0: off)."""
    return FloatProperty(name=name, default=0.0, min=0.0, soft_max=50000.0, subtype='DISTANCE',
                         unit='LENGTH', update=_geometry_changed, description=description)


def _material_changed(self, context):
    runtime.mark_dirty(self.id_data, geometry=False, material=True)


def _preview_changed(self, context):
    obj = self.id_data
    # the GPU preview draws the live LOD; the mesh (built for renders) shows as bounds
    obj.display_type = 'BOUNDS' if self.gpu_preview and not bpy.app.background else 'TEXTURED'
    _changed(self, context)


def _camera_clip_changed(self, context):
    cameras.apply_camera_clip(context.scene)
    _changed(self, context)


def _camera_poll(self, obj):
    return obj.type == 'CAMERA'


class PLOD_PG_inset(bpy.types.PropertyGroup):
    """One regional inset of a planet: a high-resolution height tile blended
    over the height map where it lies."""
    filepath: StringProperty(name="Inset", subtype='FILE_PATH', update=_geometry_changed,
                             description="A detailed height tile placed where it belongs on "
                                         "the planet: an SRTM tile named by its corner "
                                         "(N45E006.hgt) or a GeoTIFF with its longitude and "
                                         "latitude in its tags (WGS 84 degrees)")
    use_box: BoolProperty(name="Place by Box", default=False, update=_geometry_changed,
                          description="Give the tile's longitude and latitude yourself, for "
                                      "height images placed by neither their name nor their "
                                      "tags (the box runs through the corner pixels' centres)")
    west: FloatProperty(name="West", default=0.0, min=-180.0, max=180.0, precision=6,
                        update=_geometry_changed, description="Longitude of the left edge "
                                                              "(degrees east)")
    east: FloatProperty(name="East", default=1.0, min=-180.0, max=180.0, precision=6,
                        update=_geometry_changed, description="Longitude of the right edge "
                                                              "(degrees east)")
    south: FloatProperty(name="South", default=0.0, min=-90.0, max=90.0, precision=6,
                         update=_geometry_changed, description="Latitude of the bottom edge "
                                                               "(degrees north)")
    north: FloatProperty(name="North", default=1.0, min=-90.0, max=90.0, precision=6,
                         update=_geometry_changed, description="Latitude of the top edge "
                                                               "(degrees north)")
    scale: FloatProperty(name="Height", default=1.0, min=0.0, max=1.0e6, soft_max=1.0e4,
                         update=_geometry_changed,
                         description="Metres for the brightest value of an 8/16-bit image "
                                     "(read as 0 to 1); GeoTIFF heights are metres already "
                                     "and are multiplied by this")

    def as_entry(self):
        """The inset as planetlod.planets takes it: a path, or the path with its box."""
        path = mappaths.resolve(self.filepath)
        if not self.use_box:
            return path
        return dict(path=path, west=self.west, south=self.south, east=self.east,
                    north=self.north, scale=self.scale)


class PLOD_PG_settings(bpy.types.PropertyGroup):
    enabled: BoolProperty(name="Planet", description="This object is a Planet LOD planet",
                          default=False)
    preset: StringProperty(name="Preset", description="Planet preset this was made from")
    projection: EnumProperty(name="Projection", items=PROJECTION_ITEMS, default="QSC",
                             description="How the sphere is cut into six square faces "
                                         "(QSC keeps texel areas equal)",
                             update=_geometry_changed)
    radius: FloatProperty(name="Radius", description="Radius of the planet at height 0",
                          default=6371000.0, min=1.0, max=1.0e8, soft_max=1.0e7,
                          subtype='DISTANCE', unit='LENGTH', update=_geometry_changed)
    heightmap: StringProperty(name="Height Map", subtype='FILE_PATH',
                              description="Grey image of the terrain heights: a world map "
                                          "(2:1) or a cube cross (4:3). Empty: a smooth sphere",
                              update=_geometry_changed)
    height_scale: FloatProperty(name="Height Scale",
                                description="Height of the brightest pixel of the height map "
                                            "above the radius",
                                default=8848.0, min=0.0, max=1.0e6, soft_max=1.0e5,
                                subtype='DISTANCE', unit='LENGTH', update=_geometry_changed)
    heightmap_tiled: BoolProperty(name="Large Map", default=False, update=_geometry_changed,
                                  description="Read the height map a piece at a time instead "
                                              "of loading it whole, for world maps too big for "
                                              "memory (such as 86400 x 43200). The first use "
                                              "writes a tile file next to the map (its name "
                                              "plus .plodtiles, as big as the map) and keeps at "
                                              "most 128 MB of it in memory. Needed for maps "
                                              "over 268 million pixels (the panel says so); "
                                              "only for world maps (2:1)")
    insets: CollectionProperty(type=PLOD_PG_inset, name="Insets",
                               description="Detailed height tiles blended over the height map")
    inset_index: IntProperty(name="Active Inset", default=0, min=0)
    inset_feather: FloatProperty(name="Inset Blend", default=planets.INSET_FEATHER,
                                 min=0.0, max=0.5, subtype='FACTOR', update=_geometry_changed,
                                 description="Width of the border over which each inset "
                                             "blends into the height map, as a part of the "
                                             "inset's size (0: hard edges). Insets that touch "
                                             "join without a border")
    height_offset: FloatProperty(name="Height offset",
                                 description="Metres added to every map height (a datum: "
                                             "terrain below the radius, a sea floor)",
                                 default=0.0, min=-1.0e6, max=1.0e6, soft_min=-2.0e4,
                                 soft_max=2.0e4, subtype='DISTANCE', unit='LENGTH',
                                 update=_geometry_changed)
    height_signed: BoolProperty(name="Signed heights",
                                description="The map's 8/16-bit samples are signed (two's "
                                            "complement: sea floor below zero); they are "
                                            "then read as integer values",
                                default=False, update=_geometry_changed)
    use_sea_level: BoolProperty(name="Sea Level", default=False, update=_geometry_changed,
                                description="Flood the terrain below a sea level")
    sea_level: FloatProperty(name="Sea Level", description="Height of the sea above the radius",
                             default=0.0, min=-1.0e5, max=1.0e5, subtype='DISTANCE',
                             unit='LENGTH', update=_geometry_changed)
    ocean_sphere: BoolProperty(name="Ocean Sphere", description="Show a water sphere at sea level",
                               default=False, update=_material_changed)
    skip_sea: BoolProperty(name="Hide Sea Floor", default=False, update=_changed,
                           description="Leave out the terrain that lies entirely under the sea "
                                       "(faster with an ocean sphere)")
    use_detail: BoolProperty(name="Detail", default=False, update=_geometry_changed,
                             description="Procedural relief below the height map's resolution, "
                                         "down to the smallest feature; its amplitude follows "
                                         "the map (none on the sea, gentle on plains, rugged "
                                         "in mountains)")
    detail_style: EnumProperty(name="Style", items=presets.DETAIL_STYLE_ITEMS,
                               default="MOUNTAINS", update=_geometry_changed)
    detail_amplitude: FloatProperty(name="Amplitude", default=500.0, min=0.0, max=1e5,
                                    soft_max=5000.0, subtype='DISTANCE', unit='LENGTH',
                                    update=_geometry_changed,
                                    description="Height of the largest detail octave where "
                                                "the map's relief is strongest")
    detail_roughness: FloatProperty(name="Roughness", default=0.5, min=0.0, max=0.95,
                                    update=_geometry_changed,
                                    description="Amplitude ratio from one octave to the next "
                                                "(half the wavelength)")
    detail_smallest: FloatProperty(name="Smallest feature", default=0.1, min=0.001,
                                   soft_max=100.0, subtype='DISTANCE', unit='LENGTH',
                                   update=_geometry_changed,
                                   description="Wavelength of the finest octave")
    detail_craters: FloatProperty(name="Craters", default=0.0, min=0.0, max=4.0,
                                  update=_geometry_changed,
                                  description="Weight of the impact-crater layer")
    detail_plains: FloatProperty(name="Plains", default=0.15, min=0.0, max=1.0,
                                 update=_geometry_changed,
                                 description="Detail on flat land, relative to mountains")
    detail_relief: FloatProperty(name="Hill Relief", default=0.0, min=0.0, soft_max=2000.0,
                                 subtype='DISTANCE', unit='LENGTH', update=_geometry_changed,
                                 description="The map's local relief (largest height step to a "
                                             "neighbouring texel) at which land counts as hills; "
                                             "0: the 90th percentile over the land")
    detail_hills: FloatProperty(name="Hills", default=1.0, min=0.0, max=1.0,
                                update=_geometry_changed,
                                description="Detail on hills, relative to the steepest, "
                                            "highest mountains (1: hills are the top)")
    detail_highlands: FloatProperty(name="Highlands", default=0.0, min=0.0, soft_max=10000.0,
                                    subtype='DISTANCE', unit='LENGTH',
                                    update=_geometry_changed,
                                    description="Height above the sea at which steep ranges get "
                                                "the full detail, rising from Hills with "
                                                "elevation (0: off)")
    detail_fine_roughness: FloatProperty(name="Fine Roughness", default=0.5, min=0.0,
                                         max=0.95, update=_geometry_changed,
                                         description="Amplitude ratio from one octave to the "
                                                     "next below Fine Below (0.5 or less keeps "
                                                     "refinement near the ground affordable)")
    detail_fine_below: _wavelength("Fine Below", "Wavelength under which Fine Roughness "
                                                 "applies (0: Roughness everywhere)")
    detail_hills_fine: FloatProperty(name="Hills Fine Gain", default=1.0, min=1.0, max=16.0,
                                     update=_geometry_changed,
                                     description="Gain of the octaves below Hills Fine Below "
                                                 "on hills: real hills are rougher at a "
                                                 "kilometre for their broad relief than "
                                                 "ranges (1: off)")
    detail_hills_fine_below: _wavelength("Hills Fine Below", "Wavelength under which Hills "
                                                             "Fine Gain applies (0: off)")
    detail_hills_fine_to: _wavelength("Hills Fine To", "Wavelength down to which Hills Fine "
                                                       "Gain applies (0: the finest)")
    detail_seed: IntProperty(name="Seed", default=1, min=0, update=_geometry_changed)
    color_map: StringProperty(name="Colour Map", subtype='FILE_PATH',
                              description="Colour image of the surface: a world map (2:1) or a "
                                          "cube cross (4:3) in the planet's projection. Empty: "
                                          "colours by height",
                              update=_material_changed)
    lod_method: EnumProperty(name="LOD Method", default="HRTMR", update=_changed,
                             items=planets.LOD_METHOD_ITEMS,
                             description="How the terrain's patches are chosen: the seeds' "
                                         "methods side by side on the same surface")
    chunk_cracks: EnumProperty(name="Chunk Edges", default="STITCH", update=_changed,
                               description="How chunked LOD closes the gaps between chunks "
                                           "of different levels",
                               items=[("STITCH", "Stitched", "Edge variants that meet the "
                                       "coarser neighbour exactly (watertight)"),
                                      ("SKIRTS", "Skirts", "Strips hanging down from every "
                                       "chunk edge that hide the gaps")])
    geomipmap_tiles: EnumProperty(name="Tiles", default="16", update=_changed,
                                  items=[(str(2 ** k), str(2 ** k), "") for k in range(9)],
                                  description="Geomipmap tiles per cube-face edge: the finest "
                                              "detail is this times the patch density's cells")
    criterion: EnumProperty(name="Criterion", default="PIXEL", update=_changed,
                            description="How the add-on decides where the terrain needs detail",
                            items=[
        ("PIXEL", "Screen Error", "Add detail until the terrain is within a few pixels of "
                                  "the real shape on screen"),
        ("BORDERS", "Distance Ratio", "Add detail where a patch is large compared with its "
                                      "distance to the camera (split/merge borders)")])
    max_pixel_error: FloatProperty(name="Screen Error", default=2.0, min=0.1, max=64.0,
                                   subtype='PIXEL', update=_changed,
                                   description="Largest visible terrain error in pixels: "
                                               "lower is sharper and slower")
    split_border: FloatProperty(name="Split Ratio", default=0.5, min=0.01, max=10.0,
                                update=_changed,
                                description="A patch is divided when its size over its "
                                            "distance exceeds this")
    merge_border: FloatProperty(name="Merge Ratio", default=0.25, min=0.005, max=10.0,
                                update=_changed,
                                description="Divided patches join again when their size over "
                                            "distance falls below this")
    template_density: EnumProperty(name="Patch Density", items=TEMPLATE_ITEMS, default="64",
                                   description="Triangles in each terrain patch: more gives "
                                               "finer meshes with fewer patches",
                                   update=_changed)
    budget: IntProperty(name="Patch Budget",
                        description="Most terrain patches drawn at once (0: no limit); above "
                                    "it the whole view gets coarser, nothing is left out",
                        default=8000, min=0, max=1000000, update=_changed)
    max_level: IntProperty(name="Max Depth", default=0, min=0, max=48, update=_changed,
                           description="How many times a patch may be halved: limits the "
                                       "finest detail (0: automatic, from the planet's size "
                                       "and its smallest detail feature)")
    backface: BoolProperty(name="Skip Far Side", default=True, update=_changed,
                           description="Leave out the terrain behind the planet's horizon")
    frustum: BoolProperty(name="Skip Off-Screen", default=True, update=_changed,
                          description="Leave out the terrain outside the camera's view")
    lod_camera: EnumProperty(name="Viewport Detail For", default="VIEWPORT", update=_changed,
                             description="Whose view the detail in the viewport is made for. "
                                         "Renders always use the render camera",
                             items=[
        ("VIEWPORT", "Viewport", "The detail follows the view you are looking through"),
        ("SCENE", "Scene Camera", "Show the render camera's detail in the viewport (what F12 "
                                  "renders)"),
        ("CAMERA", "Chosen Camera", "Show the detail of the camera picked below")])
    camera: PointerProperty(name="Camera", type=bpy.types.Object, poll=_camera_poll,
                            update=_changed, description="Camera whose detail the viewport shows")
    freeze_lod: BoolProperty(name="Freeze Detail", default=False, update=_changed,
                             description="Keep the current detail while you fly around it; "
                                         "its camera's view is drawn in yellow")
    show_levels: BoolProperty(name="Show Levels", default=False, update=_material_changed,
                              description="Colour the terrain patches by their level of detail")
    morph: BoolProperty(name="Morphing", default=True, update=_changed,
                        description="Blend new detail in smoothly instead of popping: fine "
                                    "detail fades in with distance and new patches start "
                                    "as the coarser surface they replace (emission costs "
                                    "two to three times as much)")
    live_update: BoolProperty(name="Live Update", default=True, update=_changed,
                              description="Update the detail while you move the view")
    gpu_preview: BoolProperty(name="Fast Preview", default=True, update=_preview_changed,
                              description="Draw the planet on the GPU in the viewport (the "
                                          "mesh is then built for renders only)")
    clip_from_horizon: BoolProperty(name="Camera Clip to Horizon", default=True,
                                    update=_camera_clip_changed,
                                    description="Set the render camera's clip start and end "
                                                "from its height and the horizon, so the "
                                                "whole visible planet renders and no far side "
                                                "shows through (EEVEE)")
    view_clip_from_horizon: BoolProperty(name="Viewport Clip to Horizon", default=True,
                                         update=_changed,
                                         description="Keep the viewport's clip start and end "
                                                     "fitted to the planet as you navigate "
                                                     "(no far side showing through, no "
                                                     "clipped planet)")
    quality: EnumProperty(name="Quality", items=presets.QUALITY_ITEMS, default="PREVIEW")
    atmosphere: EnumProperty(name="Atmosphere", default="NONE", update=_material_changed,
                             items=atmosphere.ATMOSPHERE_ITEMS,
                             description="Sky and aerial perspective (the planet's world)")
    atmosphere_density: FloatProperty(name="Air density", default=1.0, min=0.0, max=100.0,
                                      soft_max=10.0, update=_material_changed,
                                      description="Scales the atmosphere's scattering")

    def as_dict(self):
        """The plain settings dict planetlod.planets works with (absolute file paths)."""
        return {
            "projection": self.projection, "radius": self.radius,
            "heightmap": mappaths.resolve(self.heightmap),
            "heightmap_tiled": self.heightmap_tiled,
            "insets": [i.as_entry() for i in self.insets if i.filepath],
            "inset_feather": self.inset_feather,
            "height_scale": self.height_scale, "height_offset": self.height_offset,
            "height_signed": self.height_signed, "use_sea_level": self.use_sea_level,
            "sea_level": self.sea_level, "skip_sea": self.skip_sea,
            "lod_method": self.lod_method, "chunk_cracks": self.chunk_cracks,
            "geomipmap_tiles": int(self.geomipmap_tiles),
            "criterion": self.criterion, "max_pixel_error": self.max_pixel_error,
            "split_border": self.split_border, "merge_border": self.merge_border,
            "template_level": template_level(self), "budget": self.budget,
            "max_level": self.max_level, "backface": self.backface, "frustum": self.frustum,
            "use_detail": self.use_detail, "detail_style": self.detail_style,
            "detail_amplitude": self.detail_amplitude,
            "detail_roughness": self.detail_roughness, "detail_smallest": self.detail_smallest,
            "detail_craters": self.detail_craters, "detail_plains": self.detail_plains,
            "detail_relief": self.detail_relief, "detail_hills": self.detail_hills,
            "detail_highlands": self.detail_highlands,
            "detail_fine_roughness": self.detail_fine_roughness,
            "detail_fine_below": self.detail_fine_below,
            "detail_hills_fine": self.detail_hills_fine,
            "detail_hills_fine_below": self.detail_hills_fine_below,
            "detail_hills_fine_to": self.detail_hills_fine_to,
            "detail_seed": self.detail_seed,
        }

    def assign(self, values):
        for key, value in values.items():
            setattr(self, key, value)


def _geo_changed(self, context):
    placement.place_geo_object(self.id_data, context.scene if context else None)


def _planet_poll(self, obj):
    return obj.type == 'MESH' and obj.planet_lod.enabled


class PLOD_PG_geo(bpy.types.PropertyGroup):
    """object.planet_lod_geo: places any object (a camera above all) on a planet by
    longitude, latitude, altitude, heading, pitch and roll, in float64, with the
    floating origin following it.  Animate east/north (metres) for smooth
    motion: float32 degrees step by about a metre on Earth."""
    enabled: BoolProperty(name="Place on planet", default=False, update=_geo_changed,
                          description="Place this object on a planet by longitude, "
                                      "latitude and altitude")
    planet: PointerProperty(name="Planet", type=bpy.types.Object, poll=_planet_poll,
                            update=_geo_changed)
    longitude: FloatProperty(name="Longitude", description="Degrees east", default=0.0,
                             min=-360.0, max=360.0, precision=6, update=_geo_changed)
    latitude: FloatProperty(name="Latitude", description="Degrees north", default=0.0,
                            min=-90.0, max=90.0, precision=6, update=_geo_changed)
    east: FloatProperty(name="East", description="Metres east of longitude/latitude, along "
                        "the surface (animate this, not the degrees, for smooth motion)",
                        default=0.0, unit='LENGTH', update=_geo_changed)
    north: FloatProperty(name="North", description="Metres north of longitude/latitude",
                         default=0.0, unit='LENGTH', update=_geo_changed)
    altitude: FloatProperty(name="Altitude", default=2.0, unit='LENGTH', update=_geo_changed,
                            description="Metres above the reference")
    altitude_reference: EnumProperty(name="Above", default="GROUND", update=_geo_changed, items=[
        ("GROUND", "Ground", "Altitude above the terrain under the object"),
        ("SEA", "Sea level", "Altitude above sea level (the radius without a sea)"),
        ("RADIUS", "Radius", "Altitude above the planet's radius")])
    heading: FloatProperty(name="Heading", description="Degrees from north towards east",
                           default=0.0, update=_geo_changed)
    pitch: FloatProperty(name="Pitch", description="Degrees above the horizon (-90: down)",
                         default=0.0, min=-90.0, max=90.0, update=_geo_changed)
    roll: FloatProperty(name="Roll", description="Degrees about the view direction",
                        default=0.0, update=_geo_changed)
    floating_origin: BoolProperty(name="Floating origin", default=True, update=_geo_changed,
                                  description="Move the planet so this object sits at the "
                                              "planet object's origin (full precision around "
                                              "it; use it on the render camera)")


def template_level(settings):
    return planets.template_level_from_density(int(settings.template_density))


# the settings that are single values (the insets are a list of entries)
SETTING_NAMES = [name for name in PLOD_PG_settings.__annotations__
                 if name not in ("insets", "inset_index")]
