"""Builds and runs the C test of the detail field's batches
(tests/c/test_detail_lanes.c): plod_detail_noise_from_n against
plod_detail_noise_from point by point, bit for bit, with per-point value
bands, gradient bands and first octaves, for every style.  Built twice:
with the SIMD clones this CPU picks at load time and without them.
"""
import pytest

SOURCES = ["detail.c", "cubemap.c", "projection.c", "base.c", "status.c"]


@pytest.mark.parametrize("clones", [True, False], ids=["clones", "no-clones"])
def test_detail_lanes_c(run_c_test, clones):
    out = run_c_test("test_detail_lanes", SOURCES, () if clones else ("-DPLOD_NO_CLONES",))
    assert "detail lanes C tests passed" in out
