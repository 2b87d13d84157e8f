/* Planet LOD viewport sky, vertex stage: a triangle over the whole view at
 * the far plane (so it only fills pixels nothing else was drawn on), with
 * the view ray of each corner in planet space (`rays`: NDC x, y to an
 * unnormalised direction, linear across the screen). */

void main()
{
  v_ray = rays * vec3(pos, 1.0);
  gl_Position = vec4(pos, 1.0, 1.0);
}
