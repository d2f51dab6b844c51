"""PyTorch data loading: samples or training batches split across
DataLoader workers and DDP ranks, each index to exactly one of them.

    from torch.utils.data import DataLoader
    import matseg, matseg.torch
    gen = matseg.Generator("2d", seed=0)
    loader = DataLoader(matseg.torch.BatchStream(gen, steps=1000), batch_size=None, num_workers=4)
    for batch in loader:            # images Bx3xHxW (the net's input), weights BxKxHxW, roi BxHxW
        ...

`FeatureStream` does the same for the batches of a feature cache
(`matseg features`): the encoder's taps and the targets on its grid.

The split: the consumer with global number g = worker * world_size + rank
of G = world_size * workers takes indices start + g, start + g + G, ...;
as a DataLoader takes its workers' items in turn, rank r sees indices
start + r, start + r + world_size, ... in order, whatever its number of
workers (so a run's first n steps on W ranks used indices start..start+nW-1).
"""

from . import _requires

_requires.torch("matseg.streams")

from collections.abc import Iterator
from typing import Any

import torch
from torch.utils.data import IterableDataset, get_worker_info

from .data import BatchPlan, Dataset, FeatureCache, Generator, Sample
from .net import normalise


def consumer() -> tuple[int, int]:
    """(this consumer's number, how many consumers) across the DDP ranks
    (when torch.distributed is initialised) and the DataLoader workers."""
    rank, world = 0, 1
    if torch.distributed.is_available() and torch.distributed.is_initialized():
        rank, world = torch.distributed.get_rank(), torch.distributed.get_world_size()
    info = get_worker_info()
    worker, workers = (info.id, info.num_workers) if info is not None else (0, 1)
    return worker * world + rank, world * workers


def my_indices(start: int, stop: int | None, number: int, count: int) -> Iterator[int]:
    """The indices of consumer `number` of `count` in start..stop (stop
    None: unbounded)."""
    i = start + number
    while stop is None or i < stop:
        yield i
        i += count


def sample_tensors(sample: Sample) -> dict[str, Any]:
    """A sample's arrays as tensors: image 3xHxW uint8, masks KxHxW, roi HxW."""
    out = {"key": sample["key"], "image": torch.from_numpy(sample["image"]).permute(2, 0, 1)}
    out["masks"] = torch.from_numpy(sample["masks"])
    if sample["roi"] is not None:
        out["roi"] = torch.from_numpy(sample["roi"])
    return out


class SampleStream(IterableDataset):
    """The samples start..stop of a `matseg.Generator` or `matseg.Dataset`
    (stop None: the source's length, or unbounded for an unbounded
    generator), split across workers and ranks. Samples differ in size:
    use batch_size=None, or `BatchStream` for the net's batches."""

    def __init__(self, source: Generator | Dataset, start: int = 0, stop: int | None = None) -> None:
        self.source, self.start = source, start
        if stop is None:
            try:
                stop = len(source)
            except TypeError:
                stop = None
        self.stop = stop

    def __iter__(self) -> Iterator[dict[str, Any]]:
        number, count = consumer()
        for i in my_indices(self.start, self.stop, number, count):
            yield sample_tensors(self.source[i])


class _StepStream(IterableDataset):
    """Steps first_step..first_step+steps (None: unbounded) split across
    workers and ranks, each yielding `self.batch(step)`."""

    def __init__(self, steps: int | None, first_step: int) -> None:
        self.first_step = first_step
        self.stop = None if steps is None else first_step + steps

    def batch(self, step: int) -> dict[str, Any]:
        """Batch `step` as tensors."""
        raise NotImplementedError

    def __iter__(self) -> Iterator[dict[str, Any]]:
        number, count = consumer()
        for step in my_indices(self.first_step, self.stop, number, count):
            yield self.batch(step)


class BatchStream(_StepStream):
    """Training batches as `matseg train` draws them (`BatchPlan`: one
    random size per batch, samples fitted and augmented; batch `s` depends
    only on (seed, s)), steps first_step..first_step+steps split across
    workers and ranks; `mix`: (Dataset, fraction) mixed into the source's
    samples, as `matseg train --mix-data`. A batch: images Bx3xHxW float32
    (normalised, the net's input), weights BxKxHxW, roi BxHxW, step."""

    def __init__(self, source: Generator | Dataset, plan: BatchPlan | None = None, seed: int = 0,
                 steps: int | None = None, first_step: int = 0, mix: tuple[Dataset, float] | None = None) -> None:
        super().__init__(steps, first_step)
        self.source, self.plan, self.seed, self.mix = source, plan or BatchPlan.default(), seed, mix

    def batch(self, step: int) -> dict[str, Any]:
        """Batch `step` as tensors."""
        b = self.source.batch(step, self.plan, self.seed, self.mix)
        return {
            "images": normalise(torch.from_numpy(b["images"]).float()),
            "weights": torch.from_numpy(b["weights"]),
            "roi": torch.from_numpy(b["roi"]),
            "step": step,
        }


class FeatureStream(_StepStream):
    """The batches of `matseg train --features` on a `matseg.FeatureCache`
    (under `plan`, whose pixels set the images a batch, and `seed`), steps
    first_step..first_step+steps split across workers and ranks: taps (a
    list of four BxCxhxw float32 tensors), lab, weights and roi on the
    stride-4 grid, step."""

    def __init__(self, cache: FeatureCache, plan: BatchPlan, seed: int = 0, steps: int | None = None,
                 first_step: int = 0) -> None:
        super().__init__(steps, first_step)
        self.cache, self.plan, self.seed = cache, plan, seed

    def batch(self, step: int) -> dict[str, Any]:
        """Batch `step` as tensors."""
        b = self.cache.batch(step, self.plan, self.seed)
        return {
            "taps": [torch.from_numpy(t) for t in b["taps"]],
            "lab": torch.from_numpy(b["lab"]),
            "weights": torch.from_numpy(b["weights"]),
            "roi": torch.from_numpy(b["roi"]),
            "step": step,
        }
