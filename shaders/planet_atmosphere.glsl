/* Planet LOD preview: the render's atmosphere (atmosphere.py: single
 * scattering, Rayleigh + Mie, optical depths by Schüler's approximation of
 * the Chapman function), shared by the planet's haze and the sky.  Needs
 * PLOD_ATMOSPHERE and its constants (draw.py) and the uniforms `camera`
 * (viewer in planet space) and `sun` (direction, strength). */

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

/* light scattered towards the viewer along a path of Rayleigh / Mie depths
 * (over beta H) depth_r / depth_m, the sun at cosine cos_sun to the path, the
 * sun's light reaching it through depths sun_r / sun_m */
void scatter(float depth_r, float depth_m, float cos_sun, float sun_r, float sun_m,
             out vec3 inscatter, out vec3 transmittance)
{
  float g = ATM_MIE_G, g2 = g * g;
  float phase_r = (cos_sun * cos_sun + 1.0) * (3.0 / (16.0 * PLOD_PI));
  float phase_m = (cos_sun * cos_sun + 1.0) * (3.0 / (8.0 * PLOD_PI) * (1.0 - g2) / (2.0 + g2)) /
                  pow(max(cos_sun * (-2.0 * g) + (1.0 + g2), 1e-4), 1.5);
  vec3 tau_r = ATM_RAYLEIGH * ATM_RAYLEIGH_HEIGHT * depth_r;
  vec3 tau_m = ATM_MIE * (ATM_MIE_HEIGHT * 1.11) * depth_m;  /* Mie extinction */
  vec3 tau = max(tau_r + tau_m, vec3(1e-7));
  vec3 scattered = tau_r * phase_r + ATM_MIE * ATM_MIE_HEIGHT * depth_m * phase_m;
  transmittance = exp(-tau);
  vec3 sun_tau = ATM_RAYLEIGH * ATM_RAYLEIGH_HEIGHT * sun_r + ATM_MIE * (ATM_MIE_HEIGHT * 1.11) * sun_m;
  vec3 sunlight = exp(-sun_tau) * sun.w;
  inscatter = scattered / tau * (vec3(1.0) - transmittance) * sunlight * ATM_GAIN;
}

/* depths (over beta H) from `point` towards the sun */
void sun_depths(vec3 point, out float sun_r, out float sun_m)
{
  float r = length(point);
  float mu = dot(point / r, sun.xyz);
  float r0 = r * sqrt(max(1.0 - mu * mu, 0.0));
  sun_r = to_space(r, mu, r0, ATM_RAYLEIGH_HEIGHT);
  sun_m = to_space(r, mu, r0, ATM_MIE_HEIGHT);
}

void aerial_perspective(vec3 point, out vec3 inscatter, out float haze)
{
  vec3 cam = camera.xyz;
  vec3 view = point - cam;
  float distance = max(length(view), 1e-3);
  vec3 d = view / distance;
  /* A point past the view ray's closest approach, where that approach lies
   * inside the sphere, is one the sphere hides (the mesh's chords along the
   * limb sag below it): it takes the haze of the approach, as the sky does
   * for the rays between the chords and the sphere. */
  float approach = -dot(cam, d);
  if (approach > 0.0 && approach < distance && length(cam + d * approach) < ATM_RADIUS) {
    point = cam + d * approach;
  }
  float depth_r = segment_depth(cam, point, d, ATM_RAYLEIGH_HEIGHT);
  float depth_m = segment_depth(cam, point, d, ATM_MIE_HEIGHT);
  float sun_r, sun_m;
  sun_depths(point, sun_r, sun_m);
  vec3 transmittance;
  scatter(depth_r, depth_m, dot(d, sun.xyz), sun_r, sun_m, inscatter, transmittance);
  haze = dot(transmittance, vec3(0.3, 0.6, 0.1));  /* luminance-weighted */
}
#endif
