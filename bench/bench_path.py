#!/usr/bin/env python3
"""Camera-path benchmark (K. Gasiński, comparison of real-time terrain
visualisation methods on the sphere, master's thesis, Gdańsk University of
Technology, 2010, chapter 6) plus the LOD-vs-uniform and sea-level-skipping
comparisons (parts 1, 2, 4 of bench/README.md).

    /usr/bin/python3 -m bench.bench_path [--frames 240] [--smoke] [--out bench/results]

Replays bench/camera_path.csv (approach, orbit over both poles, descent, skim;
linear interpolation between keyframes) over an Earth-radius planet with the
real Earth topology map (data/earth-topology.png, 8848 m scale, oceans 0).
Per frame: sectors total / after backface / after frustum, triangles, splits,
merges, refine µs (refine + cull) and emission ms (planet.mesh, 2 threads).
Writes CSVs into --out:
  path_projections.csv  CAR quad-sphere and TSC/CSC/QSC cube-spheres, 1 px
                        pixel criterion, the thesis's side/distance
                        criterion (0.5/0.25) and the 1 px criterion on a
                        smooth sphere (pixel_smooth: geometry alone),
                        template 256 triangles
  path_templates.csv    QSC, template densities 1..16384 (pixel criterion)
  uniform.csv           LOD vs the uniform mesh of the same finest level
  sealevel.csv          QSC Earth with and without sea-level skipping
  path_summary.json     the derived figures (ratios) used by report.py
Not a test: figures only.  All configurations run interleaved frame by frame
(one planet per configuration), so ratios compare the same moment of load.
"""
import argparse
import csv
import json
import math
import os
import statistics
import time

import planetlod

from bench import camera_path

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

R = camera_path.R_EARTH
RES = (1280, 720)          # the thesis's resolution
HEIGHT_SCALE = 8848.0
EARTH = os.path.join(ROOT, "data", "earth-topology.png")
CRITERIA = ("pixel", "side_distance", "pixel_smooth")
MESH_FIELDS = ("positions", "normals", "uv", "morph", "triangles", "sector_level", "face")


def make_camera(planet, matrix):
    cam = planetlod.Camera(matrix, lens=50.0, sensor_width=36.0, resolution_x=RES[0],
                           resolution_y=RES[1], clip_start=1.0, clip_end=1e10)
    near, far = planet.recommended_clip(cam)
    return planetlod.Camera(matrix, lens=50.0, sensor_width=36.0, resolution_x=RES[0],
                            resolution_y=RES[1], clip_start=near, clip_end=far)


def camera_latlon(matrix):
    x, y, z = matrix[0][3], matrix[1][3], matrix[2][3]
    r = math.sqrt(x * x + y * y + z * z)
    return math.degrees(math.asin(z / r)), math.degrees(math.atan2(y, x))


def mesh_bytes(mesh):
    return sum(memoryview(getattr(mesh, f)).nbytes for f in MESH_FIELDS)


MAX_LEVEL = 24            # the add-on's default cap (props.max_level); --max-level


def step(planet, cam, template_level, emit=True, **kw):
    """One frame: refine (+cull) then emission.  Returns a row dict."""
    kw.setdefault("max_level", MAX_LEVEL)
    s = planet.refine(cam, template_level=template_level, **kw)
    row = {k: s[k] for k in ("sectors_total", "sectors_after_backface", "sectors_after_frustum",
                             "sectors_sea_skipped", "splits", "merges", "max_level")}
    row["refine_us"] = round(s["refine_us"] + s["cull_us"], 1)
    row["visible"] = planet.visible_count
    row["triangles"] = planet.visible_count * 4 ** template_level
    row["emit_ms"] = ""
    row["mesh_bytes"] = ""
    if emit:
        t0 = time.perf_counter()
        mesh = planet.mesh(template_level, threads=2)
        row["emit_ms"] = round((time.perf_counter() - t0) * 1e3, 3)
        row["mesh_bytes"] = mesh_bytes(mesh)
        assert mesh.triangle_count == row["triangles"], (mesh.triangle_count, row["triangles"])
    return row


def write_csv(path, rows):
    fields = list(rows[0].keys())
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)
    print("wrote", os.path.relpath(path, ROOT), len(rows), "rows", flush=True)


