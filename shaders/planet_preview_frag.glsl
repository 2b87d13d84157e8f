/* Planet LOD preview, fragment stage: the ground's colour from the
 * equirectangular colour map (or an elevation ramp, or the sector level),
 * lit as the render is by the scene's sun (Lambert on the core's normal; a
 * Blender sun of strength 1 lights a white surface facing it to 1 / pi, as
 * Cycles' and EEVEE's diffuse BSDFs do), seen
 * through the haze and shown through the scene's exposure and view
 * transform; written for a framebuffer that encodes to sRGB itself where
 * Blender says so (srgbTarget, as its own shaders do).
 * The haze (with PLOD_ATMOSPHERE and its constants defined, draw.py): the
 * render material's aerial perspective (atmosphere.py: single scattering,
 * Rayleigh + Mie, optical depths by Schüler's approximation of the Chapman
 * function), per pixel: a flat sea's triangles span kilometres of haze.
 * The colour map is read at full resolution, averaged over the pixel's
 * footprint (from the viewer's distance and slant);
 * an sRGB texture's texels arrive decoded (scene-linear).  On planets with
 * an atmosphere the land gets the render's ground types
 * (planet_ground_types.glsl). */

vec3 level_colour(float level)
{
  float hue = fract(level * 0.137);
  vec3 k = clamp(abs(fract(hue + vec3(0.0, 2.0 / 3.0, 1.0 / 3.0)) * 6.0 - 3.0) - 1.0, 0.0, 1.0);
  return mix(vec3(1.0), k, 0.85);
}

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
#ifdef PLOD_ATMOSPHERE
    if (v_sea < 0.5) {
      albedo = ground_types(albedo, v_point, n, normalize(v_normal), v_height, v_crest,
                            length(to_eye));
    }
#endif
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
  /* a little light keeps the night side readable */
  vec3 light = vec3(sun.w * cosine / PLOD_PI + 0.02);
#ifdef PLOD_ATMOSPHERE
  /* the day sky's light (bluish, about a tenth of the sun's on open ground)
   * on the faces the sun misses, as the render's world lights them */
  float daylight = smoothstep(-0.05, 0.15, dot(n, normalize(sun.xyz)));
  light += sun.w / PLOD_PI * daylight * (0.5 + 0.5 * dot(normalize(v_normal), n)) *
           vec3(0.06, 0.08, 0.11);
#endif
  vec3 radiance = albedo * light;
#ifdef PLOD_ATMOSPHERE
  vec3 inscatter;
  float transmit;
  aerial_perspective(v_point, inscatter, transmit);
  radiance = radiance * transmit + inscatter;
#endif
  vec3 shown = view_transformed(radiance * camera.w);
  FragColor = vec4(srgbTarget ? srgb_to_linear(shown) : shown, 1.0);
}
