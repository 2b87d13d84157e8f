#!/usr/bin/env python3
"""Relief statistics of the Earth preset (height map + detail field) beside
real terrain: the standard deviation and range of heights in square windows
of 1, 10 and 100 km, against elevation.

    /usr/bin/python3 -m bench.bench_relief [--windows 400] [--markdown]

Three comparisons:
  * the same places, the same grids: the two real DEMs shipped in
    matplotlib's sample data (jacksboro_fault_dem.npz: 3 arc-seconds, the
    Cumberland Mountains along the Jacksboro fault, Tennessee;
    topobathy.npz: about 2.4 km, Vancouver Island and the Strait of
    Georgia) and the preset sampled on their own latitude/longitude grids,
    windows on land only;
  * named places against published figures: the peak-to-valley ranges of
    high ranges, and the local-relief classes of E. H. Hammond,
    "Analysis of properties of land form geography: an application to
    broad-scale land form mapping", Annals of the Association of American
    Geographers 54(1), 1964 (range in a 6-mile, 9.65 km, window: plains
    under 300 ft = 91 m, hills 300-1,000 ft = 91-305 m, low mountains
    1,000-3,000 ft = 305-914 m, high mountains above 3,000 ft = 914 m) and
    V. Kapos, J. Rhind, M. Edwards, M. F. Price and C. Ravilious,
    "Developing a map of the world's mountain forests", in Forests in
    Sustainable Mountain Development, CABI, 2000 (land of 300-1,000 m
    counts as mountains where the elevation range within a 7 km radius
    exceeds 300 m);
  * relief against elevation over the whole land: --windows deterministic
    random land windows per size, binned by their mean elevation (median
    standard deviation and range per bin).

Sampling: 1 and 10 km windows at 3 arc-seconds (~90 m, the Jacksboro
DEM's spacing), 100 km windows at ~1 km.  Figures only, not a test.
"""
import argparse
import math
import os
import random

import numpy as np

import planetlod
from planetlod import presets

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
R = 6371000.0

# name, longitude, latitude, kind, published 10 km range (m) and its source
PLACES = [
    ("Bernese Alps (Jungfrau)", 7.96, 46.54, "mountains",
     3350, "Jungfrau 4,158 m over Lauterbrunnen 800 m, 6 km apart"),
    ("Ortler/Bormio", 10.45, 46.48, "mountains",
     2700, "Ortler 3,905 m, Bormio 1,225 m, 13 km apart; Cevedale 3,769 m"),
    ("Everest", 86.925, 27.988, "mountains",
     3500, "Everest 8,849 m, Khumbu glacier ~5,300 m within 5 km"),
    ("Jacksboro fault, TN", -84.25, 36.59, "hills",
     None, "the DEM, same grid (below)"),
    ("Black Forest", 8.1, 47.9, "hills",
     None, "Hammond hills/low mountains: 91-914 m"),
    ("Kansas plains", -98.5, 38.5, "plains",
     91, "Hammond plains: under 91 m"),
    ("Paris basin", 2.0, 48.3, "plains",
     91, "Hammond plains: under 91 m"),
]
WINDOWS = (1000.0, 10000.0, 100000.0)
SPACING = {1000.0: 1.0 / 1200.0, 10000.0: 1.0 / 1200.0, 100000.0: 1.0 / 120.0}  # degrees


def sample_data():
    import matplotlib
    folder = os.path.join(matplotlib.get_data_path(), "sample_data")
    if not os.path.isdir(folder):
        raise SystemExit(f"no matplotlib sample data in {folder}")
    return folder


def data_path(name):
    for folder in (os.path.join(ROOT, "data"), os.path.join(ROOT, "..", "shared", "data")):
        if os.path.exists(os.path.join(folder, name)):
            return os.path.join(folder, name)
    raise FileNotFoundError(name)


def earth(detail=True, overrides=None):
    s = presets.PLANETS["EARTH"]
    kwargs = dict(heightmap=data_path(s["heightmap"]), height_scale=s["height_scale"],
                  sea_level=s["sea_level"], projection=s["projection"].lower())
    if detail:
        kwargs["detail"] = dict(presets.detail_settings("EARTH"), **(overrides or {}))
    return planetlod.Planet(s["radius"], **kwargs)


