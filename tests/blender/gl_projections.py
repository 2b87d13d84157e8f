"""Under xvfb-run: the GLSL projections of shaders/planet_common.glsl (the GPU
preview's direction -> face, u, v) against the C ones (planetlod.dirs_to_faces).

Each pixel of a float framebuffer evaluates plod_dir_to_face for one test
direction (random directions plus cube edges, cube corners, poles and the
date line); the result is read back and compared per projection with the C
core in double precision.  GLSL works in float32: u, v must agree within
float rounding (CSC: its published polynomial, evaluated in float), and the
face may differ only for directions within float rounding of a face edge."""
import math
import os
import random
import sys

import gpu
from gpu_extras.batch import batch_for_shader

import plod_testlib as lib

sys.path.insert(0, os.environ.get("PLANET_LOD_NATIVE", lib.ROOT))
import planetlod  # noqa: E402

SIDE = 64  # SIDE x SIDE directions
PROJECTIONS = {"tsc": 0, "csc": 1, "qsc": 2, "spherified": 3, "car": 4}
# float32 evaluation: a few ulps through each projection's chain of square
# roots, divisions and arc tangents; 2e-5 is 1/100 of a texel of a 1024-texel face
UV_TOLERANCE = 2e-5
EDGE_SLACK = 1e-5  # a direction this close to a face edge may land on either face

FRAGMENT = """
void main()
{
  vec3 d = texelFetch(directions, ivec2(gl_FragCoord.xy), 0).xyz;
  int face;
  vec2 uv = plod_dir_to_face(projection, d, face);
  FragColor = vec4(float(face), uv, 1.0);
}
"""


def test_directions():
    rng = random.Random(7)
    dirs = []
    special = [(0, 0, 1), (0, 0, -1), (1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0)]
    for sx in (-1, 1):
        for sy in (-1, 1):
            for sz in (-1, 1):
                special.append((sx, sy, sz))                     # cube corners
                special.append((sx, sy, 0.3 * sz))               # vertical cube edges
                special.append((0.3 * sx, sy, sz))
    for k in range(64):                                          # the date line
        lat = -1.5 + 3.0 * k / 63
        special.append((-math.cos(lat), 1e-9, math.sin(lat)))
    for v in special:
        n = math.sqrt(sum(c * c for c in v))
        dirs.append(tuple(c / n for c in v))
    while len(dirs) < SIDE * SIDE:
        v = [rng.gauss(0, 1) for _ in range(3)]
        n = math.sqrt(sum(c * c for c in v))
        dirs.append(tuple(c / n for c in v))
    return dirs


def shader():
    with open(os.path.join(lib.ROOT, "shaders", "planet_common.glsl")) as f:
        common = f.read()
    info = gpu.types.GPUShaderCreateInfo()
    info.push_constant('INT', "projection")
    info.sampler(0, 'FLOAT_2D', "directions")
    info.vertex_in(0, 'VEC2', "pos")
    info.fragment_out(0, 'VEC4', "FragColor")
    info.vertex_source("void main() { gl_Position = vec4(pos, 0.0, 1.0); }")
    info.fragment_source(common + FRAGMENT)
    return gpu.shader.create_from_info(info)


def evaluate(program, texture, code):
    target = gpu.types.GPUTexture((SIDE, SIDE), format='RGBA32F')
    framebuffer = gpu.types.GPUFrameBuffer(color_slots=target)
    batch = batch_for_shader(program, 'TRI_FAN',
                             {"pos": [(-1, -1), (1, -1), (1, 1), (-1, 1)]})
    with framebuffer.bind():
        gpu.state.viewport_set(0, 0, SIDE, SIDE)
        program.bind()
        program.uniform_int("projection", code)
        program.uniform_sampler("directions", texture)
        batch.draw(program)
        out = framebuffer.read_color(0, 0, SIDE, SIDE, 4, 0, 'FLOAT')
    out.dimensions = SIDE * SIDE * 4
    return list(out)


def edge_distance(d):
    """How far (in the face-selection sense) a direction is from a face edge:
    the gap between its largest and second-largest signed axis component."""
    comps = sorted([d[0], d[1], d[2], -d[0], -d[1], -d[2]], reverse=True)
    return comps[0] - comps[1]


def main():
    dirs = test_directions()
    flat = [c for d in dirs for c in (d[0], d[1], d[2], 0.0)]
    texture = gpu.types.GPUTexture((SIDE, SIDE), format='RGBA32F',
                                   data=gpu.types.Buffer('FLOAT', len(flat), flat))
    program = shader()
    report = []
    for name, code in PROJECTIONS.items():
        gl = evaluate(program, texture, code)
        xyz = [c for d in dirs for c in d]
        faces, us, vs = planetlod.dirs_to_faces(name, xyz)
        worst, mismatched, worst_dir = 0.0, 0, None
        for i, d in enumerate(dirs):
            g_face, g_u, g_v = int(round(gl[4 * i])), gl[4 * i + 1], gl[4 * i + 2]
            if name == "car":  # the preview's CAR atlas is equirectangular: lon/180, lat/90
                c_face = 0
                c_u = math.atan2(d[1], d[0]) / math.pi
                c_v = math.asin(max(-1.0, min(1.0, d[2]))) / (0.5 * math.pi)
                if abs(abs(c_u) - 1.0) < 1e-6 or abs(abs(c_v) - 1.0) < 1e-3:
                    continue  # the date line and the poles: both sides are the same point
            else:
                c_face, c_u, c_v = faces[i], us[i], vs[i]
            if g_face != c_face:
                mismatched += 1
                assert edge_distance(d) < EDGE_SLACK, (name, d, g_face, c_face)
                continue
            if max(abs(g_u - c_u), abs(g_v - c_v)) > worst:
                worst, worst_dir = max(abs(g_u - c_u), abs(g_v - c_v)), (d, g_u, g_v, c_u, c_v)
        assert worst < UV_TOLERANCE, (name, worst, worst_dir)
        report.append(f"{name}: max |uv| difference {worst:.2e}, {mismatched} edge "
                      f"directions on the neighbour face")
    print("PLOD gl projections:", "; ".join(report), flush=True)


if __name__ == "__main__":
    lib.run(main)  # exits non-zero on failure
    sys.stdout.flush()
    os._exit(0)  # the UI (xvfb) would otherwise wait for input
