"""python -m matseg.train: DDP over two CPU processes under torchrun, and
runs resumed from their checkpoints, by this trainer and by matseg train."""

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT, run
from PIL import Image

from matseg import train

# Small online batches; a checkpoint and a validation on one held-out
# batch every 2 steps.
SMALL = ["--min-side", 64, "--max-side", 96, "--batch-pixels", 2 * 96 * 96, "--seed", 4, "--checkpoint-every", 2,
         "--validation-batches", 1]
TORCHRUN = os.path.join(os.path.dirname(sys.executable), "torchrun")


def python_train(*args, procs=1):
    """Runs python -m matseg.train (under torchrun when procs > 1); returns
    the weights' SHA-256 every rank printed."""
    launcher = [sys.executable] if procs == 1 else [TORCHRUN, "--nproc_per_node", procs]
    done = run(launcher + ["-m", "matseg.train", *args], env={**os.environ, "OMP_NUM_THREADS": str(2 // procs)})
    digests = set(re.findall(r"rank \d+: weights sha256 ([0-9a-f]{64})", done.stdout))
    assert len(digests) == 1, done.stdout
    return digests.pop()


def metrics(folder):
    return [json.loads(line) for line in (folder / "metrics.jsonl").read_text().splitlines()]


def extend(folder, steps):
    """Plans `steps` steps for the run in `folder`: as a run stopped after
    its last checkpoint, it then has steps left to resume (the learning
    rate has no decay, so the earlier steps' schedule is unchanged)."""
    path = folder / "run.json"
    config = json.loads(path.read_text())
    config["options"]["steps"] = steps
    path.write_text(json.dumps(config))


def test_two_process_ddp_training_keeps_ranks_identical_and_matseg_segment_loads_it(tmp_path, matseg_bin):
    out = tmp_path / "run"
    python_train("--out", out, "--steps", 2, "--workers", 0, *SMALL, procs=2)
    steps = metrics(out)
    assert [m["step"] for m in steps] == [0, 1]
    # Rank 0 trained on batches 0 and 2 of the stream (rank 1 on 1 and 3).
    assert [m["batch"] for m in steps] == [0, 2]
    # matseg train's per-step fields: the batch's size and the step's time.
    for m in steps:
        assert m["images"] >= 1 and m["width"] in (64, 96) and m["height"] in (64, 96)
        assert 0.0 <= m["data_seconds"] <= m["seconds"]
    # A validation at the checkpoint (the last step), and the loss curve.
    assert "validation" not in steps[0] and 0.0 < steps[1]["validation"] < 10.0
    assert Image.open(out / "loss.png").size == (640, 360)
    run_json = json.loads((out / "run.json").read_text())
    assert run_json["options"]["steps"] == 2 and run_json["init"] == "default"
    seg = tmp_path / "seg"
    run([matseg_bin, "segment", ROOT / "assets" / "photos" / "astronaut.jpg", "--model", out,
         "--point", "100,120", "--out", seg])
    grey = np.asarray(Image.open(seg / "similarity_0.png"))
    assert grey.shape == (512, 512) and grey[120, 100] > 200

    # Resumed on two processes with one DataLoader worker each, the run
    # continues with the next batches of the stream; matseg train, which
    # takes one batch a step, declines it.
    extend(out, 3)
    python_train("--resume", out, "--workers", 1, procs=2)
    assert [m["batch"] for m in metrics(out)] == [0, 2, 4]
    refused = subprocess.run([matseg_bin, "train", "--resume", out], check=False, capture_output=True, text=True)
    assert refused.returncode != 0
    assert "the next batch is 6, not the next step 3" in refused.stderr and len(refused.stderr.splitlines()) == 1


def test_a_run_resumed_from_its_checkpoint_ends_with_the_same_weights(tmp_path):
    straight, resumed = tmp_path / "straight", tmp_path / "resumed"
    expected = python_train("--out", straight, "--steps", 4, "--workers", 0, *SMALL)
    python_train("--out", resumed, "--steps", 2, "--workers", 0, *SMALL)
    extend(resumed, 4)
    assert python_train("--resume", resumed, "--workers", 1) == expected
    assert metrics(resumed) == [dict(m, seconds=r["seconds"], data_seconds=r["data_seconds"])
                                for m, r in zip(metrics(straight), metrics(resumed), strict=True)]
    assert (resumed / "model.safetensors").read_bytes() == (straight / "model.safetensors").read_bytes()


def test_each_trainer_resumes_the_others_runs(tmp_path, matseg_bin, folders_2d):
    # The same net, batches, optimizer state and learning rate: the step
    # after the checkpoint has the loss the other trainer's own run had.
    # The Rust runs mix stored samples into the online ones.
    rust = ["train", "--online", "--encoder-features", "--colour-features",
            "--init", ROOT / "models" / "default" / "model.safetensors", *SMALL]
    py_straight, py_then_rust = tmp_path / "py3", tmp_path / "py2"
    python_train("--out", py_straight, "--steps", 3, "--workers", 0, *SMALL)
    python_train("--out", py_then_rust, "--steps", 2, "--workers", 0, *SMALL)
    extend(py_then_rust, 3)
    run([matseg_bin, "train", "--resume", py_then_rust])
    assert metrics(py_then_rust)[2]["loss"] == pytest.approx(metrics(py_straight)[2]["loss"], rel=1e-5)

    rust_straight, rust_then_py = tmp_path / "rust3", tmp_path / "rust2"
    mixed = ["--mix-data", folders_2d, "--mix-fraction", 0.5]
    run([matseg_bin, *rust, *mixed, "--out", rust_straight, "--steps", 3])
    run([matseg_bin, *rust, *mixed, "--out", rust_then_py, "--steps", 2])
    extend(rust_then_py, 3)
    python_train("--resume", rust_then_py, "--workers", 0)
    assert [m["step"] for m in metrics(rust_then_py)] == [0, 1, 2]
    assert metrics(rust_then_py)[2]["loss"] == pytest.approx(metrics(rust_straight)[2]["loss"], rel=1e-5)
    # The held-out batch is matseg train's: the same loss on it after the
    # last step (weights one PyTorch step apart from the Rust run's).
    assert metrics(rust_then_py)[2]["validation"] == pytest.approx(metrics(rust_straight)[2]["validation"], rel=1e-4)


def test_checkpoints_scored_on_a_point_benchmark_keep_the_best(tmp_path, matseg_bin):
    bench, out = tmp_path / "bench", tmp_path / "run"
    run([matseg_bin, "bench-set", "make", "--out", bench, "-n", 3, "--seed", 2])
    python_train("--out", out, "--steps", 3, "--workers", 0, *SMALL, "--checkpoint-every", 1,
                 "--validation-batches", 0, "--val-points", bench, "--val-max-side", 128, "--lr", 1e-3)
    scores = [m["val_points"] for m in metrics(out)]
    assert len(scores) == 3 and all(0.0 <= v <= 1.0 for v in scores)
    # best.safetensors holds the best-scoring checkpoint: matseg eval gives
    # it that score.
    done = run([matseg_bin, "eval", "points", bench, "--model", out / "best.safetensors", "--max-side", 128, "--json"])
    assert json.loads(done.stdout)["models"][0]["all_by_material"] == pytest.approx(max(scores), abs=1e-12)


def test_run_folders_are_checked_before_training(tmp_path):
    (tmp_path / "run.json").write_text("{}")
    with pytest.raises(SystemExit, match="already holds a run; resume it"):
        train.main(["--out", str(tmp_path)])
    with pytest.raises(SystemExit, match="nowhere/run.json: no such file: not a run folder"):
        train.main(["--resume", str(tmp_path / "nowhere")])
    with pytest.raises(SystemExit):
        train.main(["--out", str(tmp_path / "a"), "--resume", str(tmp_path)])


def test_training_reads_stored_shards(tmp_path, shards_2d):
    out = tmp_path / "run"
    done = run([sys.executable, "-m", "matseg.train", "--out", out, "--data", shards_2d, "--steps", 1,
                "--min-side", 64, "--max-side", 64, "--batch-pixels", 2 * 64 * 64, "--workers", 0],
               env={**os.environ, "OMP_NUM_THREADS": "2"})
    assert "1 steps x 1 process(es), 2 images" in done.stdout
    run_json = json.loads((out / "run.json").read_text())
    assert run_json["data"] == str(shards_2d)
    assert (out / "model.safetensors").stat().st_size > 1_000_000


# Runs on a feature cache of 8 online scenes at 64 px, two images a step.
CACHED = ["--batch-pixels", 2 * 64 * 64, "--seed", 4, "--checkpoint-every", 2, "--validation-batches", 1]


@pytest.fixture(scope="module")
def feature_cache(matseg_bin, tmp_path_factory):
    """`matseg features` of 8 online scenes at 64 px through the shipped
    model's encoder, in shards of 4."""
    out = tmp_path_factory.mktemp("features") / "cache"
    run([matseg_bin, "features", "--online", "-n", 8, "--side", 64, "--shard-size", 4, "--zoom", "native",
         "--out", out])
    return out


def test_a_run_on_a_feature_cache_resumes_exactly_and_matches_matseg_train(tmp_path, matseg_bin, feature_cache):
    straight, resumed = tmp_path / "straight", tmp_path / "resumed"
    python_train("--out", straight, "--features", feature_cache, "--steps", 4, "--workers", 0, *CACHED)
    config = json.loads((straight / "run.json").read_text())
    assert config["init"] == "default" and config["features"]["manifest"]["samples"] == 8
    assert config["options"]["lr_scales"][-1] == {"prefix": "encoder.", "scale": 0.0}
    steps = metrics(straight)
    assert [(m["images"], m["width"], m["height"]) for m in steps] == [(2, 64, 64)] * 4
    assert all(m["loss"] is not None for m in steps)

    python_train("--out", resumed, "--features", feature_cache, "--steps", 2, "--workers", 0, *CACHED)
    extend(resumed, 4)
    python_train("--resume", resumed, "--workers", 1)
    assert (resumed / "model.safetensors").read_bytes() == (straight / "model.safetensors").read_bytes()

    # matseg train on the same cache takes the same steps, and resumes this
    # trainer's run with the loss the run itself had.
    rust = tmp_path / "rust"
    run([matseg_bin, "train", "--features", feature_cache, "--encoder-features", "--colour-features",
         "--lr-scale", "encoder.=0.1", "--lr-scale", "colour.=100", "--lr", 1e-5, "--warmup", 100, "--steps", 4,
         *CACHED, "--out", rust])
    for r, p in zip(metrics(rust), steps, strict=False):
        assert r["loss"] == pytest.approx(p["loss"], rel=1e-4), (r, p)
    py_then_rust = tmp_path / "py2"
    python_train("--out", py_then_rust, "--features", feature_cache, "--steps", 2, "--workers", 0, *CACHED)
    extend(py_then_rust, 3)
    run([matseg_bin, "train", "--resume", py_then_rust])
    assert metrics(py_then_rust)[2]["loss"] == pytest.approx(steps[2]["loss"], rel=1e-5)


def test_a_cache_of_another_encoder_is_refused(tmp_path, feature_cache):
    done = subprocess.run([sys.executable, "-m", "matseg.train", "--out", tmp_path / "run", "--features",
                           feature_cache, "--init", "scratch", "--steps", "1"], check=False,
                          capture_output=True, text=True)
    assert done.returncode != 0
    assert "made by the encoder of default, whose weights differ from those of scratch" in done.stderr


def test_a_feature_cache_reads_as_arrays_and_bad_folders_are_named(tmp_path, feature_cache):
    import matseg
    from matseg.torch import FeatureStream

    cache = matseg.FeatureCache(feature_cache)
    assert len(cache) == 8 and cache.manifest["taps"] == [24, 32, 96, 1280]
    plan = matseg.BatchPlan(64, 64, 3 * 64 * 64, 2, 7, 0.5)
    b = cache.batch(5, plan, seed=1)
    assert [t.shape for t in b["taps"]] == [(3, 24, 16, 16), (3, 32, 8, 8), (3, 96, 4, 4), (3, 1280, 2, 2)]
    assert b["lab"].shape == (3, 3, 16, 16) and b["roi"].shape == (3, 16, 16)
    assert b["weights"].shape[:2][0] == 3 and b["weights"].dtype == np.float32
    # Cell targets: material shares sum to at most 1, and nearly 1 in cells
    # wholly inside the ROI (less only where fitting blurred an ROI edge).
    sums = b["weights"].sum(1)
    assert sums.max() <= 1.0 + 1e-3 and sums[b["roi"] > 0.99].min() > 0.85
    stream = FeatureStream(cache, plan, seed=1, steps=2, first_step=5)
    assert np.array_equal(next(iter(stream))["lab"].numpy(), b["lab"])
    with pytest.raises(FileNotFoundError):
        matseg.FeatureCache(tmp_path / "missing")
    with pytest.raises(matseg.MatsegError, match="not a feature cache"):
        matseg.FeatureCache(tmp_path)
