/* Planet LOD preview, fragment stage (thesis 5.4.2): colour from the
 * equirectangular colour map, or an elevation ramp, or the sector level;
 * simple Lambert light from light_dir (planet space). */

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
    base = textureLod(color_map, st, 0.0).rgb;
  }
  else {
    float t = clamp(v_height / max(height_scale, 1.0), 0.0, 1.0);
    base = mix(vec3(0.18, 0.16, 0.14), vec3(0.92, 0.9, 0.88), t);
  }
  float light = 0.25 + 0.75 * max(dot(n, normalize(light_dir)), 0.0);
  FragColor = vec4(base * light, 1.0);
}
