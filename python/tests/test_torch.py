"""matseg.torch: samples and batches split across workers and ranks."""

import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader

import matseg
import matseg.torch as mt

PLAN = matseg.BatchPlan(min_side=64, max_side=128, pixels=3 * 96 * 96, min_images=2, max_images=4, p_augment=0.5)


@pytest.mark.parametrize("count", [1, 2, 3, 8])
def test_every_index_goes_to_exactly_one_consumer(count):
    taken = [i for n in range(count) for i in mt.my_indices(5, 40, n, count)]
    assert sorted(taken) == list(range(5, 40))


def test_consumers_span_ranks_and_workers(monkeypatch):
    monkeypatch.setattr(torch.distributed, "is_initialized", lambda: True)
    monkeypatch.setattr(torch.distributed, "get_rank", lambda: 1)
    monkeypatch.setattr(torch.distributed, "get_world_size", lambda: 2)
    info = type("Info", (), {"id": 1, "num_workers": 3})()
    # The streams look the worker up where they are defined.
    import matseg.streams

    monkeypatch.setattr(matseg.streams, "get_worker_info", lambda: info)
    assert mt.consumer() == (3, 6)


@pytest.mark.parametrize("world,workers", [(1, 1), (1, 3), (2, 1), (2, 3), (4, 2)])
def test_each_rank_sees_every_world_th_index_in_order(world, workers):
    # A DataLoader yields its workers' items in turn: worker j's i-th item
    # is the rank's (i * workers + j)-th.
    for rank in range(world):
        per_worker = [list(mt.my_indices(7, 7 + 24 * world, j * world + rank, world * workers))
                      for j in range(workers)]
        in_turn = [per_worker[j][i] for i in range(len(per_worker[0])) for j in range(workers)
                   if i < len(per_worker[j])]
        assert in_turn == [7 + rank + world * k for k in range(24)]


def test_a_dataloader_with_workers_sees_each_sample_once():
    gen = matseg.Generator("2d", seed=1, samples=6)
    loader = DataLoader(mt.SampleStream(gen), batch_size=None, num_workers=2)
    seen = [s["key"] for s in loader]
    assert sorted(seen) == [f"{i:08}" for i in range(6)]
    first = next(iter(mt.SampleStream(gen, start=4)))
    assert first["image"].shape[0] == 3 and first["image"].dtype == torch.uint8
    assert torch.equal(first["masks"], torch.from_numpy(gen[4]["masks"]))


def test_batches_follow_the_plan_and_are_reproducible():
    gen = matseg.Generator("2d", seed=1)
    stream = mt.BatchStream(gen, PLAN, seed=3, steps=4)
    loader = DataLoader(stream, batch_size=None, num_workers=2)
    batches = {b["step"]: b for b in loader}
    assert list(batches) == [0, 1, 2, 3]
    for step, b in batches.items():
        n, c, h, w = b["images"].shape
        assert c == 3 and h % 32 == 0 and w % 32 == 0 and 64 <= min(h, w) and max(h, w) <= 128
        assert PLAN.min_images <= n <= PLAN.max_images
        assert b["weights"].shape[0] == n and b["weights"].shape[2:] == (h, w) and b["roi"].shape == (n, h, w)
        # Weights are fractions summing to 1 wherever a material is, 0
        # elsewhere; resampled with the image, they blend near edges. The
        # ROI (mask sum >= 10) lies inside where materials are, and is kept
        # where its resampled value is >= 0.5: there the weights sum to at
        # least that.
        sums = b["weights"].sum(1)
        assert b["weights"].min() >= 0 and sums.max() <= 1 + 1e-4
        inside = b["roi"] > 0
        assert inside.any() and sums[inside].min() >= 0.5 - 1e-4
        assert set(b["roi"].unique().tolist()) <= {0.0, 1.0}
        again = stream.batch(step)
        assert torch.equal(again["images"], b["images"]) and torch.equal(again["weights"], b["weights"])


def test_a_mixed_in_dataset_takes_its_share_of_the_samples(folders_2d):
    gen, ds = matseg.Generator("2d", seed=1), matseg.Dataset(folders_2d)
    for step in range(3):
        # None of the samples from the dataset: the generator's own batch;
        # all of them, into the dataset itself: the dataset's own batch.
        alone, none_mixed = gen.batch(step, PLAN, 3), gen.batch(step, PLAN, 3, mix=(ds, 0.0))
        assert all(np.array_equal(alone[k], none_mixed[k]) for k in alone)
        own, all_mixed = ds.batch(step, PLAN, 3), ds.batch(step, PLAN, 3, mix=(ds, 1.0))
        assert all(np.array_equal(own[k], all_mixed[k]) for k in own)
    streamed = mt.BatchStream(gen, PLAN, seed=3, mix=(ds, 0.0)).batch(1)
    assert torch.equal(streamed["images"], mt.BatchStream(gen, PLAN, seed=3).batch(1)["images"])
    with pytest.raises(ValueError, match="mix fraction 1.5: expected 0..1"):
        gen.batch(0, PLAN, 3, mix=(ds, 1.5))
    with pytest.raises(TypeError, match="matseg.Dataset"):
        gen.batch(0, PLAN, 3, mix=(gen, 0.5))  # type: ignore[arg-type]


def test_stored_datasets_give_batches_too(folders_2d):
    b = mt.BatchStream(matseg.Dataset(folders_2d), PLAN, seed=0).batch(0)
    assert b["images"].dtype == torch.float32 and b["images"].shape[0] >= 2


def test_the_public_module_names_do_not_shadow_pypi_inside_the_package():
    # matseg.torch and matseg.safetensors are what users import; the package
    # imports their implementations by names no PyPI package has.
    import pathlib

    import matseg.safetensors
    import matseg.streams
    import matseg.tensor_files

    assert mt.BatchStream is matseg.streams.BatchStream
    assert matseg.safetensors.read is matseg.tensor_files.read
    package = pathlib.Path(matseg.__file__).parent
    for source in package.glob("*.py"):
        if source.name in ("torch.py", "safetensors.py"):
            continue
        text = source.read_text()
        for shadowing in ("from .torch import", "from . import torch", "from .safetensors import",
                          "from . import safetensors"):
            assert shadowing not in text, f"{source.name}: {shadowing}"
