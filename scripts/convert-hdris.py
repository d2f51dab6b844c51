"""Converts DWAB-compressed OpenEXR environment maps into ZIP-compressed
half-float EXRs (the lossless form of the bundled copies in assets/hdris/),
keeping every value (no tone mapping, no resizing; only the slightly negative
values DWAB's lossy coding leaves in dark pixels become 0), and prints a JSON line per
file with the source's largest and mean (solid-angle weighted) luminance so
the conversion can be checked by reading the result back.

Usage: python convert-hdris.py OUT_DIR FILE.exr...
"""

import json
import os
import sys

import numpy as np
import OpenEXR


def rgb_of(exr_file):
    channels = exr_file.channels()
    if "RGB" in channels:
        return channels["RGB"].pixels.astype(np.float32)
    return np.stack([channels[c].pixels for c in "RGB"], axis=-1).astype(np.float32)


def stats(rgb):
    lum = 0.2126 * rgb[..., 0] + 0.7152 * rgb[..., 1] + 0.0722 * rgb[..., 2]
    h = lum.shape[0]
    sin = np.sin(np.pi * (np.arange(h) + 0.5) / h)[:, None]
    return float(lum.max()), float((lum * sin).sum() / (sin.sum() * lum.shape[1]))


def main():
    out_dir, files = sys.argv[1], sys.argv[2:]
    os.makedirs(out_dir, exist_ok=True)
    for path in files:
        with OpenEXR.File(path) as source:
            rgb = rgb_of(source)
        if not np.isfinite(rgb).all():
            print(f"{path}: non-finite pixels, skipped", file=sys.stderr)
            continue
        # DWAB is lossy: dark pixels come back slightly negative. Radiance
        # cannot be, so they become 0.
        negative = int((rgb < 0).sum())
        rgb = np.maximum(rgb, 0.0)
        name = os.path.basename(path)
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        target = os.path.join(out_dir, name)
        # Half floats (11-bit mantissa, up to 65504) halve the size; maps
        # brighter than that stay in full floats.
        stored = rgb.astype(np.float16) if rgb.max() < 65504 else rgb
        with OpenEXR.File(header, {"RGB": stored}) as converted:
            converted.write(target + ".part")
        os.replace(target + ".part", target)
        max_lum, mean_lum = stats(rgb)
        print(json.dumps({"file": name, "width": rgb.shape[1], "height": rgb.shape[0],
                          "max_luminance": max_lum, "mean_luminance": mean_lum,
                          "negative_values_zeroed": negative}))


if __name__ == "__main__":
    main()
