/* Planet LOD preview, fragment stage: the ground's colour from the
 * equirectangular colour map (or an elevation ramp, or the sector level),
 * lit as the render is by the scene's sun (Lambert on the core's normal; a
 * Blender sun of strength 1 lights a white surface facing it to 1), seen
 * through the haze and shown through the scene's exposure and view
 * transform; written for a framebuffer that encodes to sRGB itself where
 * Blender says so (srgbTarget, as its own shaders do).
 * The haze (with PLOD_ATMOSPHERE and its constants defined, draw.py): the
 * render material's aerial perspective (atmosphere.py: single scattering,
 * Rayleigh + Mie, optical depths by Schüler's approximation of the Chapman
 * function), per pixel: a flat sea's triangles span kilometres of haze.
 * The colour map is read at full resolution, averaged over the pixel's
 * footprint (from the viewer's distance and slant);
 * an sRGB texture's texels arrive decoded (scene-linear). */

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

#ifdef PLOD_ATMOSPHERE
/* U(r, mu), mu >= 0: optical depth / (beta H) to space; below the radius
 * counts as on it */
float up_term(float r, float mu, float height)
{
  float c = sqrt(r * (PLOD_PI / 2.0 / height));
  return c / (c * mu + 1.0) * exp(min((r - ATM_RADIUS) * (-1.0 / height), 0.0));
}

/* a whole ray through its closest approach r0 */
float grazing(float r0, float height, float limit)
{
  return sqrt(r0 * (PLOD_PI / 2.0 / height)) * 2.0 *
         exp(min((r0 - ATM_RADIUS) * (-1.0 / height), limit));
}

float to_space(float r, float mu, float r0, float height)
{
  float down = mu < 0.0 ? 1.0 : 0.0;
  return (1.0 - 2.0 * down) * up_term(r, abs(mu), height) + down * grazing(r0, height, 30.0);
}

/* depth / (beta H) between the camera and the point, along d */
float segment_depth(vec3 cam, vec3 point, vec3 d, float height)
{
  float r_c = length(cam), r_p = length(point);
  float mu_c = dot(cam / r_c, d), mu_p = dot(point / r_p, d);
  float r0 = r_c * sqrt(max(1.0 - mu_c * mu_c, 0.0));
  float down_c = mu_c < 0.0 ? 1.0 : 0.0, down_p = mu_p < 0.0 ? 1.0 : 0.0;
  float up_c = up_term(r_c, abs(mu_c), height) * (1.0 - down_c * 2.0);
  float up_p = up_term(r_p, abs(mu_p), height) * (1.0 - down_p * 2.0);
  return max(up_c - up_p + abs(down_c - down_p) * grazing(r0, height, 0.0), 0.0);
}

void aerial_perspective(vec3 point, out vec3 inscatter, out float haze)
{
  vec3 cam = camera.xyz;
  vec3 view = point - cam;
  vec3 d = view / max(length(view), 1e-3);
  float depth_r = segment_depth(cam, point, d, ATM_RAYLEIGH_HEIGHT);
  float depth_m = segment_depth(cam, point, d, ATM_MIE_HEIGHT);
  float r = length(point);
  float mu = dot(point / r, sun.xyz);
  float r0 = r * sqrt(max(1.0 - mu * mu, 0.0));
  float sun_r = to_space(r, mu, r0, ATM_RAYLEIGH_HEIGHT);
  float sun_m = to_space(r, mu, r0, ATM_MIE_HEIGHT);
  float cos_sun = dot(d, sun.xyz);
  float g = ATM_MIE_G, g2 = g * g;
  float phase_r = (cos_sun * cos_sun + 1.0) * (3.0 / (16.0 * PLOD_PI));
  float phase_m = (cos_sun * cos_sun + 1.0) * (3.0 / (8.0 * PLOD_PI) * (1.0 - g2) / (2.0 + g2)) /
                  pow(max(cos_sun * (-2.0 * g) + (1.0 + g2), 1e-4), 1.5);
  vec3 tau_r = ATM_RAYLEIGH * ATM_RAYLEIGH_HEIGHT * depth_r;
  vec3 tau_m = ATM_MIE * (ATM_MIE_HEIGHT * 1.11) * depth_m;  /* Mie extinction */
  vec3 tau = max(tau_r + tau_m, vec3(1e-7));
  vec3 scattered = tau_r * phase_r + ATM_MIE * ATM_MIE_HEIGHT * depth_m * phase_m;
  vec3 transmittance = exp(-tau);
  vec3 sun_tau = ATM_RAYLEIGH * ATM_RAYLEIGH_HEIGHT * sun_r + ATM_MIE * (ATM_MIE_HEIGHT * 1.11) * sun_m;
  vec3 sunlight = exp(-sun_tau) * sun.w;
  inscatter = scattered / tau * (vec3(1.0) - transmittance) * sunlight * ATM_GAIN;
  haze = dot(transmittance, vec3(0.3, 0.6, 0.1));  /* luminance-weighted */
}
#endif

