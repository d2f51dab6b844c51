"""Types of `matseg._core`, the package's native module (python/src).

Arrays come back as `Buffer`s, which `numpy.frombuffer` wraps without a
copy; arrays going in are C-contiguous numpy arrays of the stated dtype.
"""

from collections.abc import Callable, Sequence
from os import PathLike
from typing import Any, final

import numpy as np
from numpy.typing import NDArray

_Path = str | PathLike[str]
#: An array going in: C-contiguous, of the dtype the method states.
_BufferLike = NDArray[Any] | bytes | bytearray | memoryview
#: An RGB image going in: a C-contiguous HxWx3 uint8 array.
_Image = NDArray[np.uint8]
#: A sample as the native module hands it over: sizes, buffers, JSON text.
_SampleDict = dict[str, Any]
#: A stored dataset mixed into batches, and the share taken from it.
_Mix = tuple[Dataset, float] | None

class MatsegError(Exception):
    """A matseg job failed; the message names the file and the problem."""

@final
class Buffer:
    """Bytes made by the native module, exported through the buffer
    protocol (one-dimensional, writable, format `B`)."""

    def __len__(self) -> int: ...
    def __buffer__(self, flags: int, /) -> memoryview: ...

@final
class Generator:
    def __init__(
        self,
        kind: str,
        seed: int,
        photos: list[_Path],
        textures: list[_Path],
        materials: list[_Path],
        meshes: list[_Path],
        hdris: list[_Path],
        recipe: _Path | None,
        size: int | None,
        spp: int | None,
        licences: str,
        cache_mb: int,
    ) -> None: ...
    def sample(self, index: int) -> _SampleDict: ...
    def files(self, index: int) -> dict[str, bytes]: ...
    def batch(self, plan: str, seed: int, step: int, mix: _Mix = None) -> list[_SampleDict]: ...
    def write(
        self, out: _Path, n: int, format: str, shard_size: int, num_shards: int, shard_index: int
    ) -> tuple[int, int, int]: ...
    def warnings(self) -> list[str]: ...

@final
class Dataset:
    def __init__(self, root: _Path) -> None: ...
    def __len__(self) -> int: ...
    def key(self, index: int) -> str: ...
    def sample(self, index: int) -> _SampleDict: ...
    def batch(self, plan: str, seed: int, step: int, mix: _Mix = None) -> list[_SampleDict]: ...

@final
class FeatureCache:
    def __init__(self, dir: _Path) -> None: ...
    def __len__(self) -> int: ...
    def manifest(self) -> str: ...
    def difference(self, manifest: str) -> str | None: ...
    def batch(self, plan: str, seed: int, step: int) -> list[dict[str, tuple[list[int], Buffer]]]: ...

@final
class Model:
    def __init__(self, name: _Path) -> None: ...
    def dim(self) -> int: ...
    def describe(self, image: _Image) -> Buffer: ...
    def describe_at_own_size(self, image: _Image) -> Buffer: ...
    def similarity(
        self, image: _Image, points: list[tuple[float, float]], radius: float
    ) -> tuple[Buffer, Buffer | None]: ...
    def cluster(self, image: _Image, k: int, seed: int) -> tuple[Buffer, int]: ...
    def select(
        self,
        image: _Image,
        positive: list[tuple[float, float]],
        negative: list[tuple[float, float]],
        radius: float,
    ) -> tuple[Buffer, Buffer, str]: ...

@final
class Tracker:
    def __init__(
        self,
        model: Model,
        image: _Image,
        clicks: tuple[list[tuple[float, float]], list[tuple[float, float]]],
        radius: float,
        side: int,
        tracker: tuple[int, int, float, float, float],
    ) -> None: ...
    def step(self, image: _Image) -> tuple[Buffer, Buffer, list[float]]: ...

def default_plan() -> str: ...
def matseg_loss(
    descriptors: _BufferLike,
    weights: _BufferLike,
    roi: _BufferLike,
    shape: tuple[int, int, int, int],
    materials: int,
) -> float | None: ...
def resolve_model(name: _Path) -> str: ...
def run_files(name: _Path) -> tuple[str, str]: ...
def read_rgb(path: _Path) -> tuple[Buffer, int, int]: ...
def net_constants() -> dict[str, Any]: ...
def net_preset(name: str, encoder_features: bool, colour_features: bool) -> str: ...
def train_defaults() -> dict[str, Any]: ...
def lr_schedule(options: str) -> list[float]: ...
def plot_losses(metrics: _Path, png: _Path) -> None: ...
def score_points(model: _Path, bench: _Path, max_side: int) -> float: ...
def evaluate(
    protocol: str, bench: _Path, ask: Callable[..., Any] | None, select: Callable[..., Any] | None, name: str,
    kind: str, comparison: str | None, options: str, native: Model | None = None,
) -> str: ...
def read_safetensors(path: _Path) -> tuple[list[tuple[str, str, list[int], Buffer]], list[tuple[str, str]]]: ...
def write_safetensors(
    path: _Path, tensors: Sequence[tuple[str, str, list[int], _BufferLike]], metadata: Sequence[tuple[str, str]]
) -> None: ...

DEFAULT_CACHE_MB: int
#: Whether this build has what needs libtorch (its `torch` feature).
WITH_TORCH: bool
DEFAULT_MAX_SIDE: int
DEFAULT_RADIUS: float
DEFAULT_TRACK_SIDE: int
DEFAULT_TRACKER: tuple[int, int, float, float, float]
