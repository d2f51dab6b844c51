"""PyTorch data loading under the name users import (`import matseg.torch`):
the streams of `matseg.streams`, which the package itself imports by that
name so that its own `import torch` always means PyTorch."""

from . import _requires

_requires.torch("matseg.torch")

from .streams import BatchStream, FeatureStream, SampleStream, consumer, my_indices, sample_tensors

__all__ = ["BatchStream", "FeatureStream", "SampleStream", "consumer", "my_indices", "sample_tensors"]
