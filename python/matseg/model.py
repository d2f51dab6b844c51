"""A trained net, as `matseg segment` uses it: descriptors, similarity to
clicked points, selections by positive and negative clicks, segmentation
by points or by clustering."""

import os
from collections.abc import Iterable, Iterator, Sequence
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from . import _core
from ._arrays import view

#: Points as (x, y) pixel pairs.
Points = Sequence[tuple[float, float]] | NDArray[Any]

#: Radius of a query point's disc, in pixels (as `matseg segment`).
DEFAULT_RADIUS = _core.DEFAULT_RADIUS

#: The longer side video frames are described at (as `matseg track`).
DEFAULT_TRACK_SIDE = _core.DEFAULT_TRACK_SIDE

_MEMORY, _SAMPLES, _CONFIDENT, _PRIOR, _TEMPERATURE = _core.DEFAULT_TRACKER


class TrackedFrame(NamedTuple):
    """One frame of `Model.track`: what `matseg track` writes for it."""

    #: HxW uint8: 0 where no clicked material is, k where point k - 1's is.
    labels: NDArray[np.uint8]
    #: KxHxW float32: per point, each pixel's probability of its material.
    probability: NDArray[np.float32]
    #: Per point, the share of the frame labelled with it.
    areas: list[float]


class Selection(NamedTuple):
    """A selection made by clicks (`Model.select`)."""

    #: HxW float32: each pixel's similarity to the positive clicks, lowered
    #: where a negative click's material is as near (one click alone: its
    #: similarity map).
    soft: NDArray[np.float32]
    #: HxW bool: the selection's own decision.
    mask: NDArray[np.bool_]
    #: The selection saved as JSON (`selection.json`, what `matseg apply`
    #: reads): the clicks' descriptors and the model's name.
    saved: str


def check_image(image: object) -> NDArray[np.uint8]:
    """`image` as a C-contiguous HxWx3 uint8 array, or TypeError/ValueError
    saying what is wrong."""
    if not isinstance(image, np.ndarray):
        raise TypeError(f"image: expected an HxWx3 uint8 numpy array, got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise TypeError(f"image: expected dtype uint8 (0..255 RGB), got {image.dtype}")
    if image.ndim != 3 or image.shape[2] != 3 or image.shape[0] == 0 or image.shape[1] == 0:
        raise ValueError(f"image: expected shape HxWx3, got {image.shape}")
    return np.ascontiguousarray(image)


def check_points(points: Points, name: str = "points", empty: bool = False) -> list[tuple[float, float]]:
    """`points` (the argument `name`) as a list of (x, y) float pairs; none
    only when `empty` allows it."""
    if empty and len(points) == 0:
        return []
    try:
        pts = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name}: expected (x, y) pairs of numbers") from None
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) == 0:
        raise ValueError(f"{name}: expected a list of (x, y) pairs, got shape {pts.shape}")
    if not np.isfinite(pts).all():
        raise ValueError(f"{name}: coordinates must be finite")
    return [(float(x), float(y)) for x, y in pts]


