/* Planet LOD preview: the ground types of the render's planet material
 * (addon/planet_lod/terrain_shading.py) by the same rules, for planets with
 * an atmosphere: snow above a snow line that follows latitude and the
 * slope's aspect, rock on steep faces, scree and alpine meadow above the
 * tree line, sand at the shore, dark map greens lifted towards a meadow's
 * luminance close up, the detail field's crests lit and bare (rock, their
 * snow thinned by the wind) and its hollows darker.  The render's
 * small-scale textures (fields, canopy, rock blocks) are left out; one value
 * noise of ~300 m features breaks the snow line as the render's does. */

#ifdef PLOD_ATMOSPHERE
float ground_hash(vec3 cell)
{
  cell = fract(cell * 0.3183099 + vec3(0.71, 0.113, 0.419));
  cell *= 17.0;
  return fract(cell.x * cell.y * cell.z * (cell.x + cell.y + cell.z));
}

/* value noise in 0..1, cells one unit across (planet-space metres / scale:
 * at the Earth's radius float32 resolves about a five-hundredth of a cell
 * for cells of ~300 m) */
float ground_noise(vec3 x)
{
  vec3 i = floor(x);
  vec3 f = fract(x);
  f = f * f * (3.0 - 2.0 * f);
  float a = mix(ground_hash(i), ground_hash(i + vec3(1.0, 0.0, 0.0)), f.x);
  float b = mix(ground_hash(i + vec3(0.0, 1.0, 0.0)), ground_hash(i + vec3(1.0, 1.0, 0.0)), f.x);
  float c = mix(ground_hash(i + vec3(0.0, 0.0, 1.0)), ground_hash(i + vec3(1.0, 0.0, 1.0)), f.x);
  float d = mix(ground_hash(i + vec3(0.0, 1.0, 1.0)), ground_hash(i + vec3(1.0, 1.0, 1.0)), f.x);
  return mix(mix(a, b, f.y), mix(c, d, f.y), f.z);
}

/* The ground's albedo from the colour map's `base` at planet-space `point`
 * (local vertical `up`), shading normal `normal`, `height` metres above sea
 * level, the detail field's `ridge` (its height in units of its amplitude),
 * seen from `distance` metres. */
vec3 ground_types(vec3 base, vec3 point, vec3 up, vec3 normal, float height, float ridge,
                  float distance)
{
  float slope = degrees(acos(clamp(dot(normal, up), -1.0, 1.0)));
  float latitude = degrees(asin(clamp(up.z, -1.0, 1.0)));
  float lat_abs = abs(latitude);
  float near = 1.0 - smoothstep(3.0e3, 3.0e4, distance);
  float regional = 1.0 - smoothstep(6.0e4, 3.0e5, distance);
  float mid = ground_noise(point * (1.0 / 300.0));
  float coarse = ground_noise(point * (1.0 / 2500.0) + vec3(17.0));
  float crest = smoothstep(0.05, 0.6, ridge) * regional;
  float hollow = (1.0 - smoothstep(-0.3, 0.1, ridge)) * regional;
  /* the slope's tilt towards the nearer pole */
  vec3 north = vec3(0.0, 0.0, 1.0) - up * up.z;
  float poleward = dot(normal, north) / max(length(north), 1e-4) * (latitude < 0.0 ? -1.0 : 1.0);
  /* the render's lines (terrain_shading.SNOW_LINES, #defines from draw.py) */
  float subtropics = max(1.0 - pow((lat_abs - PLOD_SUBTROPICS_LATITUDE) *
                                   (1.0 / PLOD_SUBTROPICS_HALF_WIDTH), 2.0), 0.0);
  float snow_line = PLOD_SNOW_LINE_EQUATOR -
                    pow(lat_abs * (1.0 / 90.0), PLOD_SNOW_LINE_DROP_POWER) * PLOD_SNOW_LINE_POLAR_DROP +
                    subtropics * PLOD_SNOW_LINE_SUBTROPICS + (mid - 0.5) * 400.0 -
                    poleward * PLOD_SNOW_LINE_POLEWARD;
  float tree_line = snow_line - PLOD_TREE_LINE_BELOW_SNOW + (coarse - 0.5) * 300.0;
  float above_trees = height - tree_line;
  /* the map's dark greens (woods and their shade averaged in) lifted
   * towards a meadow's luminance close up, by at most 5 times */
  float luminance = max(dot(base, vec3(0.3, 0.6, 0.1)), 0.005);
  float lift = mix(1.0, clamp(0.1 / luminance, 1.0, 5.0), near);
  vec3 textured = base * (1.0 + (coarse - 0.5) * 0.5 * regional + (mid - 0.5) * 0.4 * near) *
                  (crest * 0.3 - hollow * 0.25 + 1.0);
  vec3 vegetation = textured * lift;
  vegetation = mix(vegetation, vegetation * vec3(0.95, 0.9, 0.7),
                   smoothstep(-150.0, 150.0, above_trees) * near * 0.6);
  float steep = smoothstep(28.0, 42.0, slope);
  float bare = max(steep, smoothstep(0.4, 0.8, ridge) * regional * 0.7);
  vec3 rock = vec3(0.34, 0.30, 0.25) * (0.8 + 0.4 * mid) * (crest * 0.3 + 1.0);
  float scree = max(smoothstep(18.0, 26.0, slope) * smoothstep(-300.0, 100.0, above_trees),
                    smoothstep(300.0, 800.0, above_trees)) * (1.0 - steep) * near;
  vec3 scree_colour = vec3(0.50, 0.47, 0.42) * (0.85 + 0.3 * mid);
  float snow = smoothstep(-150.0, 150.0, height - snow_line) * (1.0 - smoothstep(24.0, 38.0, slope)) *
               (1.0 - crest * 0.5);
  float shore = (1.0 - smoothstep(1.0, 4.0 + coarse * 4.0, height)) * (1.0 - steep);
  vec3 ground = mix(vegetation, scree_colour, scree);
  ground = mix(ground, rock, bare);
  ground = mix(ground, vec3(0.76, 0.70, 0.52), shore);
  ground = mix(ground, vec3(0.93, 0.95, 0.98) * (0.95 + 0.1 * mid), snow);
  return mix(textured, ground, max(near * 0.85, regional * 0.8) + 0.15 * steep);
}
#endif
