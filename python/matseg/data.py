"""Samples as numpy arrays: made on the fly by a generator, or read from a
stored dataset; and training batches as `matseg train` draws them."""

import dataclasses
import json
import os
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from . import _core, _requires
from ._arrays import view

#: A folder or file name.
PathLike = str | os.PathLike[str]
#: A sample: `key`, `image`, `masks`, `roi`, `meta` (see `sample_arrays`).
Sample = dict[str, Any]
#: A training batch of numpy arrays (see `batch_arrays`).
Batch = dict[str, Any]


def _paths(value: PathLike | Iterable[PathLike] | None, name: str) -> list[str]:
    """A folder, a list of folders, or None, as a list of strings."""
    if value is None:
        return []
    if isinstance(value, (str, os.PathLike)):
        return [os.fspath(value)]
    try:
        return [os.fspath(v) for v in value]
    except TypeError:
        raise TypeError(f"{name}: expected a folder or a list of folders, got {type(value).__name__}") from None


def _index(i: object, length: int | None, what: str) -> int:
    """`i` as a non-negative index below `length` (None: unbounded)."""
    if isinstance(i, (bool, np.bool_)) or not isinstance(i, (int, np.integer)):
        raise TypeError(f"{what}: sample indices are integers, got {type(i).__name__}")
    i = int(i)
    if length is not None and i < 0:
        i += length
    if i < 0 or (length is not None and i >= length):
        n = "unbounded" if length is None else f"{length} samples"
        raise IndexError(f"{what}: sample {i} is out of range ({n})")
    return i


def sample_arrays(d: dict[str, Any]) -> Sample:
    """A sample from the native module's dict: `image` HxWx3 uint8,
    `masks` KxHxW float32 (the stored 8-bit masks / 255), `roi` HxW float32
    or None, `meta` (the sidecar) as a dict or None, and `key`."""
    h, w = d["height"], d["width"]
    image = view(d["image"], np.uint8, (h, w, 3))
    masks = np.empty((len(d["masks"]), h, w), np.float32)
    for k, m in enumerate(d["masks"]):
        masks[k] = view(m, np.uint8, (h, w))
    masks /= 255.0
    roi = None
    if d["roi"] is not None:
        roi = view(d["roi"], np.uint8, (h, w)).astype(np.float32) / 255.0
    meta = json.loads(d["meta"]) if d["meta"] is not None else None
    return {"key": d["key"], "image": image, "masks": masks, "roi": roi, "meta": meta}


def read_image(path: PathLike) -> NDArray[np.uint8]:
    """A photo as an HxWx3 uint8 array, decoded as the `matseg` commands
    decode it (so the pixels, and the model's answers, are theirs)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{path}: no such file")
    rgb, w, h = _core.read_rgb(path)
    return view(rgb, np.uint8, (h, w, 3))


@dataclasses.dataclass(frozen=True)
class BatchPlan:
    """How training batches are drawn: one random size per batch (sides
    multiples of 32 in min_side..max_side), about `pixels` pixels in all,
    min_images..max_images images, a share `p_augment` augmented. The
    defaults are the paper's (as `matseg train`)."""

    min_side: int
    max_side: int
    pixels: int
    min_images: int
    max_images: int
    p_augment: float

    @classmethod
    def default(cls) -> "BatchPlan":
        """The paper's plan: sides 224..768, ~1 MP, 2-7 images, half augmented."""
        return cls(**json.loads(_core.default_plan()))

    def to_json(self) -> str:
        """The plan as the native module takes it."""
        return json.dumps(dataclasses.asdict(self))


def batch_arrays(items: list[dict[str, Any]]) -> Batch:
    """A batch from the native module's list: `images` Bx3xHxW uint8,
    `weights` BxKxHxW float32 (per-material weights summing to 1 inside the
    ROI, zero-padded to the batch's most materials), `roi` BxHxW float32."""
    b = len(items)
    h, w = items[0]["height"], items[0]["width"]
    k = max(len(it["weights"]) for it in items)
    images = np.empty((b, 3, h, w), np.uint8)
    weights = np.zeros((b, k, h, w), np.float32)
    roi = np.empty((b, h, w), np.float32)
    for i, it in enumerate(items):
        images[i] = view(it["image"], np.uint8, (h, w, 3)).transpose(2, 0, 1)
        for j, plane in enumerate(it["weights"]):
            weights[i, j] = view(plane, "<f4", (h, w))
        roi[i] = view(it["roi"], "<f4", (h, w))
    return {"images": images, "weights": weights, "roi": roi}


