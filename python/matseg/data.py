"""Samples as numpy arrays: made on the fly by a generator, or read from a
stored dataset; and training batches as `matseg train` draws them."""

import dataclasses
import json
import os

import numpy as np

from . import _core


def _paths(value, name):
    """A folder, a list of folders, or None, as a list of strings."""
    if value is None:
        return []
    if isinstance(value, (str, os.PathLike)):
        return [os.fspath(value)]
    try:
        return [os.fspath(v) for v in value]
    except TypeError:
        raise TypeError(f"{name}: expected a folder or a list of folders, got {type(value).__name__}") from None


def _index(i, length, what):
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


def sample_arrays(d):
    """A sample from the native module's dict: `image` HxWx3 uint8,
    `masks` KxHxW float32 (the stored 8-bit masks / 255), `roi` HxW float32
    or None, `meta` (the sidecar) as a dict or None, and `key`."""
    h, w = d["height"], d["width"]
    image = np.frombuffer(d["image"], np.uint8).reshape(h, w, 3).copy()
    masks = np.empty((len(d["masks"]), h, w), np.float32)
    for k, m in enumerate(d["masks"]):
        masks[k] = np.frombuffer(m, np.uint8).reshape(h, w)
    masks /= 255.0
    roi = None
    if d["roi"] is not None:
        roi = np.frombuffer(d["roi"], np.uint8).reshape(h, w).astype(np.float32) / 255.0
    meta = json.loads(d["meta"]) if d["meta"] is not None else None
    return {"key": d["key"], "image": image, "masks": masks, "roi": roi, "meta": meta}


def read_image(path):
    """A photo as an HxWx3 uint8 array, decoded as the `matseg` commands
    decode it (so the pixels, and the model's answers, are theirs)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{path}: no such file")
    rgb, w, h = _core.read_rgb(path)
    return np.frombuffer(rgb, np.uint8).reshape(h, w, 3).copy()


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
    def default(cls):
        """The paper's plan: sides 224..768, ~1 MP, 2-7 images, half augmented."""
        return cls(**json.loads(_core.default_plan()))

    def to_json(self):
        return json.dumps(dataclasses.asdict(self))


def batch_arrays(items):
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
        images[i] = np.frombuffer(it["image"], np.uint8).reshape(h, w, 3).transpose(2, 0, 1)
        for j, plane in enumerate(it["weights"]):
            weights[i, j] = np.frombuffer(plane, "<f4").reshape(h, w)
        roi[i] = np.frombuffer(it["roi"], "<f4").reshape(h, w)
    return {"images": images, "weights": weights, "roi": roi}


