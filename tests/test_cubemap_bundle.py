"""Builds and runs the C test of the interleaved maps the vertices sample
(tests/c/test_cubemap_bundle.c): plod_cubemap_bundle_sample_n against the
height, normal and modulation maps sampled one by one, bit for bit, on
every projection and texel type, at face edges, corners, clamped and
unlocated points.  Built twice: with the SIMD clones this CPU picks at
load time and without them.
"""
import pytest

SOURCES = ["cubemap.c", "projection.c", "base.c", "status.c"]


@pytest.mark.parametrize("clones", [True, False], ids=["clones", "no-clones"])
def test_cubemap_bundle_c(run_c_test, clones):
    out = run_c_test("test_cubemap_bundle", SOURCES, () if clones else ("-DPLOD_NO_CLONES",))
    assert "cubemap bundle C tests passed" in out
