"""matseg runs' safetensors files as numpy arrays, under the name users
import (`from matseg import safetensors`): the reader and writer of
`matseg.tensor_files`, which the package itself imports by that name so
that it never stands in for the PyPI `safetensors` package."""

from .tensor_files import read, write

__all__ = ["read", "write"]
