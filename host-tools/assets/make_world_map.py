#!/usr/bin/env python3
"""Regenerates world_300x150.png, the binarised equirectangular world map of the globe example.

Source: the land mask shipped in the PyPI package `global-land-mask` 1.0.0 (MIT), derived from
NOAA's GLOBE 30-arc-second elevation dataset (public domain, U.S. Government work).
Usage: pip install numpy global-land-mask && python3 make_world_map.py [OUT.png]
Each output pixel is land (black, 0) when at least half of its 72 x 72 mask cells are land.
"""
import os
import struct
import sys
import zlib

import numpy as np
from global_land_mask import globe

W, H = 300, 150


def main() -> None:
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "world_300x150.png")
    mask = ~globe._mask  # _mask is (21600 lat rows, 43200 lon cols), True = ocean
    lat = globe._lat
    if lat[0] < lat[-1]:  # make row 0 the north
        mask = mask[::-1]
    rows, cols = mask.shape
    fy, fx = rows // H, cols // W
    cells = mask[: H * fy, : W * fx].reshape(H, fy, W, fx).mean(axis=(1, 3))
    land = cells >= 0.5
    # PNG, 1-bit greyscale: 0 = black = land (ink), 1 = white = sea.
    raw = b""
    for y in range(H):
        bits = np.packbits(~land[y])
        raw += b"\x00" + bits.tobytes()

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", W, H, 1, 0, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    with open(out, "wb") as f:
        f.write(png)
    print(f"{out}: {W}x{H}, land {land.mean() * 100:.1f} %, {len(png)} bytes")


if __name__ == "__main__":
    main()