def mean(xs):
    xs = [x for x in xs if x != ""]
    return statistics.mean(xs) if xs else float("nan")


def main():
    global MAX_LEVEL
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=240, help="frames along the 80 s path")
    ap.add_argument("--template-frames", type=int, default=40,
                    help="frames for the template-density sweep")
    ap.add_argument("--smoke", action="store_true", help="a few frames, for CI (~15 s)")
    ap.add_argument("--max-level", type=int, default=MAX_LEVEL,
                    help="refinement level cap (add-on default 24; the C default is 48)")
    ap.add_argument("--out", default=os.path.join(HERE, "results"))
    args = ap.parse_args()
    MAX_LEVEL = args.max_level
    if args.smoke:
        args.frames, args.template_frames = 12, 4
    template_levels = range(6) if args.smoke else range(8)  # 4^7 = 16384 triangles
    os.makedirs(args.out, exist_ok=True)
    t_start = time.perf_counter()
    poses = camera_path.frames(args.frames)
    summary = {"frames": args.frames, "resolution": RES, "max_level_cap": MAX_LEVEL, "height_scale": HEIGHT_SCALE,
               "cpus": os.cpu_count(), "loadavg_start": os.getloadavg()}

    # ---- part 1: projections x criteria, template 256 triangles ---------------
    planets = {}
    for proj in ("car", "tsc", "csc", "qsc"):
        t0 = time.perf_counter()
        planets[proj] = planetlod.Planet(R, projection=proj, heightmap=EARTH,
                                         height_scale=HEIGHT_SCALE, sea_level=0.0)
        print(f"{proj}: Earth topology -> {planets[proj].heightmap.size}^2 cube map in "
              f"{time.perf_counter() - t0:.2f} s", flush=True)
    configs = []
    # pixel_smooth: the 1 px criterion on a smooth sphere (no height map): the
    # projections' geometry alone (curvature sag), without the height bounds
    for crit in CRITERIA:
        for proj in ("car", "tsc", "csc", "qsc"):
            if crit == "pixel":
                p = planets[proj]
            elif crit == "pixel_smooth":
                p = planetlod.Planet(R, projection=proj)
            else:
                p = planetlod.Planet(R, projection=proj, heightmap=planets[proj].heightmap,
                                     height_scale=HEIGHT_SCALE, sea_level=0.0)
            configs.append((proj, crit, p))
    rows = []
    tl = 4
    for k, (t, m, alt, seg) in enumerate(poses):
        lat, lon = camera_latlon(m)
        for proj, crit, p in configs:
            cam = make_camera(p, m)
            kw = {"criterion": "pixel" if crit == "pixel_smooth" else crit,
                  "max_pixel_error": 1.0}
            if crit == "side_distance":
                kw.update(split_border=0.5, merge_border=0.25)
            r = {"frame": k, "t_s": round(t, 3), "segment": seg, "altitude_m": round(alt, 1),
                 "cam_lat": round(lat, 3), "cam_lon": round(lon, 3), "projection": proj,
                 "criterion": crit, "template_triangles": 4 ** tl}
            r.update(step(p, cam, tl, **kw))
            rows.append(r)
        if k % max(1, args.frames // 10) == 0:
            print(f"  path frame {k}/{args.frames} ({seg}, {alt:.0f} m) "
                  f"{time.perf_counter() - t_start:.0f} s", flush=True)
    write_csv(os.path.join(args.out, "path_projections.csv"), rows)

    def sel(proj, crit, pred=lambda r: True):
        return [r for r in rows if r["projection"] == proj and r["criterion"] == crit and pred(r)]

    polar = lambda r: r["segment"] == "orbit" and abs(r["cam_lat"]) >= 60.0  # noqa: E731
    equatorial = lambda r: r["segment"] == "orbit" and abs(r["cam_lat"]) <= 30.0  # noqa: E731
    proj_summary = {}
    for crit in CRITERIA:
        for proj in ("car", "tsc", "csc", "qsc"):
            allr = sel(proj, crit)
            proj_summary[f"{proj}/{crit}"] = {
                "tri_mean": mean([r["triangles"] for r in allr]),
                "tri_max": max(r["triangles"] for r in allr),
                "tri_polar": mean([r["triangles"] for r in allr if polar(r)]),
                "tri_equator": mean([r["triangles"] for r in allr if equatorial(r)]),
                "total_polar": mean([r["sectors_total"] for r in allr if polar(r)]),
                "refine_us_mean": mean([r["refine_us"] for r in allr]),
                "refine_us_polar": mean([r["refine_us"] for r in allr if polar(r)]),
                "refine_us_max": max(r["refine_us"] for r in allr),
                "emit_ms_mean": mean([r["emit_ms"] for r in allr]),
                "emit_ms_polar": mean([r["emit_ms"] for r in allr if polar(r)]),
                "max_level": max(r["max_level"] for r in allr),
            }
    summary["projections"] = proj_summary
    for crit in CRITERIA:
        for cube in ("qsc", "tsc", "csc"):
            a, b = proj_summary[f"car/{crit}"], proj_summary[f"{cube}/{crit}"]
            summary[f"polar_ratio_car_{cube}_{crit}"] = a["tri_polar"] / max(b["tri_polar"], 1e-9)
            summary[f"equator_ratio_car_{cube}_{crit}"] = (a["tri_equator"]
                                                            / max(b["tri_equator"], 1e-9))
    print(json.dumps({k: v for k, v in summary.items() if k.startswith(("polar", "equator"))},
                     indent=1), flush=True)

    # ---- part 1b: template densities 1..16384 (QSC, pixel) ---------------------
    tposes = camera_path.frames(args.template_frames)
    tplanets = {(proj, lvl): planetlod.Planet(R, projection=proj,
                                               heightmap=planets[proj].heightmap,
                                               height_scale=HEIGHT_SCALE, sea_level=0.0)
                for proj in ("qsc",) for lvl in template_levels}
    trows = []
    for k, (t, m, alt, seg) in enumerate(tposes):
        for (proj, lvl), p in tplanets.items():
            cam = make_camera(p, m)
            r = {"frame": k, "t_s": round(t, 3), "segment": seg, "altitude_m": round(alt, 1),
                 "projection": proj, "template_triangles": 4 ** lvl}
            r.update(step(p, cam, lvl, criterion="pixel", max_pixel_error=1.0))
            trows.append(r)
    write_csv(os.path.join(args.out, "path_templates.csv"), trows)
    tsum = {}
    for (proj, lvl) in tplanets:
        rr = [r for r in trows if r["projection"] == proj and r["template_triangles"] == 4 ** lvl]
        tsum[f"{proj}/{4 ** lvl}"] = {
            "sectors_mean": mean([r["visible"] for r in rr]),
            "tri_mean": mean([r["triangles"] for r in rr]),
            "tri_max": max(r["triangles"] for r in rr),
            "refine_us_mean": mean([r["refine_us"] for r in rr]),
            "emit_ms_mean": mean([r["emit_ms"] for r in rr]),
            "frame_ms_mean": mean([r["refine_us"] / 1e3 + r["emit_ms"] for r in rr])}
    summary["templates"] = tsum

    # ---- part 2: LOD vs uniform mesh of the same finest level ------------------
    # A longest-edge-bisection level L has 12 * 2^L sectors (check below: the
    # leaves' sum of 2^(L - level) is 12 * 2^L).  A uniform mesh whose error is
    # at most the LOD's everywhere needs the LOD's finest level everywhere.
    urows = []
    qsc = planets["qsc"]
    for r in sel("qsc", "pixel"):
        L = r["max_level"]
        uni_sectors = 12 * 2 ** L
        uni_tris = uni_sectors * 4 ** tl
        bpt = r["mesh_bytes"] / max(1, r["triangles"])
        urows.append({"frame": r["frame"], "segment": r["segment"], "altitude_m": r["altitude_m"],
                      "max_level": L, "lod_triangles": r["triangles"],
                      "lod_bytes": r["mesh_bytes"], "uniform_triangles": uni_tris,
                      "uniform_bytes": round(uni_tris * bpt),
                      "ratio": uni_tris / max(1, r["triangles"])})
    # sanity check of the count formula on the last refined QSC state
    levels = qsc.sector_levels(visible_only=False).tolist()
    Lmax = max(levels)
    covered = sum(2 ** (Lmax - lv) for lv in levels)
    checked = covered == 12 * 2 ** Lmax
    base = planetlod.Planet(R, projection="qsc")
    base_tris = base.mesh(tl, visible_only=False).triangle_count
    summary["uniform_formula_check"] = {"leaf_cover_equals_12x2^L": checked,
                                        "base_mesh_triangles": base_tris,
                                        "expected": 12 * 4 ** tl}
    write_csv(os.path.join(args.out, "uniform.csv"), urows)
    finite = [u for u in urows if u["lod_triangles"] > 0]
    deep = [u for u in finite if u["max_level"] >= 20]
    summary["uniform"] = {
        "ratio_median": statistics.median(u["ratio"] for u in finite),
        "ratio_min": min(u["ratio"] for u in finite),
        "ratio_min_frame": min(finite, key=lambda u: u["ratio"])["frame"],
        "ratio_min_deep": min((u["ratio"] for u in deep), default=float("nan")),
        "frames_ratio_ge_50": sum(u["ratio"] >= 50 for u in finite),
        "frames": len(finite),
        "max_level": max(u["max_level"] for u in finite),
        "lod_tri_max": max(u["lod_triangles"] for u in finite),
        "lod_bytes_max": max(u["lod_bytes"] for u in finite),
        "uniform_tri_at_max_level": 12 * 2 ** max(u["max_level"] for u in finite) * 4 ** tl,
        "bytes_per_triangle": mean([u["lod_bytes"] / u["lod_triangles"] for u in finite])}
    print(json.dumps(summary["uniform"], indent=1), flush=True)

    # ---- part 4: sea-level skipping on the Earth map ---------------------------
    sea = {flag: planetlod.Planet(R, projection="qsc", heightmap=qsc.heightmap,
                                  height_scale=HEIGHT_SCALE, sea_level=0.0)
           for flag in (False, True)}
    srows = []
    for k, (t, m, alt, seg) in enumerate(poses):
        order = (False, True) if k % 2 == 0 else (True, False)
        res = {}
        for flag in order:
            p = sea[flag]
            cam = make_camera(p, m)
            res[flag] = step(p, cam, tl, criterion="pixel", max_pixel_error=1.0, skip_sea=flag)
        a, b = res[False], res[True]
        srows.append({"frame": k, "segment": seg, "altitude_m": round(alt, 1),
                      "triangles_all": a["triangles"], "triangles_skip": b["triangles"],
                      "sea_sectors_skipped": b["sectors_sea_skipped"],
                      "refine_us_all": a["refine_us"], "refine_us_skip": b["refine_us"],
                      "emit_ms_all": a["emit_ms"], "emit_ms_skip": b["emit_ms"],
                      "bytes_all": a["mesh_bytes"], "bytes_skip": b["mesh_bytes"]})
    write_csv(os.path.join(args.out, "sealevel.csv"), srows)
    ta = sum(r["triangles_all"] for r in srows)
    ts = sum(r["triangles_skip"] for r in srows)
    time_a = sum(r["refine_us_all"] / 1e3 + r["emit_ms_all"] for r in srows)
    time_s = sum(r["refine_us_skip"] / 1e3 + r["emit_ms_skip"] for r in srows)
    summary["sealevel"] = {
        "triangles_saved_pct": 100.0 * (ta - ts) / max(1, ta),
        "time_all_ms_per_frame": time_a / len(srows),
        "time_skip_ms_per_frame": time_s / len(srows),
        "time_saved_pct": 100.0 * (time_a - time_s) / max(1e-9, time_a),
        "speedup_pct": 100.0 * (time_a / max(1e-9, time_s) - 1.0),
        "frames_with_skips": sum(r["sea_sectors_skipped"] > 0 for r in srows)}
    print(json.dumps(summary["sealevel"], indent=1), flush=True)

    summary["loadavg_end"] = os.getloadavg()
    summary["wall_s"] = time.perf_counter() - t_start
    with open(os.path.join(args.out, "path_summary.json"), "w") as f:
        json.dump(summary, f, indent=1)
    print(f"bench_path done in {summary['wall_s']:.0f} s", flush=True)


if __name__ == "__main__":
    main()
