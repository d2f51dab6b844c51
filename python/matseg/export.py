"""Exporting the net for other runtimes.

    python -m matseg.export onnx --model default --out model.onnx

The ONNX graph takes `image`, float32 Nx3xHxW RGB in 0..255 (H and W any
multiples of 32, dynamic), and gives `descriptors`, float32 NxDxHxW unit
vectors: the net alone at the image's own size, one scale, as
`matseg.Model.describe_at_own_size`. `matseg segment` additionally shrinks
large photos to the model's inference side and averages several sizes;
a host program does that around the graph (docs/python.md).
"""

from . import _requires

_requires.torch("python -m matseg.export")

import argparse
import os
import sys
from collections.abc import Sequence
from typing import Any

import torch
from torch import Tensor, nn

from . import net as netlib


class RgbToDescriptors(nn.Module):
    """0..255 RGB in, unit descriptors out."""

    def __init__(self, net: netlib.MaterialNet) -> None:
        super().__init__()
        self.net = net

    def forward(self, image: Tensor) -> Tensor:
        """Unit descriptors of 0..255 RGB images Bx3xHxW."""
        return self.net(netlib.normalise(image))


def drop_intermediate_shapes(path: str) -> None:
    """Removes the exporter's shapes of intermediate values: it names some
    symbolic sizes alike that differ at other image sizes (the PSP's pooled
    grids), and onnxruntime then plans buffers wrongly. Without them the
    runtime infers each shape from the input's."""
    import onnx

    model = onnx.load(path)
    del model.graph.value_info[:]
    onnx.save(model, path)


def export_onnx(model: str | os.PathLike[str], out: str, opset: int = 18,
                max_side: int = 4096) -> dict[str, Any]:
    """Writes the ONNX graph of run `model` to `out` (through a temporary
    file renamed into place); returns the net's run.json."""
    net, run = netlib.load(model)
    wrapped = RgbToDescriptors(net).eval()
    blocks_h = torch.export.Dim("blocks_h", min=1, max=max_side // 32)
    blocks_w = torch.export.Dim("blocks_w", min=1, max=max_side // 32)
    example = torch.zeros(1, 3, 64, 96)
    tmp = f"{out}.{os.getpid()}.tmp"
    try:
        torch.onnx.export(
            wrapped, (example,), tmp, input_names=["image"], output_names=["descriptors"],
            dynamic_shapes={"image": {0: torch.export.Dim("batch", min=1, max=64), 2: 32 * blocks_h, 3: 32 * blocks_w}},
            opset_version=opset, dynamo=True, external_data=False, verbose=False,
        )
        drop_intermediate_shapes(tmp)
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return run


def main(argv: Sequence[str] | None = None) -> None:
    """`python -m matseg.export`: parses `argv` (default: the command line) and exports."""
    p = argparse.ArgumentParser(prog="python -m matseg.export", description="Export the matseg net.")
    sub = p.add_subparsers(dest="format", required=True)
    onnx = sub.add_parser("onnx", help="ONNX graph with dynamic batch, height and width")
    onnx.add_argument("--model", default="default", help="default, a run folder or a weights file")
    onnx.add_argument("--out", required=True, help="the .onnx file to write")
    onnx.add_argument("--opset", type=int, default=18)
    args = p.parse_args(sys.argv[1:] if argv is None else argv)
    export_onnx(args.model, args.out, args.opset)
    print(f"{args.out}: {os.path.getsize(args.out) / 1e6:.1f} MB (image Nx3xHxW 0..255 -> descriptors NxDxHxW)")


if __name__ == "__main__":
    main()
