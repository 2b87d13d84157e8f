"""Ground shading below the colour map's resolution: rock, scree, snow,
woods, farmland and shore from per-vertex height, slope, latitude, aspect and
the core's detail field, textured in planet-anchored coordinates (the planet
material's colour, addon/planet_lod/materials.py)."""


# The snow line and the tree line (metres; see ground_types), shared with the
# viewport's ground types (shaders/planet_ground_types.glsl) as #defines.
SNOW_LINES = dict(
    SNOW_LINE_EQUATOR=5200.0,
    SNOW_LINE_POLAR_DROP=5400.0,    # lower towards the poles by (|latitude| / 90)^1.4 of it
    SNOW_LINE_DROP_POWER=1.4,
    SNOW_LINE_SUBTROPICS=1500.0,    # higher in the dry subtropics, most at 27 degrees
    SUBTROPICS_LATITUDE=27.0,
    SUBTROPICS_HALF_WIDTH=13.0,
    SNOW_LINE_POLEWARD=700.0,       # lower on faces turned to the pole
    TREE_LINE_BELOW_SNOW=900.0)


def glsl_defines():
    """SNOW_LINES as GLSL #defines (PLOD_ + name)."""
    return "".join(f"#define PLOD_{name} {value!r}\n" for name, value in SNOW_LINES.items())


def attribute(b, name):
    node = b.node("ShaderNodeAttribute")
    node.attribute_type = 'GEOMETRY'
    node.attribute_name = name
    return node


def _noise(b, coords, scale, detail=4.0):
    node = b.node("ShaderNodeTexNoise")
    node.noise_dimensions = '3D'
    b.link(coords, node.inputs["Vector"])
    node.inputs["Scale"].default_value = scale
    node.inputs["Detail"].default_value = detail
    node.inputs["Roughness"].default_value = 0.55
    return b.socket(node.outputs["Fac"], vector=False)


def _parcels(b, coords, scale, edges=True):
    """(a random value per cell, another, the distance to the cell's edge in
    cells, or None) of a Voronoi tessellation of `coords` into cells 1/scale
    across."""
    cells = b.node("ShaderNodeTexVoronoi")
    cells.voronoi_dimensions = '3D'
    cells.feature = 'F1'
    cells.distance = 'EUCLIDEAN'
    b.link(coords, cells.inputs["Vector"])
    cells.inputs["Scale"].default_value = scale
    value, other, _ = b.split(b.socket(cells.outputs["Color"]))
    if not edges:
        return value, other, None
    edges = b.node("ShaderNodeTexVoronoi")
    edges.voronoi_dimensions = '3D'
    edges.feature = 'DISTANCE_TO_EDGE'
    b.link(coords, edges.inputs["Vector"])
    edges.inputs["Scale"].default_value = scale
    return value, other, b.socket(edges.outputs["Distance"], vector=False)


# crops by a parcel's random value (0..1, shifted up in dry regions): green,
# ripe, ploughed soil, fallow; multipliers of the colour map's colour whose
# mean is about one, so the farmland averages to the map seen from afar
CROP_TINTS = ((0.0, (0.72, 0.95, 0.58)), (0.35, (1.30, 1.16, 0.82)),
              (0.62, (1.02, 0.82, 0.62)), (0.84, (1.05, 1.02, 0.90)))
# land use by a region's random value: forest, cropland, dry scrub and
# pasture (likewise about one on average)
REGION_TINTS = ((0.0, (0.50, 0.62, 0.45)), (0.3, (1.0, 1.0, 1.0)),
                (0.62, (1.40, 1.25, 0.95)), (0.85, (1.1, 1.12, 0.9)))


def _tint(b, table, value):
    tint = b.const(table[0][1])
    for start, colour in table[1:]:
        tint = b.mix(tint, b.const(colour), b.less(start, value))
    return tint


