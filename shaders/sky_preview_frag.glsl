/* Planet LOD viewport sky, fragment stage: the render's sky world
 * (atmosphere.build_world) along the pixel's view ray: the atmosphere's
 * single scattering to space from the viewer, the sun's light taken at
 * the ray's closest approach to the planet (the limb seen from orbit, the
 * viewer near the ground), the sun's disk; black without an atmosphere. */

void main()
{
  vec3 d = normalize(v_ray);
  vec3 radiance = vec3(0.0);
#ifdef PLOD_ATMOSPHERE
  vec3 cam = camera.xyz;
  float r = length(cam);
  float mu = dot(cam / r, d);
  float r0 = r * sqrt(max(1.0 - mu * mu, 0.0));
  if (r > ATM_RADIUS && mu < 0.0 && r0 < ATM_RADIUS) {
    /* a ray that meets the sphere but no triangle: the sliver between the
     * sphere and the mesh's chords along the limb.  It shows what the
     * planet's shader shows at the limb, the haze up to the ray's closest
     * approach, not the scatter of a ray through the planet */
    float haze;
    aerial_perspective(cam - d * (r * mu), radiance, haze);
  }
  else {
    float depth_r = to_space(r, mu, r0, ATM_RAYLEIGH_HEIGHT);
    float depth_m = to_space(r, mu, r0, ATM_MIE_HEIGHT);
    float sun_r, sun_m;
    sun_depths(cam + d * max(-(r * mu), 0.0), sun_r, sun_m);
    float cos_sun = dot(d, sun.xyz);
    vec3 inscatter, transmittance;
    scatter(depth_r, depth_m, cos_sun, sun_r, sun_m, inscatter, transmittance);
    /* the sun's disk, three times its size, as the world draws it */
    float disk = smoothstep(cos(radians(0.8)), cos(radians(0.7)), cos_sun);
    radiance = inscatter * ATM_SKY_GAIN + transmittance * (disk * sun.w * 40.0);
  }
#endif
  vec3 shown = view_transformed(radiance * camera.w);
  FragColor = vec4(srgbTarget ? srgb_to_linear(shown) : shown, 1.0);
}