def native_batch(
    native: _core.Generator | _core.Dataset,
    step: int,
    plan: "BatchPlan | None",
    seed: int,
    mix: "tuple[Dataset, float] | None",
) -> Batch:
    """Batch `step` of a native generator or dataset under `plan` (None:
    the paper's) and `seed`, with `mix` (None, or (Dataset, fraction): that
    share of the samples taken from the dataset, as `matseg train
    --mix-data`), as `batch_arrays`."""
    plan = plan or BatchPlan.default()
    native_mix = None
    if mix is not None:
        other, fraction = mix
        if not isinstance(other, Dataset):
            raise TypeError(f"mix: expected (matseg.Dataset, fraction), got {type(other).__name__}")
        native_mix = (other._native, float(fraction))
    return batch_arrays(native.batch(plan.to_json(), int(seed), int(step), native_mix))


class Generator:
    """Samples of a 2D or 3D synthetic dataset, made on demand: `gen[i]` is
    sample i of `matseg generate --kind KIND --seed SEED` with the same
    sources and recipe (`gen.files(i)` its files, byte for byte).

    sources: folders of natural photos; textures (2d), materials, meshes,
    hdris (3d): folders; None: the fetched corpus, else the bundled assets.
    recipe: a TOML recipe file (docs/recipe.md). samples: the dataset's
    length (None: unbounded, `len()` then raises TypeError). Picklable: a
    DataLoader worker reloads the sources in its own process.
    """

    def __init__(self, kind: str = "2d", sources: PathLike | Iterable[PathLike] | None = None, *,
                 seed: int = 0, recipe: PathLike | None = None, samples: int | None = None,
                 textures: PathLike | Iterable[PathLike] | None = None,
                 materials: PathLike | Iterable[PathLike] | None = None,
                 meshes: PathLike | Iterable[PathLike] | None = None,
                 hdris: PathLike | Iterable[PathLike] | None = None, size: int | None = None,
                 spp: int | None = None, licences: str = "", cache_mb: int | None = None) -> None:
        if kind not in ("2d", "3d"):
            raise ValueError(f"kind: '{kind}' is not a scene kind (2d or 3d)")
        if samples is not None and (not isinstance(samples, int) or samples < 0):
            raise ValueError(f"samples: expected a whole number >= 0 or None, got {samples!r}")
        if recipe is not None and not os.path.isfile(recipe):
            raise FileNotFoundError(f"{os.fspath(recipe)}: no such recipe file")
        self._args: dict[str, Any] = dict(
            kind=kind, seed=int(seed), photos=_paths(sources, "sources"),
            textures=_paths(textures, "textures"), materials=_paths(materials, "materials"),
            meshes=_paths(meshes, "meshes"), hdris=_paths(hdris, "hdris"),
            recipe=None if recipe is None else os.fspath(recipe), size=size, spp=spp,
            licences=licences,
            cache_mb=_core.DEFAULT_CACHE_MB if cache_mb is None else int(cache_mb),
        )
        for folder in (*self._args["photos"], *self._args["textures"], *self._args["materials"],
                       *self._args["hdris"], *self._args["meshes"]):
            if not os.path.exists(folder):
                raise FileNotFoundError(f"{folder}: no such file or folder")
        self.samples = samples
        self._native = _core.Generator(**self._args)

    @property
    def kind(self) -> str:
        """The scene kind, 2d or 3d."""
        return str(self._args["kind"])

    @property
    def seed(self) -> int:
        """The dataset's seed."""
        return int(self._args["seed"])

    @property
    def warnings(self) -> list[str]:
        """Source files left out as unreadable, as 'skipped FILE: problem'."""
        return self._native.warnings()

    def __len__(self) -> int:
        if self.samples is None:
            raise TypeError("an unbounded generator has no length: give samples=N")
        return self.samples

    def __getitem__(self, i: int) -> Sample:
        return sample_arrays(self._native.sample(_index(i, self.samples, "Generator")))

    def files(self, i: int) -> dict[str, bytes]:
        """Sample i's files as `matseg generate` writes them (name: bytes)."""
        return self._native.files(_index(i, self.samples, "Generator"))

    def write(self, out: PathLike, *, format: str = "folders", shard_size: int = 1000, num_shards: int = 1,
              shard_index: int = 0) -> dict[str, int]:
        """Writes the dataset (its `samples`) into `out` as `matseg generate`
        does, or job `shard_index` of `num_shards` of it, skipping samples
        already complete. Returns {"generated", "skipped", "bytes"}."""
        if self.samples is None:
            raise ValueError("write: an unbounded generator: give samples=N")
        generated, skipped, size = self._native.write(
            os.fspath(out), self.samples, format, int(shard_size), int(num_shards), int(shard_index))
        return {"generated": generated, "skipped": skipped, "bytes": size}

    def batch(self, step: int, plan: "BatchPlan | None" = None, seed: int = 0,
              mix: "tuple[Dataset, float] | None" = None) -> Batch:
        """Training batch `step` of online 2D scenes (see `batch_arrays`;
        `mix`: `native_batch`)."""
        return native_batch(self._native, step, plan, seed, mix)

    def __getstate__(self) -> dict[str, Any]:
        return {"args": self._args, "samples": self.samples}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self._args, self.samples = state["args"], state["samples"]
        self._native = _core.Generator(**self._args)

    def __repr__(self) -> str:
        return f"Generator(kind={self.kind!r}, seed={self.seed}, samples={self.samples})"


