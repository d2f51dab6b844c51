"""A trained net, as `matseg segment` uses it: descriptors, similarity to
clicked points, segmentation by points or by clustering."""

import os
from typing import NamedTuple

import numpy as np

from . import _core

#: Radius of a query point's disc, in pixels (as `matseg segment`).
DEFAULT_RADIUS = _core.DEFAULT_RADIUS

#: The longer side video frames are described at (as `matseg track`).
DEFAULT_TRACK_SIDE = _core.DEFAULT_TRACK_SIDE

_MEMORY, _SAMPLES, _CONFIDENT, _PRIOR, _TEMPERATURE = _core.DEFAULT_TRACKER


class TrackedFrame(NamedTuple):
    """One frame of `Model.track`: what `matseg track` writes for it."""

    #: HxW uint8: 0 where no clicked material is, k where point k - 1's is.
    labels: np.ndarray
    #: KxHxW float32: per point, each pixel's probability of its material.
    probability: np.ndarray
    #: Per point, the share of the frame labelled with it.
    areas: list


def check_image(image):
    """`image` as a C-contiguous HxWx3 uint8 array, or TypeError/ValueError
    saying what is wrong."""
    if not isinstance(image, np.ndarray):
        raise TypeError(f"image: expected an HxWx3 uint8 numpy array, got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise TypeError(f"image: expected dtype uint8 (0..255 RGB), got {image.dtype}")
    if image.ndim != 3 or image.shape[2] != 3 or image.shape[0] == 0 or image.shape[1] == 0:
        raise ValueError(f"image: expected shape HxWx3, got {image.shape}")
    return np.ascontiguousarray(image)


def check_points(points):
    """`points` as a list of (x, y) float pairs."""
    try:
        pts = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError("points: expected (x, y) pairs of numbers") from None
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) == 0:
        raise ValueError(f"points: expected a list of (x, y) pairs, got shape {pts.shape}")
    if not np.isfinite(pts).all():
        raise ValueError("points: coordinates must be finite")
    return [(float(x), float(y)) for x, y in pts]


class Model:
    """A trained net on the CPU. `Model.load("default")` is the shipped
    model; a run folder of `matseg train` or `python -m matseg.train`, or
    its weights file, loads the same way."""

    def __init__(self, native, path):
        self._native = native
        self.path = path

    @classmethod
    def load(cls, name="default"):
        name = os.fspath(name)
        path = os.path.normpath(os.fspath(_core.resolve_model(name)))
        if name != "default" and not os.path.exists(path):
            raise FileNotFoundError(f"{path}: no such run folder or weights file")
        return cls(_core.Model(path), path)

    @property
    def dim(self):
        """Descriptor channels."""
        return self._native.dim()

    def describe(self, image):
        """Unit descriptors DxHxW float32 of `image` (HxWx3 uint8), as
        `matseg segment` computes them."""
        image = check_image(image)
        h, w = image.shape[:2]
        raw = self._native.describe(image.tobytes(), w, h)
        return np.frombuffer(raw, "<f4").reshape(-1, h, w).copy()

    def describe_at_own_size(self, image):
        """The net alone on `image` (sides multiples of 32) at its own size
        and one scale: what the PyTorch and ONNX copies of the net compute."""
        image = check_image(image)
        h, w = image.shape[:2]
        raw = self._native.describe_at_own_size(image.tobytes(), w, h)
        return np.frombuffer(raw, "<f4").reshape(-1, h, w).copy()

    def similarity(self, image, points, radius=DEFAULT_RADIUS):
        """Each point's similarity map, KxHxW float32 (cosine, 1 = the
        point's material), for points (x, y) in pixels."""
        image = check_image(image)
        h, w = image.shape[:2]
        maps, _ = self._native.similarity(image.tobytes(), w, h, check_points(points), float(radius))
        return np.frombuffer(maps, "<f4").reshape(-1, h, w).copy()

    def segment(self, image, points=None, k=None, radius=DEFAULT_RADIUS, seed=0):
        """HxW int32 labels: each pixel's most similar point (two points or
        more), or with `k` the photo split into k materials by clustering
        its descriptors (labels 0..k-1)."""
        image = check_image(image)
        h, w = image.shape[:2]
        if (points is None) == (k is None):
            raise ValueError("segment: give either points or k")
        if k is not None:
            if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
                raise TypeError(f"k: expected a whole number, got {type(k).__name__}")
            labels, _ = self._native.cluster(image.tobytes(), w, h, int(k), int(seed))
        else:
            pts = check_points(points)
            if len(pts) < 2:
                raise ValueError("segment: two points or more (one point: use similarity)")
            _, labels = self._native.similarity(image.tobytes(), w, h, pts, float(radius))
        return np.frombuffer(labels, "<i4").reshape(h, w).copy()

    def track(self, frames, points, frame=0, radius=DEFAULT_RADIUS, side=DEFAULT_TRACK_SIDE,
              memory=_MEMORY, samples=_SAMPLES, confident=_CONFIDENT, prior=_PRIOR,
              temperature=_TEMPERATURE):
        """Follows the materials under `points` ((x, y) pixels, clicked on
        frame number `frame`) through `frames`, an iterable of HxWx3 uint8
        arrays of one size (a list, or a generator decoding a video): yields
        a `TrackedFrame` for every frame from the first, as `matseg track`
        labels them (docs/video.md). Frames are taken one at a time; those
        before the clicked one are held until it comes. The settings are
        `matseg track`'s."""
        pts = check_points(points)
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
        h, w = clicked.shape[:2]
        tracker = _core.Tracker(self._native, clicked.tobytes(), w, h, pts, float(radius),
                                int(side), settings)

        def step(image):
            fh, fw = image.shape[:2]
            probability, labels, areas = tracker.step(image.tobytes(), fw, fh)
            return TrackedFrame(
                labels=np.frombuffer(labels, np.uint8).reshape(fh, fw).copy(),
                probability=np.frombuffer(probability, "<f4").reshape(-1, fh, fw).copy(),
                areas=list(areas),
            )

        def tracked():
            while held:
                yield step(held.pop(0))
            for image in frames:
                yield step(check_image(image))

        return tracked()

    def __repr__(self):
        return f"Model({self.path!r})"
