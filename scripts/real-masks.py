"""Rasterise the hand-drawn polygons of a mask benchmark into its mask PNGs.

For every ``polygons/NAME.json`` under the benchmark directory (next to
``NAME.jpg``) this writes ``NAME.mask0.png``, ``NAME.mask1.png``, ... (8-bit
greyscale, the photo's size, 255 inside, 0 outside), one per material in the
JSON's order, and ``NAME.roi.png`` (255 scored, 0 not) when the JSON has
``ignore`` polygons. The JSON reads::

    {"materials": [{"label": "moss",
                    "polygons": [[[x, y], ...], ...],
                    "holes": [[[x, y], ...], ...],
                    "minus": [0]}, ...],
     "ignore": [[[x, y], ...], ...]}

in the photo's pixel coordinates (0..width, 0..height). A material is the
union of its polygons less its holes and less the earlier materials named in
``minus``; masks of one photo must not overlap. A vertex outside the photo or
overlapping masks stop the script with a one-line error. ``--preview DIR``
also writes each photo with its masks tinted and outlined in white, and
the ignored pixels hatched.

Usage: python scripts/real-masks.py BENCHMARK_DIR [--preview DIR]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

Polygon = list[list[float]]
COLOURS = [
    (230, 25, 75),
    (60, 180, 75),
    (0, 130, 200),
    (255, 225, 25),
    (145, 30, 180),
    (70, 240, 240),
]


def fill(polygons: list[Polygon], size: tuple[int, int], where: str) -> np.ndarray:
    """Rasterise the union of the polygons (outline included) as a bool array."""
    canvas = Image.new("L", size, 0)
    draw = ImageDraw.Draw(canvas)
    for polygon in polygons:
        for x, y in polygon:
            if not (0 <= x <= size[0] and 0 <= y <= size[1]):
                raise ValueError(
                    f"{where}: vertex ({x}, {y}) outside the {size[0]}x{size[1]} photo"
                )
        if len(polygon) < 3:
            raise ValueError(f"{where}: a polygon with fewer than 3 vertices")
        draw.polygon([(x, y) for x, y in polygon], fill=255, outline=255)
    return np.asarray(canvas) >= 128


def rasterise(
    spec: dict, size: tuple[int, int], name: str
) -> tuple[list[np.ndarray], np.ndarray | None]:
    """The photo's masks (JSON order) and its ROI (None without ignore polygons)."""
    masks: list[np.ndarray] = []
    for k, material in enumerate(spec["materials"]):
        where = f"{name} material {k} ({material['label']})"
        mask = fill(material["polygons"], size, where)
        mask &= ~fill(material.get("holes", []), size, where)
        for j in material.get("minus", []):
            if not 0 <= j < k:
                raise ValueError(f"{where}: minus names {j}, not an earlier material")
            mask &= ~masks[j]
        for j, other in enumerate(masks):
            if (n := int((mask & other).sum())) > 0:
                raise ValueError(f"{where} overlaps material {j} on {n} pixels")
        if not mask.any():
            raise ValueError(f"{where} is empty")
        masks.append(mask)
    ignore = spec.get("ignore", [])
    roi = ~fill(ignore, size, f"{name} ignore") if ignore else None
    return masks, roi


def preview(
    photo: Image.Image, masks: list[np.ndarray], roi: np.ndarray | None
) -> Image.Image:
    """The photo with each mask tinted, outlined in white, ignored pixels hatched."""
    out = np.asarray(photo.convert("RGB")).astype(np.float32)
    for k, mask in enumerate(masks):
        out[mask] = 0.55 * out[mask] + 0.45 * np.array(COLOURS[k % len(COLOURS)])
    for mask in masks:
        edge = mask & ~(
            np.roll(mask, 1, 0)
            & np.roll(mask, -1, 0)
            & np.roll(mask, 1, 1)
            & np.roll(mask, -1, 1)
        )
        out[edge] = 255
    if roi is not None:
        yy, xx = np.mgrid[: roi.shape[0], : roi.shape[1]]
        out[~roi & ((xx + yy) % 6 < 2)] = 0
    return Image.fromarray(out.clip(0, 255).astype(np.uint8))


def main() -> int:
    """Rasterise every polygons/NAME.json of the benchmark directory."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "benchmark", type=Path, help="directory with NAME.jpg and polygons/NAME.json"
    )
    parser.add_argument(
        "--preview", type=Path, help="also write NAME.png previews to this directory"
    )
    args = parser.parse_args()
    specs = sorted((args.benchmark / "polygons").glob("*.json"))
    if not specs:
        print(f"error: no polygons/*.json under {args.benchmark}", file=sys.stderr)
        return 1
    total = 0
    for path in specs:
        name = path.stem
        photo = Image.open(args.benchmark / f"{name}.jpg")
        try:
            masks, roi = rasterise(json.loads(path.read_text()), photo.size, name)
        except ValueError as error:
            print(f"error: {error}", file=sys.stderr)
            return 1
        for old in args.benchmark.glob(f"{name}.mask*.png"):
            old.unlink()
        (args.benchmark / f"{name}.roi.png").unlink(missing_ok=True)
        for k, mask in enumerate(masks):
            Image.fromarray(mask.astype(np.uint8) * 255).save(
                args.benchmark / f"{name}.mask{k}.png"
            )
        if roi is not None:
            Image.fromarray(roi.astype(np.uint8) * 255).save(
                args.benchmark / f"{name}.roi.png"
            )
        if args.preview:
            args.preview.mkdir(parents=True, exist_ok=True)
            preview(photo, masks, roi).save(args.preview / f"{name}.png")
        total += len(masks)
    print(f"{len(specs)} photos, {total} masks")
    return 0


if __name__ == "__main__":
    sys.exit(main())
