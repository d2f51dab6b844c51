"""python -m matseg.export onnx, run by onnxruntime."""

import numpy as np
import onnxruntime

import matseg
from matseg.export import main as export_main


def test_the_onnx_graph_gives_the_descriptors_of_matseg_at_any_size(tmp_path):
    out = tmp_path / "model.onnx"
    export_main(["onnx", "--model", "default", "--out", str(out)])
    runtime = onnxruntime.InferenceSession(str(out), providers=["CPUExecutionProvider"])
    model = matseg.Model.load("default")
    image = matseg.Generator("2d", seed=3)[1]["image"]
    for h, w in ((224, 256), (96, 160), (32, 64)):
        crop = np.ascontiguousarray(image[:h, :w])
        ours = model.describe_at_own_size(crop)
        (onnx_d,) = runtime.run(None, {"image": crop.transpose(2, 0, 1)[None].astype(np.float32)})
        assert onnx_d.shape == (1, model.dim, h, w)
        assert np.abs(onnx_d[0] - ours).max() < 1e-3
