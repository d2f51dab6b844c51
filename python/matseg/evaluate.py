"""matseg's benchmarks and protocols for any model, as `matseg eval`
scores its own: the same protocols, the same scores, the same JSON.

    import matseg.evaluate

    class Colour:
        comparison = "euclidean"
        def describe(self, image):          # HxWx3 uint8 at the scored size
            return image / np.float32(255)  # (h, w, d) at any size

    report = matseg.evaluate.points("benchmarks/real-dev", Colour())
    report["models"][0]["all_by_material"]

A model answers one of three questions, whichever it can:

- `describe(image) -> (h, w, d)` descriptors at any stride (resized
  bilinearly to the photo, as matseg resizes its own), compared by cosine,
  or by Euclidean distance when the model's `comparison` is "euclidean";
- `similarity(image, points) -> (k, h, w)`: one map per (x, y) point of the
  `k x 2` float32 array, at any size, higher where more alike;
- `select(image, positives, negatives) -> (H, W)`: its own selection for
  the clicks so far (two `n x 2` float32 arrays), a mask or a soft map in
  0..1 at the photo's size (0.5 or more is selected): the click protocol
  only, asked after every click.

In the click protocol a model with `select` is scored by its own
selection; a `describe` model gets matseg's selection on its descriptors,
and a `similarity` model gets matseg's composition of one map per click
(docs/eval.md). `track` needs `describe` with cosine descriptors.

A plain function is taken as `describe`; a `matseg.Model` is scored as
`matseg eval` scores it. Photos are asked about one at a time, in
benchmark order, with a line per photo on stderr; Ctrl-C stops the
evaluation. What the model raises, or an answer of the wrong shape or with
NaN, stops it with a `MatsegError` naming the photo.
"""

import json
import os
import sys
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from . import _core
from ._arrays import view
from .model import DEFAULT_TRACK_SIDE, Model

#: The longer side benchmark photos are scored at, as `matseg eval`.
DEFAULT_MAX_SIDE = _core.DEFAULT_MAX_SIDE

Path = str | os.PathLike[str]


def points(bench: Path, model: Any, *, name: str | None = None, max_side: int = DEFAULT_MAX_SIDE,
           progress: bool = True) -> dict[str, Any]:
    """`model` on a point benchmark (MatSeg layout): triplet accuracy (All,
    Soft) and top-1, as `matseg eval points BENCH --json` reports them."""
    return _evaluate("points", bench, model, name, progress, max_side=max_side)


def masks(data: Path, model: Any, *, name: str | None = None, max_side: int = DEFAULT_MAX_SIDE,
          points: int = 10, erode: int = 20, min_area: int = 400, radius: float = 5.0, seed: int = 0,
          grid: int | None = None, progress: bool = True) -> dict[str, Any]:
    """`model` on a mask benchmark: mean IoU at the best threshold of each
    query point's similarity map, as `matseg eval masks DATA --json`."""
    return _evaluate("masks", data, model, name, progress, max_side=max_side, points=points, erode=erode,
                     min_area=min_area, radius=radius, seed=seed, grid=grid)


def clicks(data: Path, model: Any, *, name: str | None = None, max_side: int = DEFAULT_MAX_SIDE,
           max_clicks: int = 20, radius: float = 5.0, min_area: int = 100, unions: bool = False,
           progress: bool = True) -> dict[str, Any]:
    """The click protocol on a mask benchmark (NoC@85, NoC@90, IoU after
    each click) or a point benchmark, with matseg's selection on the
    model's descriptors, as `matseg eval clicks DATA --json`."""
    return _evaluate("clicks", data, model, name, progress, max_side=max_side, max_clicks=max_clicks,
                     radius=radius, min_area=min_area, unions=unions)


