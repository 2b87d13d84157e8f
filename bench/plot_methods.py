#!/usr/bin/env python3
"""Figures of the LOD methods side by side, from the benches' JSON files.

    /usr/bin/python3 -m bench.plot_methods [--results bench/results]

Reads (whichever exist) methods.json (bench_methods.py --json),
method_error.json (bench_method_error.py --json), method_cycles.json and the
renders of bench_method_cycles.py (method_cycles/), and writes
fig_methods_triangles.png (triangles per frame per method on the camera
path and the descent), fig_methods_error.png (screen error against the
full-detail surface per frame; the clipmap's ring width against its error
and triangles) and fig_methods_cycles.png (the renders, method by shot).
"""
import argparse
import json
import os

import matplotlib
matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))


def triangles(data, path):
    fig, axes = plt.subplots(1, len(data), figsize=(6 * len(data), 3.8), squeeze=False)
    for ax, (title, methods) in zip(axes[0], data.items()):
        for name, rows in methods.items():
            ax.semilogy([r["tris"] for r in rows], label=name)
        ax.set_title(f"{title}: Earth map, 1 px at 1920x1080", fontsize=9)
        ax.set_xlabel("frame")
        ax.set_ylabel("triangles a frame")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def error(data, path):
    groups = {}
    for key, rows in data.items():
        title, name = key.split("|")
        groups.setdefault(title, {})[name] = rows
    fig, axes = plt.subplots(1, len(groups) + 1, figsize=(5.5 * (len(groups) + 1), 3.8),
                             squeeze=False)
    for ax, (title, methods) in zip(axes[0], groups.items()):
        for k, (name, rows) in enumerate(methods.items()):
            colour = f"C{k}"
            f = [r["frame"] for r in rows]
            ax.semilogy(f, [max(r["p99_px"], 1e-3) for r in rows], "o-", color=colour,
                        label=name)
            ax.semilogy(f, [max(r["max_px"], 1e-3) for r in rows], ":", color=colour)
        ax.axhline(1.0, color="k", lw=0.6)
        ax.set_title(f"{title}: screen error, p99 (max dotted)", fontsize=9)
        ax.set_xlabel("frame")
        ax.set_ylabel("px")
        ax.legend(fontsize=7)
    ax = axes[0, -1]
    for k, (title, methods) in enumerate(groups.items()):
        for name, rows in methods.items():
            x = np.mean([r["tris"] for r in rows])
            y = np.median([r["p99_px"] for r in rows])
            marker = "s" if name.startswith("clipmap") else "o"
            ax.loglog(x, y, marker, color=("tab:blue", "tab:orange")[k % 2])
            ax.annotate(name, (x, y), fontsize=6)
    ax.axhline(1.0, color="k", lw=0.6)
    ax.set_title("triangles (mean) against p99 error (median frame); "
                 + ", ".join(f"{c}: {t}" for c, t in zip(("blue", "orange"), groups)), fontsize=8)
    ax.set_xlabel("triangles")
    ax.set_ylabel("px")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def renders(result, folder, path):
    labels = list(result["methods"])
    shots = list(result["methods"][labels[0]]["shots"])
    fig, axes = plt.subplots(len(labels), len(shots), figsize=(3.6 * len(shots),
                                                               2.2 * len(labels)), squeeze=False)
    for i, label in enumerate(labels):
        for j, shot in enumerate(shots):
            s = result["methods"][label]["shots"][shot]
            ax = axes[i, j]
            ax.imshow(mpimg.imread(os.path.join(folder, f"{label}_{shot}.png")))
            extra = f", {s['psnr_db']:.1f} dB" if "psnr_db" in s else ""
            ax.set_title(f"{label} {shot}: {s['triangles']:,} tris, {s['render_s']:.1f} s"
                         f"{extra}", fontsize=7)
            ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=65)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", default=os.path.join(HERE, "results"))
    args = ap.parse_args()
    r = args.results
    made = []
    if os.path.exists(os.path.join(r, "methods.json")):
        with open(os.path.join(r, "methods.json")) as f:
            triangles(json.load(f), os.path.join(r, "fig_methods_triangles.png"))
        made.append("fig_methods_triangles.png")
    if os.path.exists(os.path.join(r, "method_error.json")):
        with open(os.path.join(r, "method_error.json")) as f:
            error(json.load(f), os.path.join(r, "fig_methods_error.png"))
        made.append("fig_methods_error.png")
    if os.path.exists(os.path.join(r, "method_cycles.json")):
        with open(os.path.join(r, "method_cycles.json")) as f:
            renders(json.load(f), os.path.join(r, "method_cycles"),
                    os.path.join(r, "fig_methods_cycles.png"))
        made.append("fig_methods_cycles.png")
    print("wrote", ", ".join(made) if made else "nothing (no results)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
