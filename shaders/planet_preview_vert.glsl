/* Planet LOD preview, vertex stage: the surface the core emitted for the
 * viewport's LOD, the vertices the planet's render mesh gets (heights with
 * the detail, morphing, the sea lifted), relative to the planet's anchor, with
 * the core's normals (planet space).  `surface` holds two texels per vertex:
 * (position, height above sea level) and (normal, 4 * sector level + 2 * sea
 * + 1 + crest: the detail field in units of its amplitude), zero past the
 * preview's vertices (planetlod/surface.py). */

void main()
{
  ivec2 size = textureSize(surface, 0);
  int width = size.x;
  int texel = 2 * vertex_index;
  /* slots past the texture are clipped away; those in its zero padding draw
   * zero-area triangles (the padding holds whole sectors) */
  if (texel >= size.x * size.y) {
    gl_Position = vec4(0.0, 0.0, 2.0, 1.0);
    v_point = v_normal = vec3(0.0, 0.0, 1.0);
    v_height = v_sea = v_level = v_crest = 0.0;
    return;
  }
  ivec2 at = ivec2(texel % width, texel / width);
  vec4 point = texelFetch(surface, at, 0);
  vec4 normal = texelFetch(surface, at + ivec2(1, 0), 0);
  /* planet space in float32 is enough for the direction (colour lookups)
   * and the haze (scale heights of kilometres) */
  v_point = point.xyz + anchor.xyz;
  v_normal = normal.xyz;
  v_height = point.w;
  v_sea = floor(mod(normal.w, 4.0) * 0.5);
  v_level = floor(normal.w * 0.25);
  v_crest = mod(normal.w, 2.0) - 1.0;
  gl_Position = ModelViewProjectionMatrix * vec4(point.xyz, 1.0);
}
