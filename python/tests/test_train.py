"""python -m matseg.train under torchrun: DDP over two CPU processes."""

import json
import os
import re
import sys

import numpy as np
from PIL import Image

from conftest import ROOT, run


def test_two_process_ddp_training_keeps_ranks_identical_and_matseg_segment_loads_it(tmp_path, matseg_bin):
    out = tmp_path / "run"
    torchrun = os.path.join(os.path.dirname(sys.executable), "torchrun")
    done = run([torchrun, "--nproc_per_node", 2, "-m", "matseg.train", "--out", out, "--steps", 2,
                "--min-side", 64, "--max-side", 96, "--batch-pixels", 2 * 96 * 96, "--workers", 0, "--seed", 4],
               env={**os.environ, "OMP_NUM_THREADS": "1"})
    digests = dict(re.findall(r"rank (\d+): weights sha256 ([0-9a-f]{64})", done.stdout))
    assert set(digests) == {"0", "1"}
    assert digests["0"] == digests["1"]
    metrics = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    assert [m["step"] for m in metrics] == [0, 1]
    # Rank 0 trained on batches 0 and 2 of the stream (rank 1 on 1 and 3).
    assert [m["batch"] for m in metrics] == [0, 2]
    # matseg train's per-step fields: the batch's size and the step's time.
    for m in metrics:
        assert m["images"] >= 1 and m["width"] in (64, 96) and m["height"] in (64, 96)
        assert 0.0 <= m["data_seconds"] <= m["seconds"]
    run_json = json.loads((out / "run.json").read_text())
    assert run_json["options"]["steps"] == 2 and run_json["init"] == "default"
    seg = tmp_path / "seg"
    run([matseg_bin, "segment", ROOT / "assets" / "photos" / "astronaut.jpg", "--model", out,
         "--point", "100,120", "--out", seg])
    grey = np.asarray(Image.open(seg / "similarity_0.png"))
    assert grey.shape == (512, 512) and grey[120, 100] > 200


def test_training_reads_stored_shards(tmp_path, shards_2d):
    out = tmp_path / "run"
    done = run([sys.executable, "-m", "matseg.train", "--out", out, "--data", shards_2d, "--steps", 1,
                "--min-side", 64, "--max-side", 64, "--batch-pixels", 2 * 64 * 64, "--workers", 0],
               env={**os.environ, "OMP_NUM_THREADS": "2"})
    assert "1 steps x 1 process(es), 2 images" in done.stdout
    run_json = json.loads((out / "run.json").read_text())
    assert run_json["data"] == str(shards_2d)
    assert (out / "model.safetensors").stat().st_size > 1_000_000
