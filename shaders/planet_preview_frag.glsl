/* Planet LOD preview, fragment stage (thesis 5.4.2): colour from the
 * equirectangular colour map, or an elevation ramp, or the sector level;
 * Lambert light from light_dir (planet space) on the terrain's normal (from
 * the height atlas, per vertex), so relief shows at any LOD.
 * The colour map is read at the mip level of the pixel's footprint
 * (textureGrad; the longitude derivative unwrapped across the date line). */

vec3 level_colour(float level)
{
  float hue = fract(level * 0.137);
  vec3 k = clamp(abs(fract(hue + vec3(0.0, 2.0 / 3.0, 1.0 / 3.0)) * 6.0 - 3.0) - 1.0, 0.0, 1.0);
  return mix(vec3(1.0), k, 0.85);
}

void main()
{
  vec3 n = normalize(v_dir);
  vec3 base;
  if (show_levels != 0) {
    base = level_colour(floor(v_level + 0.5));
  }
  else if (has_color != 0) {
    vec2 st = vec2(atan(n.y, n.x) / (2.0 * PLOD_PI) + 0.5, asin(clamp(n.z, -1.0, 1.0)) / PLOD_PI + 0.5);
    vec2 dx = dFdx(st), dy = dFdy(st);
    dx.x -= floor(dx.x + 0.5);
    dy.x -= floor(dy.x + 0.5);
    base = textureGrad(color_map, st, dx, dy).rgb;
  }
  else {
    float t = clamp(v_height / max(height_scale, 1.0), 0.0, 1.0);
    base = mix(vec3(0.18, 0.16, 0.14), vec3(0.92, 0.9, 0.88), t);
  }
  vec3 shade = has_height != 0 ? normalize(v_normal) : n;
  float light = 0.15 + 0.85 * max(dot(shade, normalize(light_dir)), 0.0);
  FragColor = vec4(base * light, 1.0);
}
