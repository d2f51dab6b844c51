"""The safetensors files of matseg runs (`model.safetensors`) as numpy
arrays, read and written by the same code as `matseg weights` and `matseg
train` (the native module's matseg-weights)."""

import os
from typing import Any

import numpy as np
from numpy.typing import NDArray

from . import _core
from ._arrays import view

_DTYPES = {"F32": "<f4", "F16": "<f2", "F64": "<f8", "I64": "<i8", "I32": "<i4", "U8": "u1"}
_NAMES = {np.dtype(v): k for k, v in _DTYPES.items()}


def read(path: str | os.PathLike[str]) -> tuple[dict[str, NDArray[Any]], dict[str, str]]:
    """name -> numpy array, and the `__metadata__` dict (or {})."""
    path = os.fspath(path)
    tensors, metadata = _core.read_safetensors(path)
    arrays = {}
    for name, dtype, shape, data in tensors:
        if dtype not in _DTYPES:
            raise ValueError(f"{path}: {name}: unsupported dtype {dtype}")
        arrays[name] = view(data, _DTYPES[dtype], shape)
    return arrays, dict(metadata)


def write(path: str | os.PathLike[str], tensors: dict[str, NDArray[Any]],
          metadata: dict[str, object] | None = None) -> None:
    """Writes name -> numpy array (float32, float16, int64...) to `path`
    through a temporary file renamed into place."""
    entries: list[tuple[str, str, list[int], NDArray[Any]]] = []
    for name in sorted(tensors):
        a = np.ascontiguousarray(tensors[name])
        a = a.astype(a.dtype.newbyteorder("<"), copy=False)
        kind = _NAMES.get(np.dtype(a.dtype.str))
        if kind is None:
            raise ValueError(f"{name}: cannot store dtype {a.dtype}")
        entries.append((name, kind, list(a.shape), a.reshape(-1).view(np.uint8)))
    meta = [(str(k), str(v)) for k, v in (metadata or {}).items()]
    _core.write_safetensors(os.fspath(path), entries, meta)