void main()
{
  vec3 n = normalize(v_point);
  vec3 albedo;
  int shading = display % 4;
  if (shading == SHADING_LEVELS) {
    albedo = srgb_to_linear(level_colour(floor(v_level + 0.5)));
  }
  else if (shading == SHADING_COLOR_MAP) {  /* the sea's colour included */
    vec2 st = vec2(atan(n.y, n.x) / (2.0 * PLOD_PI) + 0.5, asin(clamp(n.z, -1.0, 1.0)) / PLOD_PI + 0.5);
    /* The map's full resolution only, averaged over the pixel's footprint
     * by four taps where the map is minified.  Its mip levels, read through
     * llvmpipe's sampler (textureGrad or textureLod), gave dots of a far
     * coarser colour along lines of the view: triangle edges, and the
     * boundaries between levels.  The footprint comes from the view, not
     * from screen-space derivatives: across the view (pixel_size: radians
     * per pixel, or minus planet-space metres per pixel when orthographic),
     * stretched along the ground by the view's slant, in map rows (the map
     * spans pi in latitude; a row is as wide in longitude at the equator). */
    vec3 to_eye = camera.xyz - v_point;
    float across = pixel_size > 0.0 ? length(to_eye) * pixel_size : -pixel_size;
    float slant = max(abs(dot(n, normalize(to_eye))), 0.05);
    vec2 size = vec2(textureSize(color_map, 0));
    float rows = across / slant / length(v_point) * size.y / PLOD_PI;
    float spread = 0.25 * clamp(rows, 0.0, 32.0);
    vec2 tap = vec2(spread / (2.0 * size.y * max(length(n.xy), 0.05)), spread / size.y);
    albedo = 0.25 * (textureLod(color_map, st + vec2(tap.x, 0.5 * tap.y), 0.0).rgb +
                     textureLod(color_map, st + vec2(-0.5 * tap.x, tap.y), 0.0).rgb +
                     textureLod(color_map, st - vec2(tap.x, 0.5 * tap.y), 0.0).rgb +
                     textureLod(color_map, st - vec2(-0.5 * tap.x, tap.y), 0.0).rgb);
  }
  else if (v_sea > 0.5) {  /* ground the core lifted to the sea surface */
    albedo = vec3(0.004, 0.02, 0.06);  /* the render material's deep water */
  }
  else {
    /* the render material's elevation ramp (scene-linear stops) */
    float t = clamp(v_height / max(anchor.w, 1.0), 0.0, 1.0);
    albedo = t < 0.45 ? mix(vec3(0.18, 0.16, 0.14), vec3(0.55, 0.42, 0.3), t / 0.45) :
                        mix(vec3(0.55, 0.42, 0.3), vec3(0.92, 0.9, 0.88), (t - 0.45) / 0.55);
  }
  float cosine = max(dot(normalize(v_normal), normalize(sun.xyz)), 0.0);
  /* a little sky light keeps the night side readable */
  vec3 radiance = albedo * (sun.w * cosine + 0.02);
#ifdef PLOD_ATMOSPHERE
  vec3 inscatter;
  float transmit;
  aerial_perspective(v_point, inscatter, transmit);
  radiance = radiance * transmit + inscatter;
#endif
  vec3 shown = view_transformed(radiance * camera.w);
  FragColor = vec4(srgbTarget ? srgb_to_linear(shown) : shown, 1.0);
}
