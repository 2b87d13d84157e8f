"""Planet and quality presets (bpy-free data; applied by operators and preset files)."""

# Per planet: settings to assign to object.planet_lod; file names are looked up
# with core.data_path().  Radii in metres; height_scale = metres per unit of
# normalised map height (maps are 0..1).
PLANETS = {
    "EARTH": dict(label="Earth", radius=6371000.0, heightmap="earth-topology.png",
                  color_map="earth-blue-marble.jpg", height_scale=8848.0,
                  use_sea_level=True, sea_level=0.0, ocean_sphere=False,
                  projection="QSC", atmosphere="EARTH"),
    "MOON": dict(label="Moon", radius=1737400.0, heightmap="lunar_bumpmap.jpg",
                 color_map="lunar_surface_2k.jpg", height_scale=19000.0,
                 use_sea_level=False, sea_level=0.0, ocean_sphere=False, projection="QSC",
                 atmosphere="NONE"),
    "MARS": dict(label="Mars-like (procedural)", radius=3389500.0,
                 heightmap="mars-like-height.png", color_map="mars-like-color.png",
                 height_scale=25000.0, use_sea_level=False, sea_level=0.0,
                 ocean_sphere=False, projection="QSC", atmosphere="MARS"),
    "ASTEROID": dict(label="Asteroid (procedural)", radius=20000.0,
                     heightmap="asteroid-height.png", color_map="", height_scale=6000.0,
                     use_sea_level=False, sea_level=0.0, ocean_sphere=False,
                     projection="QSC", atmosphere="NONE"),
}

PLANET_ITEMS = [(key, value["label"], f"{value['label']} planet preset")
                for key, value in PLANETS.items()]

# Quality: LOD tolerance and geometry budget.
QUALITY = {
    "DRAFT": dict(label="Draft", template_density="16", max_pixel_error=8.0, budget=2000),
    "PREVIEW": dict(label="Preview", template_density="64", max_pixel_error=3.0, budget=8000),
    "FINAL": dict(label="Final", template_density="256", max_pixel_error=1.0, budget=40000),
}

QUALITY_ITEMS = [(key, value["label"], f"{value['label']} quality")
                 for key, value in QUALITY.items()]


def planet_settings(key, data_path):
    """Settings dict for planet preset `key`, with map names resolved by data_path."""
    values = dict(PLANETS[key])
    values.pop("label")
    values["heightmap"] = data_path(values["heightmap"]) if values["heightmap"] else ""
    values["color_map"] = data_path(values["color_map"]) if values["color_map"] else ""
    return values


def quality_settings(key):
    values = dict(QUALITY[key])
    values.pop("label")
    return values