def ground_types(b, s, base, normal, airless):
    """Ground colour below the colour map's resolution: rock on steep slopes and
    bare crests, snow above a latitude-dependent snow line, sand at the shore,
    vegetation tinted by the colour map: woods in hollows and on hillsides,
    farmland parcels of a few hundred metres on flat lowland, regolith on
    airless bodies; by per-vertex height, slope, latitude and the core's
    detail field (`planet_detail`: its ridges and hollows, which the colour map
    cannot show), textured by noise in planet-anchored coordinates.  The
    detail field's ridges and hollows, the land-use regions and the far
    farmland show within 300 km of the camera, the fields and the other
    ground types within 30-40 km (the colour map rules beyond).  Returns
    (colour, relief for the bump)."""
    height = b.socket(attribute(b, "planet_height").outputs["Fac"], vector=False)
    slope = b.socket(attribute(b, "planet_slope").outputs["Fac"], vector=False)
    latitude = b.socket(attribute(b, "planet_latitude").outputs["Fac"], vector=False)
    field = b.socket(attribute(b, "planet_detail").outputs["Fac"], vector=False)
    coords = b.node("ShaderNodeTexCoord")
    detail = b.socket(coords.outputs["Object"]) + b.input_vector("plod_detail_offset")
    camera_data = b.node("ShaderNodeCameraData")
    distance = b.socket(camera_data.outputs["View Distance"], vector=False)
    fades = {}

    def fade(reach):  # 1 within a tenth of `reach`, 0 beyond it (one set of nodes each)
        if reach not in fades:
            fades[reach] = 1.0 - b.smoothstep(0.1 * reach, reach, distance)
        return fades[reach]
    # five octaves of ground texture, each faded in where the colour map's
    # 10 km texels are magnified enough for it to show (about 6 cm, 0.8 m,
    # 11 m, 250 m and 3.3 km features, seen within 25 m, 0.2, 3, 30 and 200 km)
    grit = _noise(b, detail, 16.0, detail=3.0)
    fine = _noise(b, detail, 1.3)
    mid = _noise(b, detail, 0.09)
    coarse = _noise(b, detail, 0.004)
    broad = _noise(b, detail, 0.0003)
    grain = 1.0
    for noise, amount, reach in ((grit, 1.6, 25.0), (fine, 1.2, 200.0), (mid, 1.4, 3000.0),
                                 (coarse, 1.6, 3.0e4),
                                 (broad, 1.4, 2.0e5)):
        grain = (noise - 0.5) * (fade(reach) * amount) + grain
    near = fade(3.0e4)
    regional = 1.0 - b.smoothstep(6.0e4, 3.0e5, distance)
    # the detail field in units of its first octave's amplitude: crests
    # (up to ~0.8) lit and bare, hollows (below 0) darker
    amplitude = s.detail_amplitude if s.use_detail and s.detail_amplitude > 0.0 else 1.0
    ridge = field * (1.0 / amplitude)
    crest = b.smoothstep(0.05, 0.6, ridge) * regional
    hollow = (1.0 - b.smoothstep(-0.3, 0.1, ridge)) * regional
    bump = fine * fade(200.0) + grit * (fade(25.0) * 0.3)  # relief for the Bump node
    rock = (0.30, 0.28, 0.26)  # regolith on airless bodies
    textured = base * grain * (crest * 0.3 - hollow * 0.25 + 1.0)
    if airless:  # fresh ejecta on crests, older darker regolith in hollows
        ground = b.mix(textured, b.const(rock) * grain,
                       b.smoothstep(30.0, 45.0, slope) * near * 0.5)
        return ground, bump
    # the colour map's own green against its browns: farmland and woods follow
    # the region's climate (green crops and woods where the map is green)
    base_r, base_g, _ = b.split(base)
    green = b.smoothstep(-0.02, 0.03, base_g - base_r)
    # the snow line (5,200 m at the equator, highest in the dry subtropics,
    # ~5,600 m at 20-30 degrees: the Himalaya, the Andes' Puna; falling to
    # ~3,000 m in the Alps and towards the poles; R. F. Flint, "Glacial and
    # Quaternary Geology", Wiley, 1971), lower on poleward faces, which the
    # sun barely reaches, and the tree line
    # ~900 m below it (C. Körner, "Alpine Treelines", Springer, 2012: a
    # growing-season isotherm, 3,500-4,000 m in the tropics, ~2,000 m in
    # the Alps)
    lat_abs = b.math("ABSOLUTE", latitude)
    poleward = _poleward_facing(b, normal, latitude)
    k = SNOW_LINES
    subtropics = b.maximum(1.0 - b.power((lat_abs - k["SUBTROPICS_LATITUDE"]) * (
        1.0 / k["SUBTROPICS_HALF_WIDTH"]), 2.0), 0.0)
    snow_line = k["SNOW_LINE_EQUATOR"] - b.power(
        lat_abs * (1.0 / 90.0), k["SNOW_LINE_DROP_POWER"]) * k["SNOW_LINE_POLAR_DROP"] + \
        subtropics * k["SNOW_LINE_SUBTROPICS"] + (mid - 0.5) * 400.0 - \
        poleward * k["SNOW_LINE_POLEWARD"]
    tree_line = snow_line - k["TREE_LINE_BELOW_SNOW"] + (coarse - 0.5) * 300.0
    below_trees = 1.0 - b.smoothstep(-150.0, 150.0, height - tree_line)
    # woods: soft-edged stands, gathered in hollows and on hillsides, below
    # the tree line
    cover = broad + (coarse - 0.5) * fade(4.0e4) + (mid - 0.5) * (fade(3000.0) * 0.7) + \
        hollow * 0.35 + b.smoothstep(8.0, 20.0, slope) * 0.12
    woods = b.smoothstep(0.5, 0.62, cover - green * 0.08) * (green * 0.5 + 0.4) * fade(2.5e5) \
        * below_trees
    # farmland on flat lowland: parcels of one crop each (Voronoi cells, a
    # random value per cell picks green, ripe, ploughed or fallow), a few
    # hundred metres across, in holdings of a few kilometres seen from afar,
    # with field margins close up
    flat = (1.0 - b.smoothstep(5.0, 12.0, slope)) * (1.0 - b.smoothstep(800.0, 2500.0, height))
    aridity = (1.0 - green) * 0.25
    near_parcels, near_brightness, near_edge = _parcels(b, detail, 1.0 / 350.0)
    far_parcels, far_brightness, _ = _parcels(b, detail, 1.0 / 2500.0, edges=False)
    near_crop = _tint(b, CROP_TINTS, near_parcels + aridity) * (near_brightness * 0.35 + 0.82)
    far_crop = _tint(b, CROP_TINTS, far_parcels + aridity) * (far_brightness * 0.7 + 0.65)
    crop = b.mix(b.mix(b.const((1.0, 1.0, 1.0)), far_crop, fade(2.5e5)), near_crop,
                 fade(4.0e4))
    margin = (1.0 - b.smoothstep(0.008, 0.02, near_edge)) * fade(5000.0)
    crop = b.mix(crop, b.const((0.5, 0.6, 0.42)), margin * 0.8)
    # land use in regions of a few kilometres with irregular borders: the
    # texture of a plain seen from 20 to 300 km up, where fields blur
    warp = b.node("ShaderNodeTexNoise")
    warp.noise_dimensions = '3D'
    b.link(detail, warp.inputs["Vector"])
    warp.inputs["Scale"].default_value = 1.0 / 4000.0
    warp.inputs["Detail"].default_value = 3.0
    warped = detail + (b.socket(warp.outputs["Color"]) - (0.5, 0.5, 0.5)) * 6000.0
    region, _, _ = _parcels(b, warped, 1.0 / 6000.0, edges=False)
    land_use = b.mix(b.const((1.0, 1.0, 1.0)), _tint(b, REGION_TINTS, region + aridity),
                     fade(3.0e5))
    farmland = flat * (1.0 - woods)
    # the colour map is ground seen from orbit, woods and their shade
    # averaged in, and dark where green (Alpine green ~0.02): close up,
    # dark ground is lifted towards a meadow's luminance (~0.1: grass
    # reflects ~0.1 in green), by at most 5 times
    luminance = b.maximum(b.dot(base, (0.3, 0.6, 0.1)), 0.005)
    lift = b.minimum(b.maximum(b.math("DIVIDE", 0.1, luminance), 1.0), 5.0)
    lift = (lift - 1.0) * near + 1.0
    vegetation = textured * land_use * lift
    vegetation = b.mix(vegetation, vegetation * crop, farmland)
    # a canopy: crowns ~8 m across with dark gaps between them (the texture
    # that tells woods from meadows from 2 km), darker stands seen from afar
    crowns, _, gaps = _parcels(b, detail, 1.0 / 8.0)
    canopy = (crowns * 0.35 + 0.75) * (b.smoothstep(0.0, 0.25, gaps) * 0.6 + 0.4)
    canopy = b.mix(b.const(0.8), canopy, fade(4000.0))
    vegetation = b.mix(vegetation, textured * (lift * 0.6) * (0.9, 1.1, 0.8) * canopy, woods)
    # above the tree line: alpine meadow, yellower, thinning out to stone
    alpine = (1.0 - below_trees) * near
    vegetation = b.mix(vegetation, vegetation * (0.95, 0.9, 0.7), alpine * 0.6)
    steep = b.smoothstep(28.0, 42.0, slope)
    bare = b.maximum(steep, b.smoothstep(0.4, 0.8, ridge) * regional * 0.7)
    # rock: grey-brown stone in blocks (the canopy's cells) with dark joints
    # between them, banded by strata ~15 m thick, warped; the blocks and
    # bands show within a few kilometres (finer than a pixel beyond)
    strata = b.math("SINE", height * 0.42 + mid * 9.0)
    blocks = (crowns * 0.4 + 0.8) * (b.smoothstep(0.0, 0.06, gaps) * 0.45 + 0.55) * \
        (strata * 0.15 + 1.0)
    rock_colour = b.const((0.34, 0.30, 0.25)) * (grain * 0.6 + 0.4) * (crest * 0.3 + 1.0) * \
        ((blocks - 1.0) * fade(4000.0) + 1.0)
    # scree: pale debris on the moderate slopes under rock walls, high up,
    # and the moraine and rubble that cover the ground well above the trees
    above_trees = height - tree_line
    scree = b.maximum(b.smoothstep(18.0, 26.0, slope) * b.smoothstep(-300.0, 100.0, above_trees),
                      b.smoothstep(300.0, 800.0, above_trees)) * (1.0 - steep) * near
    scree_colour = b.const((0.50, 0.47, 0.42)) * (grain * 0.35 + 0.65)
    # snow: above the snow line, gone from slopes steeper than ~35 degrees
    # (a steep face shows rock, a ridge above it snow) and thinner on the
    # detail field's crests, which the wind scours
    snow = b.smoothstep(-150.0, 150.0, height - snow_line) * \
        (1.0 - b.smoothstep(24.0, 38.0, slope)) * (1.0 - crest * 0.5)
    shore = (1.0 - b.smoothstep(1.0, 4.0 + coarse * 4.0, height)) * (1.0 - steep)
    sand = b.const((0.76, 0.70, 0.52)) * (grain * 0.25 + 0.75)
    ground = b.mix(vegetation, scree_colour, scree)
    ground = b.mix(ground, rock_colour, bare)
    ground = b.mix(ground, sand, shore)
    ground = b.mix(ground, b.const((0.93, 0.95, 0.98)) * (grain * 0.1 + 0.9), snow)
    # the colour map's own colour from afar; the ground types close up and,
    # within the detail field's reach, on its crests and in its hollows
    return b.mix(textured, ground, b.maximum(near * 0.85, regional * 0.8) + 0.15 * steep), bump


