"""numpy views of the native module's buffers (no copy: the array keeps
the buffer alive and may be written)."""

from typing import Any

import numpy as np
from numpy.typing import DTypeLike, NDArray

from . import _core


def view(buffer: _core.Buffer | bytes, dtype: DTypeLike, shape: tuple[int, ...] | list[int]) -> NDArray[Any]:
    """`buffer` as an array of `dtype` and `shape`."""
    return np.frombuffer(memoryview(buffer), dtype).reshape(shape)
