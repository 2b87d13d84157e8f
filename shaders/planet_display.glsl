/* Planet LOD preview: how a radiance reaches the screen (the scene's view
 * transform on the grey axis, sRGB encoding), shared by the planet's and
 * the sky's preview shaders (uniform `display`: 4 * view transform + ...). */

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
  if (display / 4 == 1) {
    return mix(FILMIC[i], FILMIC[i + 1], f);
  }
  return mix(AGX[i], AGX[i + 1], f);
}

/* the scene's view transform (display / 4): Standard (0, clipped), Filmic
 * (1), AgX (2) */
vec3 view_transformed(vec3 radiance)
{
  if (display / 4 == 0) {
    return linear_to_srgb(radiance);
  }
  return vec3(view_curve(radiance.r), view_curve(radiance.g), view_curve(radiance.b));
}