def native_batch(native, step, plan, seed, mix):
    """Batch `step` of a native generator or dataset under `plan` (None:
    the paper's) and `seed`, with `mix` (None, or (Dataset, fraction): that
    share of the samples taken from the dataset, as `matseg train
    --mix-data`), as `batch_arrays`."""
    plan = plan or BatchPlan.default()
    if mix is not None:
        other, fraction = mix
        if not isinstance(other, Dataset):
            raise TypeError(f"mix: expected (matseg.Dataset, fraction), got {type(other).__name__}")
        mix = (other._native, float(fraction))
    return batch_arrays(native.batch(plan.to_json(), int(seed), int(step), mix))


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

    def __init__(self, kind="2d", sources=None, *, seed=0, recipe=None, samples=None,
                 textures=None, materials=None, meshes=None, hdris=None, size=None,
                 spp=None, licences="", cache_mb=None):
        if kind not in ("2d", "3d"):
            raise ValueError(f"kind: '{kind}' is not a scene kind (2d or 3d)")
        if samples is not None and (not isinstance(samples, int) or samples < 0):
            raise ValueError(f"samples: expected a whole number >= 0 or None, got {samples!r}")
        if recipe is not None and not os.path.isfile(recipe):
            raise FileNotFoundError(f"{os.fspath(recipe)}: no such recipe file")
        self._args = dict(
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
    def kind(self):
        return self._args["kind"]

    @property
    def seed(self):
        return self._args["seed"]

    @property
    def warnings(self):
        """Source files left out as unreadable, as 'skipped FILE: problem'."""
        return self._native.warnings()

    def __len__(self):
        if self.samples is None:
            raise TypeError("an unbounded generator has no length: give samples=N")
        return self.samples

    def __getitem__(self, i):
        return sample_arrays(self._native.sample(_index(i, self.samples, "Generator")))

    def files(self, i):
        """Sample i's files as `matseg generate` writes them (name: bytes)."""
        return self._native.files(_index(i, self.samples, "Generator"))

    def write(self, out, *, format="folders", shard_size=1000, num_shards=1, shard_index=0):
        """Writes the dataset (its `samples`) into `out` as `matseg generate`
        does, or job `shard_index` of `num_shards` of it, skipping samples
        already complete. Returns {"generated", "skipped", "bytes"}."""
        if self.samples is None:
            raise ValueError("write: an unbounded generator: give samples=N")
        generated, skipped, size = self._native.write(
            os.fspath(out), self.samples, format, int(shard_size), int(num_shards), int(shard_index))
        return {"generated": generated, "skipped": skipped, "bytes": size}

    def batch(self, step, plan=None, seed=0, mix=None):
        """Training batch `step` of online 2D scenes (see `batch_arrays`;
        `mix`: `native_batch`)."""
        return native_batch(self._native, step, plan, seed, mix)

    def __getstate__(self):
        return {"args": self._args, "samples": self.samples}

    def __setstate__(self, state):
        self._args, self.samples = state["args"], state["samples"]
        self._native = _core.Generator(**self._args)

    def __repr__(self):
        return f"Generator(kind={self.kind!r}, seed={self.seed}, samples={self.samples})"


class Dataset:
    """A stored dataset, MatSeg folders or WebDataset shards (of `matseg
    generate` or the original's), with random access: `ds[i]` as
    `Generator`'s samples. Picklable (reopened in each process)."""

    def __init__(self, root):
        root = os.fspath(root)
        if not os.path.exists(root):
            raise FileNotFoundError(f"{root}: no such file or folder")
        self.root = root
        self._native = _core.Dataset(root)

    def __len__(self):
        return len(self._native)

    def __getitem__(self, i):
        return sample_arrays(self._native.sample(_index(i, len(self), self.root)))

    def key(self, i):
        """Sample i's folder name or shard key."""
        return self._native.key(_index(i, len(self), self.root))

    def batch(self, step, plan=None, seed=0, mix=None):
        """Training batch `step` drawn from the dataset (see `batch_arrays`;
        `mix`: `native_batch`)."""
        return native_batch(self._native, step, plan, seed, mix)

    def __getstate__(self):
        return {"root": self.root}

    def __setstate__(self, state):
        self.__init__(state["root"])

    def __repr__(self):
        return f"Dataset({self.root!r}, {len(self)} samples)"


class FeatureCache:
    """A feature cache made by `matseg features`: training samples already
    run through a model's encoder, with their ground truth on the stride-4
    grid. `batch(step, plan, seed)` is batch `step` of `matseg train
    --features` on it. Picklable (reopened in each process)."""

    def __init__(self, root):
        root = os.fspath(root)
        if not os.path.exists(root):
            raise FileNotFoundError(f"{root}: no such folder")
        self.root = root
        self._native = _core.FeatureCache(root)
        self.manifest = json.loads(self._native.manifest())

    def __len__(self):
        return len(self._native)

    def difference(self, manifest):
        """What differs between this cache and the one `manifest` (a dict,
        as a run's `features` keeps it) describes, in words; None when they
        are the same."""
        return self._native.difference(json.dumps(manifest))

    def batch(self, step, plan, seed=0):
        """Batch `step`: `taps` (the encoder's four taps, BxCxhxw float32
        each), `lab` (the cells' L*a*b* colours, Bx3xhxw), `weights` (BxKxhxw,
        zero-padded to the batch's most materials) and `roi` (Bxhxw), all on
        the stride-4 grid but the taps."""
        samples = self._native.batch(plan.to_json(), int(seed), int(step))

        def array(sample, name):
            shape, data = sample[name]
            return np.frombuffer(data, "<f2").reshape(shape).astype(np.float32)

        def stacked(name):
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

    def __getstate__(self):
        return {"root": self.root}

    def __setstate__(self, state):
        self.__init__(state["root"])

    def __repr__(self):
        return f"FeatureCache({self.root!r}, {len(self)} samples)"
