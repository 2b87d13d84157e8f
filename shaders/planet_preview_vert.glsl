/* Planet LOD preview, vertex stage (thesis 5.4.1 without instancing: Blender 3.4's
 * GPUBatch cannot draw instanced, so one vertex buffer repeats the template's
 * barycentric weights for every sector slot and gl_VertexID / template_vertices
 * picks the sector).
 *
 * sector_data: RGBA32F, 3 texels per sector (unit corner direction, level in .w),
 *              row-major with data_width texels per row.
 * height_atlas: R32F face atlas of the height cube map (CAR: one equirectangular face).
 * The vertex is the interpolated corner direction, normalised onto the sphere
 * ("spherified" as in the thesis) and displaced by radius + height.
 * Needs planet_common.glsl prepended. */

void main()
{
  int sector = gl_VertexID / template_vertices;
  if (sector >= sector_count) {  /* unused slot: a degenerate, clipped point */
    gl_Position = vec4(0.0, 0.0, 2.0, 1.0);
    v_dir = vec3(0.0, 0.0, 1.0);
    v_level = 0.0;
    v_height = 0.0;
    v_normal = vec3(0.0, 0.0, 1.0);
    return;
  }
  int base = sector * 3;
  vec4 c0 = texelFetch(sector_data, ivec2(base % data_width, base / data_width), 0);
  vec4 c1 = texelFetch(sector_data, ivec2((base + 1) % data_width, (base + 1) / data_width), 0);
  vec4 c2 = texelFetch(sector_data, ivec2((base + 2) % data_width, (base + 2) / data_width), 0);
  vec3 dir = normalize(bary.x * c0.xyz + bary.y * c1.xyz + bary.z * c2.xyz);
  float h = 0.0;
  if (has_height != 0) {
    h = plod_atlas_height(height_atlas, projection, dir, height_norm) * height_scale +
        height_offset;
  }
  /* the terrain's normal: central differences of the atlas about a texel apart
   * (per vertex, not per pixel: a pixel shader doing this costs a software
   * renderer seconds per frame) */
  vec3 normal = dir;
  if (has_height != 0) {
    vec3 t1 = normalize(cross(abs(dir.z) < 0.9 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0), dir));
    vec3 t2 = cross(dir, t1);
    float step_angle = 2.0 / float(textureSize(height_atlas, 0).y);
    float k = height_norm * height_scale;
    float h1 = plod_atlas_height(height_atlas, projection, normalize(dir + step_angle * t1), k)
             - plod_atlas_height(height_atlas, projection, normalize(dir - step_angle * t1), k);
    float h2 = plod_atlas_height(height_atlas, projection, normalize(dir + step_angle * t2), k)
             - plod_atlas_height(height_atlas, projection, normalize(dir - step_angle * t2), k);
    float run = 2.0 * step_angle * radius;
    normal = normalize(dir - (h1 / run) * t1 - (h2 / run) * t2);
  }
  v_normal = normal;
  v_dir = dir;
  v_level = c0.w;
  v_height = h;
  gl_Position = ModelViewProjectionMatrix * vec4(dir * (radius + h), 1.0);
}
