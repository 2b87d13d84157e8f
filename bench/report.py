#!/usr/bin/env python3
"""Plots and the results table of the benchmarks.

    /usr/bin/python3 -m bench.report [--results bench/results] [--command "bench/run_all.sh"]

Reads what bench_path.py, bench_blender.py and bench_cycles.py wrote into
--results, draws PNGs there (matplotlib, Agg) and rewrites the table in
bench/README.md between the markers <!-- results:begin --> / <!-- results:end -->.
Every figure states the machine (uname -m, cpu count), the Blender version
and the command that produced the data.  Missing inputs are skipped (and the
table says "not run").
"""
import argparse
import csv
import json
import os
import platform
import shutil
import subprocess

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
BEGIN, END = "<!-- results:begin -->", "<!-- results:end -->"
SEG_COLORS = {"approach": "#eeeeee", "orbit": "#dde8f5", "descent": "#f5e8dd", "skim": "#e2f2dd"}


def read_csv(path):
    if not os.path.isfile(path):
        return None
    with open(path) as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        for k, v in r.items():
            try:
                r[k] = float(v)
            except (TypeError, ValueError):
                pass
    return rows


def read_json(path):
    if not os.path.isfile(path):
        return None
    with open(path) as f:
        return json.load(f)


def blender_version(*sources):
    for s in sources:
        if s and s.get("blender"):
            return "Blender " + s["blender"]
    exe = shutil.which("blender")
    if not exe:
        return "Blender: not installed"
    try:
        out = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=60)
        return out.stdout.splitlines()[0].strip()
    except (OSError, subprocess.SubprocessError, IndexError):
        return "Blender: unknown"


def footer(fig, ctx):
    fig.text(0.01, 0.005, f"{ctx['machine']}, {ctx['cpus']} CPUs, {ctx['blender']} | "
             f"command: {ctx['command']}", fontsize=7, color="#555555", ha="left", va="bottom")


def shade_segments(ax, rows):
    start, seg = 0, rows[0]["segment"]
    for r in rows[1:] + [None]:
        if r is None or r["segment"] != seg:
            end = r["frame"] if r is not None else rows[-1]["frame"] + 1
            ax.axvspan(start, end, color=SEG_COLORS.get(seg, "#ffffff"), zorder=0)
            ax.text((start + end) / 2, 1.0, seg, transform=ax.get_xaxis_transform(),
                    ha="center", va="bottom", fontsize=7)
            if r is not None:
                start, seg = r["frame"], r["segment"]


def save(fig, ctx, name):
    footer(fig, ctx)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    path = os.path.join(ctx["results"], name)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    print("wrote", os.path.relpath(path, ROOT))
    return name


def fig_sectors(proj_rows, ctx):
    fig, axes = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True)
    for ax, proj in zip(axes, ("qsc", "car")):
        rows = [r for r in proj_rows if r["projection"] == proj and r["criterion"] == "pixel"]
        shade_segments(ax, rows)
        x = [r["frame"] for r in rows]
        for key, label in (("sectors_total", "total"), ("sectors_after_backface",
                                                        "after backface"),
                           ("sectors_after_frustum", "after frustum")):
            ax.plot(x, [r[key] for r in rows], label=label, lw=1.2)
        ax.set_yscale("log")
        ax.set_ylabel(f"{proj.upper()} sectors")
        ax.legend(fontsize=8, loc="upper left")
    axes[-1].set_xlabel("frame (80 s path)")
    fig.suptitle("Sectors per frame along the camera path (1 px criterion, 1280x720)",
                 fontsize=10)
    return save(fig, ctx, "fig_path_sectors.png")


def fig_projections(proj_rows, ctx):
    crits = [c for c in ("pixel", "side_distance", "pixel_smooth")
             if any(r["criterion"] == c for r in proj_rows)]
    fig, axes = plt.subplots(len(crits), 1, figsize=(10, 3.2 * len(crits)), sharex=True)
    for ax, crit in zip(axes, crits):
        first = [r for r in proj_rows if r["projection"] == "qsc" and r["criterion"] == crit]
        shade_segments(ax, first)
        for proj in ("car", "tsc", "csc", "qsc"):
            rows = [r for r in proj_rows if r["projection"] == proj and r["criterion"] == crit]
            ax.plot([r["frame"] for r in rows], [r["triangles"] for r in rows],
                    label=proj.upper(), lw=1.1)
        ax.set_yscale("log")
        ax.set_ylabel(f"triangles ({crit})")
        ax.legend(fontsize=8, ncol=4, loc="upper left")
    axes[-1].set_xlabel("frame")
    fig.suptitle("Quad-sphere (CAR) vs cube-spheres: triangles per frame (template 256)",
                 fontsize=10)
    return save(fig, ctx, "fig_projections.png")


