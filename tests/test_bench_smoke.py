"""bench/run_all.sh --smoke (the CI-sized benchmark run): the CSVs, JSON and
plots exist and hold sane figures.  No timing is asserted (speed targets are
printed by the benchmarks, not tested)."""
import csv
import json
import os
import shutil
import subprocess

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    if not shutil.which(os.environ.get("BLENDER", "blender")):
        pytest.skip("blender not installed")
    out = tmp_path_factory.mktemp("bench")
    env = dict(os.environ, BENCH_OUT=str(out))
    proc = subprocess.run([os.path.join(ROOT, "bench", "run_all.sh"), "--smoke"], cwd=ROOT,
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-6000:]
    return out


def test_path_csv_culling_order_and_triangles(smoke):
    data = rows(smoke / "path_projections.csv")
    projections = {r["projection"] for r in data}
    assert projections == {"car", "tsc", "csc", "qsc"}
    assert {r["criterion"] for r in data} == {"pixel", "side_distance", "pixel_smooth"}
    assert {r["segment"] for r in data} == {"approach", "orbit", "descent", "skim"}
    for r in data:
        total, back, frus = (int(r[k]) for k in ("sectors_total", "sectors_after_backface",
                                                   "sectors_after_frustum"))
        assert 0 < frus <= back <= total, r
        assert int(r["triangles"]) == int(r["visible"]) * int(r["template_triangles"])
        assert int(r["visible"]) <= frus
        assert int(r["max_level"]) <= 24
        assert int(r["mesh_bytes"]) > 0
    # the path gets closer: the skim needs finer sectors than the approach's first frame
    qsc = [r for r in data if r["projection"] == "qsc" and r["criterion"] == "pixel"]
    assert int(qsc[-1]["max_level"]) > int(qsc[0]["max_level"])


def test_templates_uniform_sealevel(smoke):
    t = rows(smoke / "path_templates.csv")
    dens = sorted({int(r["template_triangles"]) for r in t})
    assert dens[0] == 1 and all(b == 4 * a for a, b in zip(dens, dens[1:]))
    u = rows(smoke / "uniform.csv")
    for r in u:  # a uniform mesh at the LOD's finest level is never smaller
        assert int(r["uniform_triangles"]) >= int(r["lod_triangles"]) > 0
        assert int(r["uniform_triangles"]) == 12 * 2 ** int(r["max_level"]) * 256
    s = rows(smoke / "sealevel.csv")
    for r in s:
        assert int(r["triangles_skip"]) <= int(r["triangles_all"])
    summary = json.loads((smoke / "path_summary.json").read_text())
    assert summary["uniform_formula_check"]["leaf_cover_equals_12x2^L"]
    assert summary["uniform_formula_check"]["base_mesh_triangles"] == \
        summary["uniform_formula_check"]["expected"]
    for key in ("polar_ratio_car_qsc_pixel", "polar_ratio_car_qsc_side_distance",
                "polar_ratio_car_qsc_pixel_smooth"):
        assert summary[key] > 0


def test_blender_handoff_and_report(smoke):
    h = rows(smoke / "blender_handoff.csv")
    assert len(h) == 4
    for r in h:
        assert int(r["triangles"]) > 0
        assert float(r["floor_total_ms"]) > 0 and float(r["lod_total_ms"]) > 0
    js = json.loads((smoke / "blender_handoff.json").read_text())
    assert js["blender"].startswith("3.4") and js["frames"] == 4
    readme = (smoke / "README.md").read_text()
    assert "<!-- results:begin -->" in readme and "| 2 | uniform / LOD" in readme
    for name in ("fig_path_sectors.png", "fig_projections.png", "fig_templates.png",
                 "fig_uniform.png", "fig_handoff.png"):
        assert (smoke / name).stat().st_size > 10000, name
