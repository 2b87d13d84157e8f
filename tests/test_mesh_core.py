"""Builds and runs the C unit tests of the mesh core (tests/c/test_mesh.c).

They exercise cext/mesh.c alone on hand-made conforming sector sets (cube
base sectors, uniform and adaptive longest-edge bisections with forced
splits): template layout, watertightness after welding, shared-vertex
normals, geomorphing, threads = 1 vs N bit-identity, bad input.
"""


def test_mesh_core_c(run_c_test):
    assert "mesh C tests passed" in run_c_test("test_mesh", ["mesh.c", "base.c"])
