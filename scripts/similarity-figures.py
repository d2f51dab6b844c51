"""Pairs of panels for the docs: a photo's overlay_0.png (red: the weight
of the material under the point) beside its similarity_0.png (grey: the
cosine), each 300 px wide, the point circled on the grey map.
Usage: similarity-figures.py SEGMENT_DIR X Y OUT.jpg (X, Y in the photo's pixels;
the maps have the photo's size)"""

import sys

from PIL import Image, ImageDraw

PANEL = 300
GAP = 4


def main() -> None:
    folder, x, y, out = sys.argv[1:5]
    overlay = Image.open(f"{folder}/overlay_0.png").convert("RGB")
    similarity = Image.open(f"{folder}/similarity_0.png").convert("RGB")
    scale = PANEL / overlay.width
    height = round(overlay.height * scale)
    panels = [p.resize((PANEL, height), Image.LANCZOS) for p in (overlay, similarity)]
    figure = Image.new("RGB", (2 * PANEL + GAP, height), "white")
    for i, panel in enumerate(panels):
        figure.paste(panel, (i * (PANEL + GAP), 0))
    # The point, in the photo's pixels, on the grey panel.
    cx = PANEL + GAP + float(x) * scale
    cy = float(y) * scale
    ImageDraw.Draw(figure).ellipse((cx - 4, cy - 4, cx + 4, cy + 4), outline=(220, 0, 0), width=1)
    figure.save(out, quality=88)


if __name__ == "__main__":
    main()