def fig_templates(summary, ctx):
    t = summary.get("templates", {})
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for proj in ("qsc", "car"):
        keys = sorted((int(k.split("/")[1]), v) for k, v in t.items() if k.startswith(proj))
        if not keys:
            continue
        x = [k for k, _ in keys]
        axes[0].plot(x, [v["sectors_mean"] for _, v in keys], "o-", label=f"{proj} sectors")
        axes[0].plot(x, [v["tri_mean"] for _, v in keys], "s--", label=f"{proj} triangles")
        axes[1].plot(x, [v["refine_us_mean"] / 1e3 for _, v in keys], "o-",
                     label=f"{proj} refine+cull")
        axes[1].plot(x, [v["emit_ms_mean"] for _, v in keys], "s--", label=f"{proj} emission")
    for ax in axes:
        ax.set_xscale("log", base=4)
        ax.set_yscale("log")
        ax.set_xlabel("template triangles per sector")
        ax.legend(fontsize=8)
    axes[0].set_ylabel("mean per frame")
    axes[1].set_ylabel("ms per frame (mean)")
    fig.suptitle("Template density 1..16384 (1 px criterion, mean over the path)", fontsize=10)
    return save(fig, ctx, "fig_templates.png")


def fig_uniform(urows, ctx):
    fig, ax = plt.subplots(figsize=(10, 4))
    x = [r["frame"] for r in urows]
    ax.plot(x, [r["lod_triangles"] for r in urows], label="LOD (QSC, 1 px)")
    ax.plot(x, [r["uniform_triangles"] for r in urows], label="uniform mesh, same finest level")
    ax2 = ax.twinx()
    ax2.plot(x, [r["ratio"] for r in urows], color="#999999", lw=0.8, label="ratio")
    ax2.set_yscale("log")
    ax2.set_ylabel("uniform / LOD")
    ax.set_yscale("log")
    ax.set_xlabel("frame")
    ax.set_ylabel("triangles")
    ax.legend(fontsize=8, loc="upper left")
    fig.suptitle("LOD vs uniform cube-sphere of the same finest detail", fontsize=10)
    return save(fig, ctx, "fig_uniform.png")


def fig_handoff(hrows, grows, ctx):
    fig, ax = plt.subplots(figsize=(10, 4))
    x = [r["frame"] for r in hrows]
    ax.plot(x, [r["lod_total_ms"] for r in hrows], "o-", ms=3,
            label="add-on: refine + emit + write_mesh + evaluate")
    ax.plot(x, [r["floor_total_ms"] for r in hrows], "s-", ms=3,
            label="floor: precomputed mesh foreach_set + evaluate")
    ax.plot(x, [r["emit_ms"] for r in hrows], ":", label="emission alone")
    if grows:
        ax.plot([r["frame"] for r in grows], [r["gpu_build_ms"] for r in grows], "^-", ms=3,
                label="GPU preview batch/texture build (xvfb, llvmpipe)")
    ax.set_yscale("log")
    ax.set_xlabel("frame")
    ax.set_ylabel("ms")
    ax.legend(fontsize=8)
    fig.suptitle("Blender hand-off per frame (Earth preset, FINAL quality)", fontsize=10)
    return save(fig, ctx, "fig_handoff.png")


def fig_cycles(cyc, ctx):
    frames = cyc.get("frames", [])
    if not frames:
        return None
    fig, axes = plt.subplots(1, 3, figsize=(10, 3.6))
    labels = ("LOD mesh", "adaptive subdiv")
    xs = range(len(frames))
    for ax, key, title in zip(axes, ("time_s", "peak_mb", "psnr_db"),
                              ("render time (s)", "peak memory (MB)", "PSNR vs reference (dB)")):
        for i, (method, lab) in enumerate(zip(("lod", "adaptive"), labels)):
            vals = [f[method].get(key, 0) or 0 for f in frames]
            ax.bar([x + 0.4 * i for x in xs], vals, width=0.4, label=lab)
        ax.set_xticks([x + 0.2 for x in xs])
        ax.set_xticklabels([f"f{f['frame']}" for f in frames])
        ax.set_title(title, fontsize=9)
    axes[0].legend(fontsize=8)
    fig.suptitle("Cycles: LOD mesh vs adaptive subdivision + displacement", fontsize=10)
    name = save(fig, ctx, "fig_cycles.png")
    # the renders themselves (reference, LOD, adaptive) per frame
    fig, axes = plt.subplots(len(frames), 3, figsize=(10, 1.9 * len(frames) + 0.4),
                             squeeze=False)
    for row, f in zip(axes, frames):
        for ax, method in zip(row, ("ref", "lod", "adaptive")):
            path = os.path.join(ctx["results"], f[method]["png"])
            if os.path.isfile(path):
                ax.imshow(plt.imread(path))
            extra = "" if method == "ref" else f", {f[method].get('psnr_db', 0):.1f} dB"
            ax.set_title(f"t={f['t_s']:g} s {method}: {f[method]['time_s']:.1f} s{extra}",
                         fontsize=8)
            ax.axis("off")
    ctx["figures"].append(save(fig, ctx, "fig_cycles_renders.png"))
    return name