def track(bench: Path, model: Any, *, name: str | None = None, side: int = DEFAULT_TRACK_SIDE,
          progress: bool = True) -> dict[str, Any]:
    """`model` on generated sequences (`matseg generate --kind 3d --frames
    F`): each material clicked on a sequence's first frame and followed
    through its frames, with matseg's tracker on the model's descriptors
    (compared by cosine), as `matseg eval track DATA --json`. Frames reach
    the model at longer side `side` at most; a `matseg.Model` describes
    them as `matseg eval track` does."""
    native = model._native if isinstance(model, Model) else None
    return _evaluate("track", bench, model, name, progress, native=native, side=side)


def _evaluate(protocol: str, bench: Path, model: Any, name: str | None, progress: bool,
              native: _core.Model | None = None, **options: Any) -> dict[str, Any]:
    kind, answer, comparison, selects = _question(model)
    name = name or _name(model)
    photos: list[str] = []

    def told(buffer: _core.Buffer, height: int, width: int, photo: str) -> NDArray[np.uint8]:
        """The photo asked about, with a line on stderr the first time."""
        if not photos or photos[-1] != photo:
            photos.append(photo)
            if progress:
                print(f"matseg.evaluate.{protocol} {name}: photo {len(photos)} {photo}", file=sys.stderr,
                      flush=True)
        return view(buffer, np.uint8, (height, width, 3))

    def array(out: Any, what: str) -> NDArray[np.float32]:
        if not hasattr(out, "shape"):
            raise TypeError(f"{what} returned {type(out).__name__}; expected a numpy array")
        return np.ascontiguousarray(out, dtype=np.float32)

    def ask(buffer: _core.Buffer, height: int, width: int, photo: str,
            asked_points: list[tuple[float, float]]) -> NDArray[np.float32]:
        assert answer is not None, "asked only when the model answers"
        image = told(buffer, height, width, photo)
        if kind == "similarity":
            return array(answer(image, _points(asked_points)), "similarity")
        return array(answer(image), "describe")

    def select(buffer: _core.Buffer, height: int, width: int, photo: str,
               positives: list[tuple[float, float]], negatives: list[tuple[float, float]]) -> NDArray[np.float32]:
        assert selects is not None, "asked only when the model selects"
        image = told(buffer, height, width, photo)
        return array(selects(image, _points(positives), _points(negatives)), "select")

    report = _core.evaluate(protocol, os.fspath(bench), ask if answer else None, select if selects else None,
                            name, kind, comparison, json.dumps(options), native)
    result: dict[str, Any] = json.loads(report)
    return result


def _points(points: list[tuple[float, float]]) -> NDArray[np.float32]:
    """(x, y) points as the `n x 2` float32 array a model is given."""
    return np.asarray(points, dtype=np.float32).reshape(-1, 2)


def _question(model: Any) -> tuple[str, Callable[..., Any] | None, str | None, Callable[..., Any] | None]:
    """What `model` answers: the kind of its maps, the function asked for
    them (none for a model that only selects), its comparison, and its own
    selection for clicks (when it has one)."""
    if isinstance(model, Model):
        return "descriptors", lambda image: model.describe(image).transpose(1, 2, 0), "cosine", None
    comparison = getattr(model, "comparison", None)
    selects = getattr(model, "select", None)
    selects = selects if callable(selects) else None
    if hasattr(model, "describe"):
        return "descriptors", model.describe, comparison, selects
    if hasattr(model, "similarity"):
        return "similarity", model.similarity, None, selects
    if selects is not None:
        return "descriptors", None, None, selects
    if callable(model):
        return "descriptors", model, comparison, None
    raise TypeError(f"model: a {type(model).__name__} has none of describe(image), similarity(image, points) "
                    "or select(image, positives, negatives)")


def _name(model: Any) -> str:
    """The name tables give `model`: its `name`, else its class's or
    function's."""
    if isinstance(model, Model):
        return os.path.basename(os.path.normpath(model.path))
    given = getattr(model, "name", None)
    if isinstance(given, str):
        return given
    return getattr(model, "__name__", type(model).__name__)
