"""matseg from Python: synthetic material scenes with exact soft
annotations, stored datasets, and trained models that find "all of this
material" in a photo.

    import matseg
    gen = matseg.Generator("2d", seed=0, samples=1000)
    s = gen[0]                    # image HxWx3 uint8, masks KxHxW float32, roi, meta
    model = matseg.Model.load("default")
    maps = model.similarity(s["image"], [(40, 60)])

`matseg.evaluate` scores any model (an object with `describe(image)` or
`similarity(image, points)`) by matseg's benchmarks and protocols.
`matseg.torch` (PyTorch data loading), `python -m matseg.train` (training
under torchrun), `python -m matseg.export` (ONNX) and `python -m
matseg.ray` (generation on a Ray cluster) import their heavy dependencies
only when used.
"""

from ._core import MatsegError
from .data import BatchPlan, Dataset, FeatureCache, Generator, read_image
from .model import Model

__all__ = ["BatchPlan", "Dataset", "FeatureCache", "Generator", "MatsegError", "Model", "read_image"]