class Model:
    """A trained net on the CPU. `Model.load("default")` is the shipped
    model; a run folder of `matseg train` or `python -m matseg.train`, or
    its weights file, loads the same way."""

    def __init__(self, native: _core.Model, path: str) -> None:
        self._native = native
        self.path = path

    @classmethod
    def load(cls, name: str | os.PathLike[str] = "default") -> "Model":
        """Loads `default` (the shipped model), a run folder or a weights
        file; FileNotFoundError when there is none."""
        name = os.fspath(name)
        path = os.path.normpath(os.fspath(_core.resolve_model(name)))
        if name != "default" and not os.path.exists(path):
            raise FileNotFoundError(f"{path}: no such run folder or weights file")
        return cls(_core.Model(path), path)

    @property
    def dim(self) -> int:
        """Descriptor channels."""
        return self._native.dim()

    def describe(self, image: NDArray[np.uint8]) -> NDArray[np.float32]:
        """Unit descriptors DxHxW float32 of `image` (HxWx3 uint8), as
        `matseg segment` computes them."""
        image = check_image(image)
        h, w = image.shape[:2]
        raw = self._native.describe(image)
        return view(raw, "<f4", (-1, h, w))

    def describe_at_own_size(self, image: NDArray[np.uint8]) -> NDArray[np.float32]:
        """The net alone on `image` (sides multiples of 32) at its own size
        and one scale: what the PyTorch and ONNX copies of the net compute."""
        image = check_image(image)
        h, w = image.shape[:2]
        raw = self._native.describe_at_own_size(image)
        return view(raw, "<f4", (-1, h, w))

    def similarity(self, image: NDArray[np.uint8], points: Points,
                   radius: float = DEFAULT_RADIUS) -> NDArray[np.float32]:
        """Each point's similarity map, KxHxW float32 (cosine, 1 = the
        point's material), for points (x, y) in pixels."""
        image = check_image(image)
        h, w = image.shape[:2]
        maps, _ = self._native.similarity(image, check_points(points), float(radius))
        return view(maps, "<f4", (-1, h, w))

    def select(self, image: NDArray[np.uint8], positive: Points, negative: Points = (),
               radius: float = DEFAULT_RADIUS) -> Selection:
        """The selection `positive` clicks of one material and `negative`
        clicks ((x, y) pixels) make on `image`, as `matseg segment --point
        1:X,Y --not X,Y` makes it: a `Selection` (soft map, mask, saved)."""
        image = check_image(image)
        h, w = image.shape[:2]
        pos = check_points(positive, "positive")
        neg = check_points(negative, "negative", empty=True)
        soft, mask, saved = self._native.select(image, pos, neg, float(radius))
        return Selection(
            soft=view(soft, "<f4", (h, w)),
            mask=view(mask, np.uint8, (h, w)).astype(bool),
            saved=saved,
        )

    def segment(self, image: NDArray[np.uint8], points: Points | None = None, k: int | None = None,
                radius: float = DEFAULT_RADIUS, seed: int = 0) -> NDArray[np.int32]:
        """HxW int32 labels: each pixel's most similar point (two points or
        more), or with `k` the photo split into k materials by clustering
        its descriptors (labels 0..k-1)."""
        image = check_image(image)
        h, w = image.shape[:2]
        if (points is None) == (k is None):
            raise ValueError("segment: give either points or k")
        if points is None:
            if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
                raise TypeError(f"k: expected a whole number, got {type(k).__name__}")
            clusters, _ = self._native.cluster(image, int(k), int(seed))
            return view(clusters, "<i4", (h, w))
        pts = check_points(points)
        if len(pts) < 2:
            raise ValueError("segment: two points or more (one point: use similarity)")
        _, nearest = self._native.similarity(image, pts, float(radius))
        assert nearest is not None, "two points or more have nearest-point labels"
        return view(nearest, "<i4", (h, w))

    def track(self, frames: Iterable[NDArray[np.uint8]], points: Points, frame: int = 0,
              radius: float = DEFAULT_RADIUS, side: int = DEFAULT_TRACK_SIDE, memory: int = _MEMORY,
              samples: int = _SAMPLES, confident: float = _CONFIDENT, prior: float = _PRIOR,
              temperature: float = _TEMPERATURE, negative: Points = ()) -> Iterator[TrackedFrame]:
        """Follows the materials under `points` ((x, y) pixels, clicked on
        frame number `frame`; none of them taking the materials under the
        `negative` clicks on that frame) through `frames`, an iterable of HxWx3 uint8
        arrays of one size (a list, or a generator decoding a video): yields
        a `TrackedFrame` for every frame from the first, as `matseg track`
        labels them (docs/video.md). Frames are taken one at a time; those
        before the clicked one are held until it comes. The settings are
        `matseg track`'s."""
        pts = check_points(points)
        neg = check_points(negative, "negative", empty=True)
        if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)) or frame < 0:
            raise ValueError(f"frame: expected a frame number from 0, got {frame!r}")
        settings = (int(memory), int(samples), float(confident), float(prior), float(temperature))
        frames = iter(frames)
        held = []
        for index in range(int(frame) + 1):
            try:
                held.append(check_image(next(frames)))
            except StopIteration:
                raise IndexError(f"frame {frame}: past the end: the frames are {index}") from None
        clicked = held[-1]
        tracker = _core.Tracker(self._native, clicked, (pts, neg), float(radius), int(side), settings)

        def step(image: NDArray[np.uint8]) -> TrackedFrame:
            fh, fw = image.shape[:2]
            probability, labels, areas = tracker.step(image)
            return TrackedFrame(
                labels=view(labels, np.uint8, (fh, fw)),
                probability=view(probability, "<f4", (-1, fh, fw)),
                areas=list(areas),
            )

        def tracked() -> Iterator[TrackedFrame]:
            while held:
                yield step(held.pop(0))
            for image in frames:
                yield step(check_image(image))

        return tracked()

    def __repr__(self) -> str:
        return f"Model({self.path!r})"
