/* planet_common.glsl -- forward cube-sphere projections (direction -> face, u, v),
 * GLSL ports of cext/projection.c (WCSLIB face frames), shared by the preview's
 * vertex and fragment shaders.  Projection codes as plod_projection:
 * 0 TSC, 1 CSC, 2 QSC, 3 spherified, 4 CAR. */

#define PLOD_PI 3.14159265358979

int plod_select_face(vec3 d)
{
  int face = 0;
  float zeta = d.z;
  if (d.x > zeta) { face = 1; zeta = d.x; }
  if (d.y > zeta) { face = 2; zeta = d.y; }
  if (-d.x > zeta) { face = 3; zeta = -d.x; }
  if (-d.y > zeta) { face = 4; zeta = -d.y; }
  if (-d.z > zeta) { face = 5; }
  return face;
}

/* (xi, eta, zeta) in the face frame */
vec3 plod_to_local(int face, vec3 d)
{
  if (face == 0) return vec3(d.y, -d.x, d.z);
  if (face == 1) return vec3(d.y, d.z, d.x);
  if (face == 2) return vec3(-d.x, d.z, d.y);
  if (face == 3) return vec3(-d.y, d.z, -d.x);
  if (face == 4) return vec3(d.x, d.z, -d.y);
  return vec3(d.y, d.x, -d.z);
}

float plod_csc_F(float a, float b)
{
  const float gstar = 1.37484847732, mm = 0.004869491981;
  const float gamma = -0.13161671474, omega1 = -0.159596235474;
  const float d0 = 0.0759196200467, d1 = -0.0217762490699;
  const float c00 = 0.141189631152, c10 = 0.0809701286525;
  const float c01 = -0.281528535557, c11 = 0.15384112876;
  const float c20 = -0.178251207466, c02 = 0.106959469314;
  float a2 = a * a, b2 = b * b, ca2 = 1.0 - a2, cb2 = 1.0 - b2;
  float sum_c = c00 + c10 * a2 + c01 * b2 + c11 * a2 * b2 + c20 * a2 * a2 + c02 * b2 * b2;
  return a * (a2 + ca2 * (gstar + b2 * (gamma * ca2 + mm * a2 + cb2 * sum_c) +
                          a2 * (omega1 - ca2 * (d0 + d1 * a2))));
}

vec2 plod_qsc_fwd(vec3 l)
{
  bool swap_axes = abs(l.y) > abs(l.x);
  float major = swap_axes ? l.y : l.x;
  float minor = swap_axes ? l.x : l.y;
  if (major == 0.0) return vec2(0.0);
  float omega = minor / major;
  float w2 = omega * omega;
  float q = sqrt(2.0 + w2);
  float a = major * sqrt((1.0 + w2) * q / ((1.0 + l.z) * (q - 1.0)));
  float b = a * (12.0 / PLOD_PI) * atan(omega * (q - 1.0) / (q + w2));
  return swap_axes ? vec2(b, a) : vec2(a, b);
}

float plod_sph_root(float s2, float d)
{
  float p = 3.0 + 2.0 * d;
  return 12.0 * s2 / (p + sqrt(max(p * p - 24.0 * s2, 0.0)));
}

vec2 plod_sph_fwd(vec3 l)
{
  float x2 = l.x * l.x, y2 = l.y * l.y, d = x2 - y2;
  return vec2(sign(l.x) * sqrt(plod_sph_root(x2, d)), sign(l.y) * sqrt(plod_sph_root(y2, -d)));
}

/* unit direction -> (u, v) in [-1, 1] on `face` (CAR: lon/180, lat/90 on face 0) */
vec2 plod_dir_to_face(int projection, vec3 d, out int face)
{
  if (projection == 4) {
    face = 0;
    /* latitude by atan, not asin: GLSL's asin may be off by 1e-4 rad
       towards the poles (llvmpipe), atan stays within float rounding */
    return vec2(atan(d.y, d.x) / PLOD_PI, atan(d.z, length(d.xy)) / (0.5 * PLOD_PI));
  }
  face = plod_select_face(d);
  vec3 l = plod_to_local(face, d);
  vec2 uv;
  if (projection == 0) uv = l.xy / l.z;
  else if (projection == 1) uv = vec2(plod_csc_F(l.x / l.z, l.y / l.z), plod_csc_F(l.y / l.z, l.x / l.z));
  else if (projection == 2) uv = plod_qsc_fwd(l);
  else uv = plod_sph_fwd(l);
  return clamp(uv, -1.0, 1.0);
}

/* Bilinear height from the face atlas (faces side by side, rows along +v),
 * taps clamped inside the face so faces never bleed into each other. */
float plod_atlas_height(sampler2D atlas, int projection, vec3 d, float scale)
{
  int face;
  vec2 uv = plod_dir_to_face(projection, d, face);
  ivec2 size = textureSize(atlas, 0);
  int face_w = projection == 4 ? size.x : size.x / 6;
  vec2 texel = (uv * 0.5 + 0.5) * vec2(face_w, size.y) - 0.5;
  vec2 base = floor(texel);
  vec2 f = texel - base;
  ivec2 lo = clamp(ivec2(base), ivec2(0), ivec2(face_w - 1, size.y - 1));
  ivec2 hi = clamp(ivec2(base) + 1, ivec2(0), ivec2(face_w - 1, size.y - 1));
  int off = face * face_w;
  float h00 = texelFetch(atlas, ivec2(off + lo.x, lo.y), 0).r;
  float h10 = texelFetch(atlas, ivec2(off + hi.x, lo.y), 0).r;
  float h01 = texelFetch(atlas, ivec2(off + lo.x, hi.y), 0).r;
  float h11 = texelFetch(atlas, ivec2(off + hi.x, hi.y), 0).r;
  return mix(mix(h00, h10, f.x), mix(h01, h11, f.x), f.y) * scale;
}