def _poleward_facing(b, normal, latitude):
    """The shading normal's tilt towards the nearer pole: sin(slope) times
    the cosine of the slope's aspect from the pole (0 on flat ground and
    east/west faces).  Planet axes are world axes (the planet object is not
    rotated); the local vertical is the direction from the planet's centre."""
    geometry = b.node("ShaderNodeNewGeometry")
    up = b.normalize(b.socket(geometry.outputs["Position"]) + b.input_vector("plod_anchor"))
    _, _, up_z = b.split(up)
    north = (0.0, 0.0, 1.0) - up * up_z  # the pole axis in the tangent plane
    towards_north = b.dot(normal, north) / b.maximum(b.length(north), 1e-4)
    hemisphere = 1.0 - b.less(latitude, 0.0) * 2.0
    return towards_north * hemisphere


def water(b, normal):
    """Principled water: low roughness (sun glint), tinted by depth where the
    height map has bathymetry."""
    depth = b.socket(attribute(b, "planet_sea_depth").outputs["Fac"], vector=False)
    deep = 1.0 - b.exp(depth * (-1.0 / 40.0))
    colour = b.mix(b.const((0.02, 0.10, 0.14)), b.const((0.004, 0.02, 0.06)), deep * 0.8 + 0.2)
    water = b.node("ShaderNodeBsdfPrincipled")
    b.link(colour, water.inputs["Base Color"])
    water.inputs["Roughness"].default_value = 0.07
    water.inputs["IOR"].default_value = 1.33
    b.link(normal, water.inputs["Normal"])
    return water