def fmt(v, nd=1):
    if v is None:
        return "n/a"
    if isinstance(v, float):
        return f"{v:,.{nd}f}"
    return f"{v:,}"


def table(summary, handoff, handoff_gpu, cyc, ctx):
    lines = [BEGIN, "",
             f"Measured on {ctx['machine']}, {ctx['cpus']} CPUs, {ctx['blender']}; "
             f"command: `{ctx['command']}`.", "",
             "| # | measure | result | target / literature |", "|---|---|---|---|"]
    if summary:
        lines.append(f"| 1 | path frames (1280x720, level cap {summary.get('max_level_cap')}) "
                     f"| {summary['frames']} | |")
        for crit in ("pixel", "side_distance", "pixel_smooth"):
            if f"polar_ratio_car_qsc_{crit}" not in summary:
                continue
            r = [summary.get(f"polar_ratio_car_{c}_{crit}") for c in ("tsc", "csc", "qsc")]
            e = [summary.get(f"equator_ratio_car_{c}_{crit}") for c in ("tsc", "csc", "qsc")]
            lines.append(f"| 1 | CAR / cube triangles over the poles ({crit}; TSC, CSC, QSC) | "
                         + ", ".join(fmt(v, 2) for v in r) + " | Gasiński 2010: ~2x |")
            lines.append(f"| 1 | CAR / cube triangles over the equator ({crit}; TSC, CSC, QSC) | "
                         + ", ".join(fmt(v, 2) for v in e) + " | (control) |")
        p = summary["projections"].get("qsc/pixel", {})
        lines.append(f"| 1 | QSC 1 px: triangles mean / max, refine µs mean, emit ms mean | "
                     f"{fmt(p.get('tri_mean'), 0)} / {fmt(p.get('tri_max'))} / "
                     f"{fmt(p.get('refine_us_mean'))} / {fmt(p.get('emit_ms_mean'), 2)} | |")
        u = summary.get("uniform", {})
        lines.append(f"| 2 | uniform / LOD triangles (= memory), median over frames | "
                     f"{fmt(u.get('ratio_median'), 0)} | ≥ 50x |")
        lines.append(f"| 2 | ... frames with ratio ≥ 50 / frames; lowest ratio | "
                     f"{u.get('frames_ratio_ge_50')} / {u.get('frames')}; "
                     f"{fmt(u.get('ratio_min'), 2)} (far view, frame {u.get('ratio_min_frame')}) | |")
        urows = read_csv(os.path.join(ctx["results"], "uniform.csv")) or []
        segs = []
        for seg in ("approach", "orbit", "descent", "skim"):
            vals = sorted(r["ratio"] for r in urows if r["segment"] == seg)
            if vals:
                segs.append(f"{seg} {fmt(vals[len(vals) // 2], 0)}")
        lines.append(f"| 2 | ... median ratio per segment | {'; '.join(segs)} | |")
        lines.append(f"| 2 | ... lowest ratio among frames at level ≥ 20 | "
                     f"{fmt(u.get('ratio_min_deep'), 0)} | |")
        s = summary.get("sealevel", {})
        lines.append(f"| 4 | sea-level skipping: triangles saved | "
                     f"{fmt(s.get('triangles_saved_pct'), 2)} % | geomipmap paper: +22 % |")
        lines.append(f"| 4 | sea-level skipping: refine+emit time saved | "
                     f"{fmt(s.get('time_saved_pct'), 1)} % (noise level: see README) | |")
    for h, label in ((handoff, "-b"), (handoff_gpu, "xvfb")):
        if not h:
            continue
        lines.append(f"| 5 | hand-off ({label}, {h['frames']} frames, {h['quality']}): add-on "
                     f"median ms (refine / emit / update / evaluate) | "
                     f"{fmt(h['lod_total_ms_median'], 2)} ({fmt(h['refine_ms_median'], 2)} / "
                     f"{fmt(h['emit_ms_median'], 2)} / {fmt(h['update_ms_median'], 2)} / "
                     f"{fmt(h['lod_eval_ms_median'], 2)}) | |")
        lines.append(f"| 5 | ... Blender floor median ms (push / evaluate); add-on/floor over "
                     f"all frames | {fmt(h['floor_total_ms_median'], 2)} "
                     f"({fmt(h['floor_push_ms_median'], 2)} / {fmt(h['floor_eval_ms_median'], 2)})"
                     f"; {fmt(h['lod_over_floor_total'], 2)}x | |")
        if h.get("gpu_build_ms_median") is not None:
            lines.append(f"| 5 | GPU preview per update: surface / texture upload ms "
                         f"(median, llvmpipe) | {fmt(h.get('gpu_surface_ms_median'), 3)} / "
                         f"{fmt(h['gpu_build_ms_median'], 2)} | |")
        elif h.get("gpu_note") and not handoff_gpu:
            lines.append(f"| 5 | GPU preview per update | {h['gpu_note']} | |")
    if cyc:
        agg = cyc.get("aggregate", {})
        lines.append(f"| 3 | Cycles {cyc.get('resolution')} {cyc.get('samples')} spp: "
                     f"adaptive / LOD render time | {fmt(agg.get('time_ratio'), 2)}x | ≥ 3x |")
        lines.append(f"| 3 | ... adaptive / LOD peak memory | {fmt(agg.get('mem_ratio'), 2)}x "
                     f"| ≥ 5x |")
        lines.append(f"| 3 | ... PSNR vs {cyc.get('ref_samples')} spp reference (LOD; adaptive), "
                     f"mean dB | {fmt(agg.get('psnr_lod'), 1)}; {fmt(agg.get('psnr_adaptive'), 1)}"
                     f" | ≥ 40 dB |")
        lines.append(f"| 3 | ... SSIM (LOD; adaptive), mean | {fmt(agg.get('ssim_lod'), 3)}; "
                     f"{fmt(agg.get('ssim_adaptive'), 3)} | |")
    else:
        lines.append("| 3 | Cycles adaptive subdivision comparison | not run | |")
    lines += ["", "Figures: " + ", ".join(f"`{n}`" for n in ctx["figures"] if n), "", END]
    return "\n".join(lines)


