"""Shared fixtures: the repository, the `matseg` command built from it (the
reference the package is compared with), and datasets that command wrote."""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="package")
def matseg_bin():
    """The matseg command: $MATSEG_BIN, else the workspace's debug or
    release build (`cargo test` and `cargo build` make them)."""
    candidates = [os.environ.get("MATSEG_BIN")] + [str(ROOT / "target" / p / "matseg") for p in ("debug", "release")]
    for c in candidates:
        if c and os.access(c, os.X_OK):
            return c
    pytest.fail("no matseg command: build it (cargo build -p matseg-cli) or set MATSEG_BIN")


def run(cmd, **kw):
    """Runs a command; on failure the test fails with its output."""
    done = subprocess.run([str(c) for c in cmd], check=False, capture_output=True, text=True, **kw)
    if done.returncode != 0:
        pytest.fail(f"{' '.join(map(str, cmd))} exited {done.returncode}:\n{done.stdout}\n{done.stderr}")
    return done


@pytest.fixture(scope="package")
def folders_2d(matseg_bin, tmp_path_factory):
    """6 samples of `matseg generate --seed 7` as MatSeg folders."""
    out = tmp_path_factory.mktemp("gen") / "folders"
    run([matseg_bin, "generate", "--out", out, "-n", 6, "--seed", 7, "--threads", 2])
    return out


@pytest.fixture(scope="package")
def shards_2d(matseg_bin, tmp_path_factory):
    """The same 6 samples as WebDataset shards of 4."""
    out = tmp_path_factory.mktemp("gen") / "shards"
    run([matseg_bin, "generate", "--out", out, "-n", 6, "--seed", 7, "--format", "wds", "--shard-size", 4,
         "--threads", 2])
    return out