def heights(planet, lon, lat):
    """Heights at arrays of longitudes and latitudes (degrees)."""
    lo, la = np.radians(np.asarray(lon, float)), np.radians(np.asarray(lat, float))
    dirs = np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], axis=-1)
    h, _normals = planet.surface(np.ascontiguousarray(dirs.reshape(-1), dtype=np.float64))
    return np.frombuffer(h, dtype=np.float64).reshape(np.shape(lo))


def window(planet, lon, lat, size):
    """The heights of a size x size metre window centred at lon, lat."""
    step = SPACING[size]
    n = max(2, int(round(size / (step * math.pi / 180.0 * R))) + 1)
    half = (n - 1) / 2.0
    k = np.arange(n) - half
    la = lat + k * step
    lo = lon + k * step / max(math.cos(math.radians(lat)), 0.05)
    grid_lo, grid_la = np.meshgrid(lo, la)
    return heights(planet, grid_lo, grid_la)


def cluster(planet, lon, lat, size):
    """Median mean/std/range of the window at a place and its 8 neighbours
    5 km away (one window is one draw of the field)."""
    shift = 5000.0 / (math.pi / 180.0 * R)
    out = [stats(window(planet, lon + i * shift / math.cos(math.radians(lat)),
                        lat + j * shift, size))
           for i in (-1, 0, 1) for j in (-1, 0, 1)]
    return tuple(float(x) for x in np.median(np.array(out), axis=0))


def stats(z):
    return float(z.mean()), float(z.std()), float(np.ptp(z))


def dem_windows(z, rows, cols, step_rows, step_cols, land=None):
    """Windows of rows x cols samples of grid z, mean/std/range per window
    (those wholly on land when `land` is given)."""
    out = []
    for i in range(0, z.shape[0] - rows + 1, step_rows):
        for j in range(0, z.shape[1] - cols + 1, step_cols):
            if land is not None and not land[i:i + rows, j:j + cols].all():
                continue
            out.append(stats(z[i:i + rows, j:j + cols]))
    return np.array(out)


