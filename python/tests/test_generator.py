"""matseg.Generator and matseg.Dataset against what `matseg generate` writes."""

import pickle

import numpy as np
import pytest
from conftest import run

import matseg


def folder_files(folder):
    return {p.name: p.read_bytes() for p in folder.iterdir() if p.name != "Finished.txt"}


def test_generated_files_are_byte_identical_to_matseg_generate(folders_2d):
    gen = matseg.Generator("2d", seed=7, samples=6)
    for i in range(6):
        assert gen.files(i) == folder_files(folders_2d / f"{i:08}")


def test_samples_are_the_stored_samples_as_arrays(folders_2d, shards_2d):
    gen = matseg.Generator("2d", seed=7, samples=6)
    folders, shards = matseg.Dataset(folders_2d), matseg.Dataset(shards_2d)
    assert len(gen) == len(folders) == len(shards) == 6
    for i in (0, 3, 5):
        s = gen[i]
        for stored in (folders[i], shards[i]):
            assert np.array_equal(s["image"], stored["image"])
            assert np.array_equal(s["masks"], stored["masks"])
            assert stored["meta"] == s["meta"]
        h, w = s["image"].shape[:2]
        assert s["image"].dtype == np.uint8 and s["image"].shape == (h, w, 3)
        assert s["masks"].dtype == np.float32 and s["masks"].shape[1:] == (h, w)
        assert s["roi"].shape == (h, w)
        # Each pixel's mask fractions sum to its ROI value (8-bit rounding aside).
        assert np.abs(s["masks"].sum(0) - s["roi"]).max() <= 0.5 * len(s["masks"]) / 255 + 1e-6
        assert s["meta"]["index"] == i and s["meta"]["seed"] == 7 and s["meta"]["kind"] == "2d"
    assert folders.key(2) == "00000002" and folders[-1]["key"] == "00000005"


def test_a_3d_sample_matches_matseg_generate(matseg_bin, tmp_path):
    out = tmp_path / "d3"
    run([matseg_bin, "generate", "--kind", "3d", "--out", out, "-n", 2, "--seed", 4, "--size", 48, "--spp", 2])
    gen = matseg.Generator("3d", seed=4, samples=2, size=48, spp=2)
    assert gen.files(1) == folder_files(out / "00000001")
    assert gen[1]["image"].shape == (48, 48, 3)


def test_a_generator_pickles_for_dataloader_workers():
    gen = matseg.Generator("2d", seed=2, samples=4)
    copy = pickle.loads(pickle.dumps(gen))
    assert len(copy) == 4 and copy.seed == 2
    assert np.array_equal(copy[3]["image"], gen[3]["image"])
    ds_copy = pickle.loads(pickle.dumps(matseg.Generator("2d", seed=2)))
    with pytest.raises(TypeError, match="unbounded"):
        len(ds_copy)


def test_write_splits_into_jobs_like_matseg_generate(folders_2d, tmp_path):
    gen = matseg.Generator("2d", seed=7, samples=6)
    reports = [gen.write(tmp_path, num_shards=3, shard_index=i) for i in range(3)]
    assert [r["generated"] for r in reports] == [2, 2, 2]
    for i in range(6):
        assert folder_files(tmp_path / f"{i:08}") == folder_files(folders_2d / f"{i:08}")
    again = gen.write(tmp_path)
    assert again["generated"] == 0 and again["skipped"] == 6


def test_bad_input_raises_clear_python_errors(tmp_path):
    with pytest.raises(ValueError, match="kind: '4d'"):
        matseg.Generator("4d")
    with pytest.raises(FileNotFoundError, match="nowhere"):
        matseg.Generator("2d", sources=tmp_path / "nowhere")
    with pytest.raises(FileNotFoundError, match="nowhere"):
        matseg.Dataset(tmp_path / "nowhere")
    with pytest.raises(matseg.MatsegError, match="no complete samples"):
        matseg.Dataset(tmp_path)
    bad = tmp_path / "bad.toml"
    bad.write_text("[scene]\nsize_min = 'big'\n")
    with pytest.raises(matseg.MatsegError, match="bad.toml"):
        matseg.Generator("2d", recipe=bad)
    gen = matseg.Generator("2d", samples=3)
    with pytest.raises(IndexError, match="sample 3 is out of range"):
        gen[3]
    with pytest.raises(TypeError, match="integers"):
        gen["0"]  # type: ignore[index]
    with pytest.raises(ValueError, match="licence"):
        matseg.Generator("2d", licences="not-a-licence")
    with pytest.raises(ValueError, match="3d scenes"):
        matseg.Generator("3d", size=32, spp=1).batch(0)


def test_missing_bundled_assets_are_named(tmp_path, monkeypatch):
    monkeypatch.setenv("MATSEG_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("MATSEG_ASSETS", str(tmp_path / "assets"))
    with pytest.raises(matseg.MatsegError, match=r"assets/photos: no such folder, .* MATSEG_ASSETS"):
        matseg.Generator("2d")