def rewrite_readme(text, readme):
    old = open(readme).read() if os.path.isfile(readme) else "# Benchmarks\n\n"
    if BEGIN in old and END in old:
        new = old[:old.index(BEGIN)] + text + old[old.index(END) + len(END):]
    else:
        new = old.rstrip("\n") + "\n\n## Results\n\n" + text + "\n"
    with open(readme, "w") as f:
        f.write(new)
    print("rewrote", os.path.relpath(readme, ROOT))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", default=os.path.join(HERE, "results"))
    ap.add_argument("--command", default="bench/run_all.sh")
    ap.add_argument("--readme", default=os.path.join(HERE, "README.md"))
    args = ap.parse_args()
    res = args.results
    summary = read_json(os.path.join(res, "path_summary.json"))
    handoff = read_json(os.path.join(res, "blender_handoff.json"))
    handoff_gpu = read_json(os.path.join(res, "blender_handoff_gpu.json"))
    cyc = read_json(os.path.join(res, "cycles.json"))
    ctx = {"machine": platform.machine(), "cpus": os.cpu_count(), "command": args.command,
           "blender": blender_version(handoff, handoff_gpu, cyc), "results": res,
           "figures": []}
    proj_rows = read_csv(os.path.join(res, "path_projections.csv"))
    if proj_rows:
        ctx["figures"].append(fig_sectors(proj_rows, ctx))
        ctx["figures"].append(fig_projections(proj_rows, ctx))
    if summary:
        ctx["figures"].append(fig_templates(summary, ctx))
    urows = read_csv(os.path.join(res, "uniform.csv"))
    if urows:
        ctx["figures"].append(fig_uniform(urows, ctx))
    hrows = read_csv(os.path.join(res, "blender_handoff.csv"))
    grows = read_csv(os.path.join(res, "blender_handoff_gpu.csv"))
    if hrows or grows:
        ctx["figures"].append(fig_handoff(hrows or grows, grows, ctx))
    if cyc:
        ctx["figures"].append(fig_cycles(cyc, ctx))
    rewrite_readme(table(summary, handoff, handoff_gpu, cyc, ctx), args.readme)


if __name__ == "__main__":
    main()
