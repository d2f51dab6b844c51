"""python -m matseg.ray generate on a local two-CPU Ray cluster."""

import filecmp
import os
import sys

from conftest import run


def same_tree(a, b):
    cmp = filecmp.dircmp(a, b)
    if cmp.left_only or cmp.right_only or cmp.funny_files:
        return False
    _, mismatch, errors = filecmp.cmpfiles(a, b, cmp.common_files, shallow=False)
    same_dirs = all(same_tree(os.path.join(a, d), os.path.join(b, d)) for d in cmp.common_dirs)
    return not mismatch and not errors and same_dirs


def test_ray_tasks_write_what_one_matseg_generate_writes_and_resume(tmp_path, matseg_bin):
    one, ray_out = tmp_path / "one", tmp_path / "ray"
    run([matseg_bin, "generate", "--out", one, "-n", 9, "--seed", 5, "--format", "wds", "--shard-size", 2])
    cmd = [sys.executable, "-m", "matseg.ray", "generate", "--out", ray_out, "-n", 9, "--seed", 5,
           "--format", "wds", "--shard-size", 2, "--num-shards", 3, "--address", "local", "--num-cpus", 2]
    first = run(cmd)
    assert "9 samples generated" in first.stdout
    assert same_tree(one, ray_out)
    os.remove(ray_out / "shard-000002.tar")
    second = run(cmd)
    assert "2 samples generated, 7 already complete" in second.stdout
    assert same_tree(one, ray_out)
