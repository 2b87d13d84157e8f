#!/usr/bin/env python3
"""Writes the procedural planets' maps into data/ (deterministic: fixed seeds).

    /usr/bin/python3 tools/make_procedural_maps.py

mars-like-height.png    1024x512 16-bit grey, equirectangular: fBm hills, one
                        large basin, a volcano and ~120 craters.
mars-like-color.png     1024x512 8-bit RGB, the height through a rust colour ramp.
asteroid-height.png     512x256 16-bit grey: a lumpy body (low-order bumps +
                        craters) meant for a large height scale.
Needs numpy only (python3-numpy); PNGs are written with zlib.
"""
import os
import sys

import struct
import zlib

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def directions(width, height):
    lon = (np.arange(width) + 0.5) / width * 2 * np.pi - np.pi
    lat = np.pi / 2 - (np.arange(height) + 0.5) / height * np.pi
    lon, lat = np.meshgrid(lon, lat)
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], -1)


def value_noise(dirs, rng, octaves, base_freq):
    """Sum of random-phase plane waves over the sphere (seamless, no poles artefacts)."""
    out = np.zeros(dirs.shape[:2])
    amp = 1.0
    for octave in range(octaves):
        freq = base_freq * 2 ** octave
        for _ in range(6):
            k = rng.normal(size=3)
            k /= np.linalg.norm(k)
            out += amp * np.sin(freq * (dirs @ k) + rng.uniform(0, 2 * np.pi))
        amp *= 0.5
    return out / np.abs(out).max()


def craters(dirs, rng, count, rmin, rmax):
    out = np.zeros(dirs.shape[:2])
    for _ in range(count):
        c = rng.normal(size=3)
        c /= np.linalg.norm(c)
        r = rmin * (rmax / rmin) ** rng.uniform() ** 2
        d = np.arccos(np.clip(dirs @ c, -1, 1)) / r
        bowl = np.where(d < 1, d * d - 1, 0.0)
        rim = 0.35 * np.exp(-((d - 1) / 0.25) ** 2)
        out += r * (bowl + rim)
    return out


def normalise(h):
    return (h - h.min()) / (h.max() - h.min())


def write_png(name, pixels):
    """Minimal PNG writer (grey or RGB, 8 or 16 bit) with zlib: no imaging library needed."""
    height, width = pixels.shape[:2]
    channels = 1 if pixels.ndim == 2 else pixels.shape[2]
    depth = 16 if pixels.dtype == np.uint16 else 8
    rows = pixels.reshape(height, width * channels).astype(">u2" if depth == 16 else "u1")
    raw = b"".join(b"\0" + row.tobytes() for row in rows)

    def chunk(tag, data):
        return (struct.pack(">I", len(data)) + tag + data
                + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF))
    header = struct.pack(">IIBBBBB", width, height, depth, 0 if channels == 1 else 2, 0, 0, 0)
    with open(os.path.join(ROOT, "data", name), "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
                + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def main():
    rng = np.random.default_rng(20240501)
    dirs = directions(1024, 512)
    h = 0.6 * value_noise(dirs, rng, 5, 2.0)
    basin = np.array([0.3, -0.8, 0.52]) / np.linalg.norm([0.3, -0.8, 0.52])
    h -= 1.2 * np.exp(-(np.arccos(np.clip(dirs @ basin, -1, 1)) / 0.5) ** 2)
    volcano = np.array([-0.6, 0.4, 0.3]) / np.linalg.norm([-0.6, 0.4, 0.3])
    h += 1.5 * np.exp(-(np.arccos(np.clip(dirs @ volcano, -1, 1)) / 0.08) ** 2)
    h += 4.0 * craters(dirs, rng, 120, 0.01, 0.25)
    h = normalise(h)
    write_png("mars-like-height.png", (h * 65535).astype(np.uint16))
    ramp = np.array([[0.25, 0.12, 0.08], [0.55, 0.27, 0.14], [0.76, 0.45, 0.27], [0.9, 0.75, 0.6]])
    t = h * (len(ramp) - 1)
    i = np.minimum(t.astype(int), len(ramp) - 2)
    f = (t - i)[..., None]
    colour = ramp[i] * (1 - f) + ramp[i + 1] * f
    write_png("mars-like-color.png", (colour * 255).astype(np.uint8))

    rng = np.random.default_rng(433)
    dirs = directions(512, 256)
    h = value_noise(dirs, rng, 2, 1.0) + 3.0 * craters(dirs, rng, 40, 0.05, 0.5)
    write_png("asteroid-height.png", (normalise(h) * 65535).astype(np.uint16))
    return 0


if __name__ == "__main__":
    sys.exit(main())
