/* Planet LOD preview, fragment stage: the ground's colour from the
 * equirectangular colour map (or an elevation ramp, or the sector level),
 * lit as the render is by the scene's sun (Lambert on the core's normal;
 * a Blender sun of strength 1 lights a white surface facing it to 1) and shown through the scene's
 * exposure and view transform: the callback draws into display space.
 * The colour map is read at the mip level of the pixel's footprint
 * (textureGrad; the longitude derivative unwrapped across the date line);
 * its sRGB texels arrive encoded and are decoded here. */

#define PLOD_PI 3.14159265358979

vec3 level_colour(float level)
{
  float hue = fract(level * 0.137);
  vec3 k = clamp(abs(fract(hue + vec3(0.0, 2.0 / 3.0, 1.0 / 3.0)) * 6.0 - 3.0) - 1.0, 0.0, 1.0);
  return mix(vec3(1.0), k, 0.85);
}

vec3 srgb_to_linear(vec3 c)
{
  return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(vec3(0.04045), c));
}

vec3 linear_to_srgb(vec3 c)
{
  c = clamp(c, 0.0, 1.0);
  return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

/* The display value (sRGB-encoded, per channel, on the grey axis) of scene
 * radiance 2^(-12 + k/2), k = 0..40, through Blender's Filmic (3.x) and AgX
 * (4.x) views with no look, sampled from their OpenColorIO configurations. */
const float FILMIC[41] = float[41](0.0018, 0.0042, 0.0072, 0.0110, 0.0159, 0.0220, 0.0297, 0.0394, 0.0515, 0.0666, 0.0853, 0.1082, 0.1360, 0.1694, 0.2090, 0.2551, 0.3076, 0.3662, 0.4297, 0.4967, 0.5642, 0.6310, 0.6950, 0.7542, 0.8072, 0.8534, 0.8923, 0.9241, 0.9494, 0.9688, 0.9832, 0.9932, 0.9997, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000);
const float AGX[41] = float[41](0.0000, 0.0002, 0.0007, 0.0016, 0.0032, 0.0057, 0.0097, 0.0159, 0.0252, 0.0393, 0.0578, 0.0793, 0.1045, 0.1341, 0.1691, 0.2104, 0.2592, 0.3170, 0.3837, 0.4574, 0.5321, 0.6020, 0.6652, 0.7214, 0.7710, 0.8142, 0.8518, 0.8847, 0.9137, 0.9391, 0.9616, 0.9814, 0.9985, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000);

float view_curve(float x)
{
  float k = clamp((log2(max(x, 1e-6)) + 12.0) * 2.0, 0.0, 40.0);
  int i = min(int(k), 39);
  float f = k - float(i);
  if (view_transform == 1) {
    return mix(FILMIC[i], FILMIC[i + 1], f);
  }
  return mix(AGX[i], AGX[i + 1], f);
}

/* the scene's view transform: Standard (0, clipped), Filmic (1), AgX (2) */
vec3 view_transformed(vec3 radiance)
{
  if (view_transform == 0) {
    return linear_to_srgb(radiance);
  }
  return vec3(view_curve(radiance.r), view_curve(radiance.g), view_curve(radiance.b));
}

void main()
{
  vec3 n = normalize(v_dir);
  vec3 albedo;
  if (show_levels != 0) {
    albedo = srgb_to_linear(level_colour(v_level));
  }
  else if (v_sea > 0.8) {  /* ground the core lifted to the sea surface */
    albedo = vec3(0.004, 0.02, 0.06);  /* the render material's deep water */
  }
  else if (has_color != 0) {
    vec2 st = vec2(atan(n.y, n.x) / (2.0 * PLOD_PI) + 0.5, asin(clamp(n.z, -1.0, 1.0)) / PLOD_PI + 0.5);
    vec2 dx = dFdx(st), dy = dFdy(st);
    dx.x -= floor(dx.x + 0.5);
    dy.x -= floor(dy.x + 0.5);
    albedo = srgb_to_linear(textureGrad(color_map, st, dx, dy).rgb);
  }
  else {
    /* the render material's elevation ramp (scene-linear stops) */
    float t = clamp(v_height / max(height_scale, 1.0), 0.0, 1.0);
    albedo = t < 0.45 ? mix(vec3(0.18, 0.16, 0.14), vec3(0.55, 0.42, 0.3), t / 0.45) :
                        mix(vec3(0.55, 0.42, 0.3), vec3(0.92, 0.9, 0.88), (t - 0.45) / 0.55);
  }
  float cosine = max(dot(normalize(v_normal), normalize(sun.xyz)), 0.0);
  /* a little sky light keeps the night side readable */
  vec3 radiance = albedo * (sun.w * cosine + 0.02);
  FragColor = vec4(view_transformed(radiance * exposure), 1.0);
}