def real_dems(planet):
    """Rows (place, window, real std, real range, preset std, preset range,
    windows) for the two DEMs and the preset on the same grids."""
    folder = sample_data()
    rows = []
    jb = np.load(os.path.join(folder, "jacksboro_fault_dem.npz"))
    z = jb["elevation"].astype(float)
    lat = np.linspace(float(jb["ymin"]), float(jb["ymax"]), z.shape[0])
    lon = np.linspace(float(jb["xmin"]), float(jb["xmax"]), z.shape[1])
    grid_lo, grid_la = np.meshgrid(lon, lat)
    synthetic = heights(planet, grid_lo, grid_la)
    dy = abs(float(jb["dy"])) * math.pi / 180.0 * R
    dx = abs(float(jb["dx"])) * math.pi / 180.0 * R * math.cos(math.radians(lat.mean()))
    for size in (1000.0, 10000.0):
        r, c = int(round(size / dy)) + 1, int(round(size / dx)) + 1
        real = dem_windows(z, r, c, max(1, r // 2), max(1, c // 2))
        syn = dem_windows(synthetic, r, c, max(1, r // 2), max(1, c // 2))
        rows.append(("Jacksboro DEM (hills)", size, *np.median(real[:, 1:], axis=0),
                     *np.median(syn[:, 1:], axis=0), len(real)))
    tb = np.load(os.path.join(folder, "topobathy.npz"))
    z = tb["topo"].astype(float)
    lat, lon = tb["latitude"].astype(float), tb["longitude"].astype(float) - 360.0
    grid_lo, grid_la = np.meshgrid(lon, lat)
    synthetic = heights(planet, grid_lo, grid_la)
    land = z > 0.0
    dy = abs(lat[1] - lat[0]) * math.pi / 180.0 * R
    dx = abs(lon[1] - lon[0]) * math.pi / 180.0 * R * math.cos(math.radians(lat.mean()))
    for size in (10000.0, 100000.0):
        r, c = int(round(size / dy)) + 1, int(round(size / dx)) + 1
        step = 1 if size < 50000.0 else 4
        real = dem_windows(z, r, c, step, step, land)
        syn = dem_windows(synthetic, r, c, step, step, land)
        if len(real):
            rows.append(("Vancouver Island DEM (mountains)", size,
                         *np.median(real[:, 1:], axis=0), *np.median(syn[:, 1:], axis=0),
                         len(real)))
    return rows


BINS = [(0, 200), (200, 500), (500, 1000), (1000, 2000), (2000, 3000), (3000, 4500),
        (4500, 9000)]


def land_windows(planet, count, size, seed=7):
    """count windows at deterministic random land places (mean > 0 m)."""
    rnd = random.Random(seed)
    out = []
    tries = 0
    while len(out) < count and tries < 50 * count:
        tries += 1
        lat = math.degrees(math.asin(rnd.uniform(-0.95, 0.95)))
        lon = rnd.uniform(-180.0, 180.0)
        z = window(planet, lon, lat, size)
        if z.min() <= 0.0:
            continue
        out.append(stats(z))
    return np.array(out)


def fmt(x):
    return f"{x:,.0f}"


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--windows", type=int, default=400,
                        help="random land windows per size for the elevation bins")
    parser.add_argument("--set", default="",
                        help="detail overrides, key=value,... (e.g. hills=0.25,hills_fine=2)")
    parser.add_argument("--quick", action="store_true",
                        help="the DEMs and the named places only")
    args = parser.parse_args()
    overrides = {k: float(v) for k, v in (kv.split("=") for kv in args.set.split(",") if kv)}
    planet = earth(overrides=overrides)
    print(f"planetlod from {planetlod.__file__}; Earth preset detail "
          f"{planet.detail}")

    print("\n### The same grids: real DEM against the preset (median over windows)\n")
    print("| place | window | real std | preset std | ratio | real range | preset range "
          "| ratio | windows |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, size, rs, rr, ss, sr, n in real_dems(planet):
        print(f"| {name} | {size / 1000:g} km | {fmt(rs)} | {fmt(ss)} | {ss / rs:.2f} | "
              f"{fmt(rr)} | {fmt(sr)} | {sr / rr:.2f} | {n} |")

    print("\n### Named places: the preset's windows against published figures\n")
    print("| place (median of 9 windows 5 km apart) | kind | mean elevation | std 1 / 10 / 100 km | range 1 / 10 / 100 km "
          "| published 10 km range | ratio |")
    print("|---|---|---|---|---|---|---|")
    for name, lon, lat, kind, published, source in PLACES:
        figures = [cluster(planet, lon, lat, size) for size in WINDOWS]
        mean = figures[1][0]
        std = " / ".join(fmt(f[1]) for f in figures)
        rng = " / ".join(fmt(f[2]) for f in figures)
        if published is None:
            ratio = ""
        elif kind == "plains":
            ratio = "below" if figures[1][2] <= published else f"{figures[1][2] / published:.2f}"
        else:
            ratio = f"{figures[1][2] / published:.2f}"
        bound = f"{'< ' if kind == 'plains' else ''}{fmt(published)} ({source})" \
            if published else source
        print(f"| {name} | {kind} | {fmt(mean)} | {std} | {rng} | {bound} | {ratio} |")
    if args.quick:
        return

    print(f"\n### Relief against elevation: {args.windows} random land windows per size "
          "(median std / range per bin of the window's mean elevation)\n")
    per_size = {size: land_windows(planet, args.windows, size) for size in WINDOWS}
    print("| mean elevation | " + " | ".join(f"{s / 1000:g} km std / range (n)"
                                              for s in WINDOWS) + " |")
    print("|---|" + "---|" * len(WINDOWS))
    for lo, hi in BINS:
        cells = []
        for size in WINDOWS:
            a = per_size[size]
            sel = a[(a[:, 0] >= lo) & (a[:, 0] < hi)] if len(a) else a
            cells.append(f"{fmt(np.median(sel[:, 1]))} / {fmt(np.median(sel[:, 2]))} "
                         f"({len(sel)})" if len(sel) else "-")
        print(f"| {lo:,}-{hi:,} m | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
