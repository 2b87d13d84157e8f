"""Planet and quality presets (bpy-free data; applied by operators and preset files)."""

# Per planet: settings to assign to object.planet_lod; file names are looked up
# with the data_path the caller passes.  Radii in metres; height_scale = metres per unit of
# normalised map height (maps are 0..1).
PLANETS = {
    "EARTH": dict(label="Earth", radius=6371000.0, heightmap="earth-topology.png",
                  color_map="earth-blue-marble.jpg", height_scale=8848.0,
                  use_sea_level=True, sea_level=0.0, ocean_sphere=False,
                  projection="QSC", atmosphere="EARTH", use_detail=True,
                  detail_style="MOUNTAINS", detail_amplitude=4000.0, detail_roughness=0.65,
                  detail_craters=0.0, detail_plains=0.01, detail_relief=150.0,
                  detail_hills=0.25, detail_highlands=3500.0,
                  detail_fine_roughness=0.43, detail_fine_below=9000.0,
                  detail_hills_fine=4.0, detail_hills_fine_below=2500.0,
                  detail_hills_fine_to=500.0),
    "MOON": dict(label="Moon", radius=1737400.0, heightmap="lunar_bumpmap.jpg",
                 color_map="lunar_surface_2k.jpg", height_scale=19000.0,
                 use_sea_level=False, sea_level=0.0, ocean_sphere=False, projection="QSC",
                 atmosphere="NONE", use_detail=True, detail_style="CRATERS",
                 detail_amplitude=400.0, detail_roughness=0.5, detail_craters=1.0,
                 detail_plains=0.8),
    "MARS": dict(label="Mars-like (procedural)", radius=3389500.0,
                 heightmap="mars-like-height.png", color_map="mars-like-color.png",
                 height_scale=25000.0, use_sea_level=False, sea_level=0.0,
                 ocean_sphere=False, projection="QSC", atmosphere="MARS", use_detail=True,
                 detail_style="MOUNTAINS", detail_amplitude=1200.0, detail_roughness=0.5,
                 detail_craters=0.6, detail_plains=0.35),
    "ASTEROID": dict(label="Asteroid (procedural)", radius=20000.0,
                     heightmap="asteroid-height.png", color_map="", height_scale=6000.0,
                     use_sea_level=False, sea_level=0.0, ocean_sphere=False,
                     projection="QSC", atmosphere="NONE", use_detail=True,
                     detail_style="CRATERS", detail_amplitude=30.0, detail_roughness=0.5,
                     detail_craters=1.0, detail_plains=0.9),
}

PLANET_ITEMS = [(key, value["label"], f"{value['label']} planet preset")
                for key, value in PLANETS.items()]

# Quality: LOD tolerance and geometry budget.
QUALITY = {
    "DRAFT": dict(label="Draft", template_density="16", max_pixel_error=8.0, budget=2000),
    "PREVIEW": dict(label="Preview", template_density="64", max_pixel_error=3.0, budget=8000),
    "FINAL": dict(label="Final", template_density="256", max_pixel_error=1.0, budget=40000),
}

# Detail below the map's resolution (planetlod.Planet(detail=...)): styles
# and the settings each preset uses (above, detail_* keys).
DETAIL_STYLES = {"HILLS": "hills", "MOUNTAINS": "mountains", "CRATERS": "craters"}
DETAIL_STYLE_ITEMS = [
    ("HILLS", "Hills", "Rolling hills: gradient-noise octaves"),
    ("MOUNTAINS", "Mountains", "Ridged, eroded mountains: fine detail on ridges, smooth valleys"),
    ("CRATERS", "Craters", "Impact craters (bowl, rim, ejecta) over low hills, for airless "
                           "bodies"),
]
DETAIL_SEED = 1
# the detail settings presets may leave out, at their neutral values (the
# modulation's plains-to-hills law alone, one roughness for every octave)
DETAIL_LAW_DEFAULTS = dict(detail_relief=0.0, detail_hills=1.0, detail_highlands=0.0,
                           detail_fine_roughness=0.5, detail_fine_below=0.0,
                           detail_hills_fine=1.0, detail_hills_fine_below=0.0,
                           detail_hills_fine_to=0.0)


def detail_kwargs(settings):
    """planetlod.Planet(detail=...) for a settings dict (None when off)."""
    if not settings.get("use_detail"):
        return None
    return dict(style=DETAIL_STYLES[settings.get("detail_style", "MOUNTAINS")],
                amplitude=float(settings.get("detail_amplitude", 0.0)),
                roughness=float(settings.get("detail_roughness", 0.5)),
                smallest=float(settings.get("detail_smallest", 0.1)),
                craters=float(settings.get("detail_craters", 0.0)),
                plains=float(settings.get("detail_plains", 0.15)),
                relief=float(settings.get("detail_relief", 0.0)),
                hills=float(settings.get("detail_hills", 1.0)),
                highlands=float(settings.get("detail_highlands", 0.0)),
                fine_roughness=float(settings.get("detail_fine_roughness", 0.5)),
                fine_below=float(settings.get("detail_fine_below", 0.0)),
                hills_fine=float(settings.get("detail_hills_fine", 1.0)),
                hills_fine_below=float(settings.get("detail_hills_fine_below", 0.0)),
                hills_fine_to=float(settings.get("detail_hills_fine_to", 0.0)),
                seed=int(settings.get("detail_seed", DETAIL_SEED)))


def detail_settings(key):
    """planetlod.Planet(detail=...) of planet preset `key`."""
    return detail_kwargs(PLANETS[key])


QUALITY_ITEMS = [(key, value["label"], f"{value['label']} quality")
                 for key, value in QUALITY.items()]


def planet_settings(key, data_path):
    """Settings dict for planet preset `key`, with map names resolved by data_path."""
    values = dict(DETAIL_LAW_DEFAULTS)  # a preset without them resets them
    values.update(PLANETS[key])
    values.pop("label")
    values["heightmap"] = data_path(values["heightmap"]) if values["heightmap"] else ""
    values["color_map"] = data_path(values["color_map"]) if values["color_map"] else ""
    return values


def quality_settings(key):
    values = dict(QUALITY[key])
    values.pop("label")
    return values