class Dataset:
    """A stored dataset, MatSeg folders or WebDataset shards (of `matseg
    generate` or the original's), with random access: `ds[i]` as
    `Generator`'s samples. Picklable (reopened in each process)."""

    def __init__(self, root: PathLike) -> None:
        self._open(os.fspath(root))

    def _open(self, root: str) -> None:
        if not os.path.exists(root):
            raise FileNotFoundError(f"{root}: no such file or folder")
        self.root = root
        self._native = _core.Dataset(root)

    def __len__(self) -> int:
        return len(self._native)

    def __getitem__(self, i: int) -> Sample:
        return sample_arrays(self._native.sample(_index(i, len(self), self.root)))

    def key(self, i: int) -> str:
        """Sample i's folder name or shard key."""
        return self._native.key(_index(i, len(self), self.root))

    def batch(self, step: int, plan: BatchPlan | None = None, seed: int = 0,
              mix: "tuple[Dataset, float] | None" = None) -> Batch:
        """Training batch `step` drawn from the dataset (see `batch_arrays`;
        `mix`: `native_batch`)."""
        return native_batch(self._native, step, plan, seed, mix)

    def __getstate__(self) -> dict[str, Any]:
        return {"root": self.root}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self._open(state["root"])

    def __repr__(self) -> str:
        return f"Dataset({self.root!r}, {len(self)} samples)"


class FeatureCache:
    """A feature cache made by `matseg features`: training samples already
    run through a model's encoder, with their ground truth on the stride-4
    grid. `batch(step, plan, seed)` is batch `step` of `matseg train
    --features` on it. Picklable (reopened in each process)."""

    def __init__(self, root: PathLike) -> None:
        self._open(os.fspath(root))

    def _open(self, root: str) -> None:
        if not os.path.exists(root):
            raise FileNotFoundError(f"{root}: no such folder")
        _requires.libtorch_build("matseg.FeatureCache")
        self.root = root
        self._native = _core.FeatureCache(root)
        self.manifest: dict[str, Any] = json.loads(self._native.manifest())

    def __len__(self) -> int:
        return len(self._native)

    def difference(self, manifest: dict[str, Any]) -> str | None:
        """What differs between this cache and the one `manifest` (a dict,
        as a run's `features` keeps it) describes, in words; None when they
        are the same."""
        return self._native.difference(json.dumps(manifest))

    def batch(self, step: int, plan: BatchPlan, seed: int = 0) -> Batch:
        """Batch `step`: `taps` (the encoder's four taps, BxCxhxw float32
        each), `lab` (the cells' L*a*b* colours, Bx3xhxw), `weights` (BxKxhxw,
        zero-padded to the batch's most materials) and `roi` (Bxhxw), all on
        the stride-4 grid but the taps."""
        samples = self._native.batch(plan.to_json(), int(seed), int(step))

        def array(sample: dict[str, Any], name: str) -> NDArray[np.float32]:
            shape, data = sample[name]
            return view(data, "<f2", shape).astype(np.float32)

        def stacked(name: str) -> NDArray[np.float32]:
            return np.stack([array(s, name) for s in samples])

        weights = [array(s, "weights") for s in samples]
        k = max(w.shape[0] for w in weights)
        padded = np.zeros((len(weights), k) + weights[0].shape[1:], np.float32)
        for i, w in enumerate(weights):
            padded[i, : w.shape[0]] = w
        return {
            "taps": [stacked(name) for name in ("s4", "s8", "s16", "s32")],
            "lab": stacked("lab"),
            "weights": padded,
            "roi": stacked("roi"),
        }

    def __getstate__(self) -> dict[str, Any]:
        return {"root": self.root}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self._open(state["root"])

    def __repr__(self) -> str:
        return f"FeatureCache({self.root!r}, {len(self)} samples)"
