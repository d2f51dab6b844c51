"""The package built without libtorch (scripts/test-python-without-torch.sh
installs it where there is no torch): what needs PyTorch says what to
install; everything else works (test_model.py, test_track.py,
test_evaluate.py and test_generator.py run there too)."""

import importlib.util

import numpy as np
import pytest
from conftest import ROOT

import matseg
from matseg import _core

pytestmark = pytest.mark.skipif(_core.WITH_TORCH, reason="the package built without libtorch")


def test_torch_is_not_installed_and_not_needed():
    assert importlib.util.find_spec("torch") is None
    photo = matseg.read_image(ROOT / "assets" / "photos" / "coffee.jpg")[:96, :128]
    d = matseg.Model.load("default").describe(photo)
    assert d.shape[1:] == photo.shape[:2] and d.dtype == np.float32
    assert np.allclose(np.linalg.norm(d, axis=0), 1.0, atol=1e-4)


@pytest.mark.parametrize("module", ["matseg.torch", "matseg.net", "matseg.train", "matseg.export"])
def test_what_needs_pytorch_says_what_to_install(module):
    missing = r"needs PyTorch, which is not installed: pip install torch==2\.11\.0"
    with pytest.raises(ModuleNotFoundError, match=missing):
        importlib.import_module(module)


def test_a_feature_cache_needs_the_build_with_libtorch(tmp_path):
    with pytest.raises(ImportError, match=r"matseg\.FeatureCache needs matseg built with libtorch.*--features torch"):
        matseg.FeatureCache(tmp_path)
