"""The safetensors files of matseg runs (`model.safetensors`) as numpy
arrays, read and written by the same code as `matseg weights` and `matseg
train` (the native module's matseg-weights)."""

import os

import numpy as np

from . import _core

_DTYPES = {"F32": "<f4", "F16": "<f2", "F64": "<f8", "I64": "<i8", "I32": "<i4", "U8": "u1"}
_NAMES = {np.dtype(v): k for k, v in _DTYPES.items()}


def read(path):
    """name -> numpy array, and the `__metadata__` dict (or {})."""
    path = os.fspath(path)
    tensors, metadata = _core.read_safetensors(path)
    arrays = {}
    for name, dtype, shape, data in tensors:
        if dtype not in _DTYPES:
            raise ValueError(f"{path}: {name}: unsupported dtype {dtype}")
        arrays[name] = np.frombuffer(data, _DTYPES[dtype]).reshape(shape).copy()
    return arrays, dict(metadata)


def write(path, tensors, metadata=None):
    """Writes name -> numpy array (float32, float16, int64...) to `path`
    through a temporary file renamed into place."""
    entries = []
    for name in sorted(tensors):
        a = np.ascontiguousarray(tensors[name])
        a = a.astype(a.dtype.newbyteorder("<"), copy=False)
        kind = _NAMES.get(np.dtype(a.dtype.str))
        if kind is None:
            raise ValueError(f"{name}: cannot store dtype {a.dtype}")
        entries.append((name, kind, list(a.shape), a.tobytes()))
    meta = [(str(k), str(v)) for k, v in (metadata or {}).items()]
    _core.write_safetensors(os.fspath(path), entries, meta)
