"""matseg.Model against `matseg segment`, and its errors."""

import numpy as np
import pytest
from conftest import ROOT, run
from PIL import Image

import matseg

PHOTO = ROOT / "assets" / "photos" / "astronaut.jpg"


@pytest.fixture(scope="module")
def model():
    return matseg.Model.load("default")


@pytest.fixture(scope="module")
def photo():
    return matseg.read_image(PHOTO)


def test_similarity_and_segmentation_match_matseg_segment(model, photo, matseg_bin, tmp_path):
    points = [(100.0, 120.0), (400.0, 60.0)]
    run([matseg_bin, "segment", PHOTO, "--point", "100,120", "--point", "400,60", "--out", tmp_path])
    maps = model.similarity(photo, points)
    assert maps.shape == (2, *photo.shape[:2]) and maps.dtype == np.float32
    for k in range(2):
        grey = np.asarray(Image.open(tmp_path / f"similarity_{k}.png"))
        ours = np.round(np.clip(maps[k], 0, 1) * 255).astype(np.uint8)
        assert np.abs(ours.astype(int) - grey.astype(int)).max() <= 1
    labels = model.segment(photo, points=points)
    cli = np.asarray(Image.open(tmp_path / "labels.png"))
    assert labels.dtype == np.int32 and labels.shape == photo.shape[:2]
    assert (labels == cli).mean() > 0.999
    # The point's own pixel is most similar to itself.
    assert maps[0][120, 100] > 0.9 and labels[120, 100] == 0 and labels[60, 400] == 1


def test_selection_matches_matseg_segment_and_applies_as_saved(model, photo, matseg_bin, tmp_path):
    out, applied = tmp_path / "segment", tmp_path / "apply"
    run([matseg_bin, "segment", PHOTO, "--point", "1:100,120", "--point", "1:120,300",
         "--not", "400,60", "--out", out])
    selection = model.select(photo, [(100, 120), (120, 300)], negative=[(400, 60)])
    assert selection.mask.shape == photo.shape[:2] and selection.mask.dtype == bool
    cli = np.asarray(Image.open(out / "mask_0.png")) > 127
    assert (selection.mask == cli).mean() > 0.999
    assert selection.mask[120, 100] and not selection.mask[60, 400]
    # The saved selection, applied to the same photo, keeps the clicks'
    # descriptors, not where they were clicked: a later click, which on its
    # photo reached only the cells near it and very like it, reaches by its
    # descriptor alone. The applied mask holds the clicked one, and may
    # reach further.
    saved = tmp_path / "selection.json"
    saved.write_text(selection.saved)
    run([matseg_bin, "apply", saved, PHOTO, "--out", applied])
    again = np.asarray(Image.open(applied / "masks" / "astronaut.png")) > 127
    assert (again & selection.mask).sum() > 0.98 * selection.mask.sum()
    assert (again == selection.mask).mean() > 0.85
    # One click saved and applied: exactly the same mask.
    one = model.select(photo, [(100, 120)])
    saved.write_text(one.saved)
    run([matseg_bin, "apply", saved, PHOTO, "--out", applied])
    again = np.asarray(Image.open(applied / "masks" / "astronaut.png")) > 127
    assert (again == one.mask).all()
    # One positive click alone: its similarity map, as it is.
    alone = model.select(photo, [(100, 120)])
    assert np.array_equal(alone.soft, model.similarity(photo, [(100, 120)])[0])
    with pytest.raises(ValueError, match="positive"):
        model.select(photo, [])
    with pytest.raises(ValueError, match="^not 9999"):
        model.select(photo, [(100, 120)], negative=[(9999, 1)])


def test_descriptors_are_unit_vectors(model, photo):
    small = photo[:96, :128]
    d = model.describe(small)
    assert d.shape == (model.dim, 96, 128)
    assert np.allclose(np.linalg.norm(d, axis=0), 1, atol=1e-4)


def test_clustering_splits_into_k_labels(model, photo):
    labels = model.segment(photo, k=3, seed=1)
    assert set(np.unique(labels)) == {0, 1, 2}


def test_bad_images_and_points_raise(model, photo):
    with pytest.raises(TypeError, match="dtype uint8"):
        model.describe(photo.astype(np.float32))
    with pytest.raises(ValueError, match="HxWx3"):
        model.describe(photo[:, :, 0])
    with pytest.raises(TypeError, match="numpy array"):
        model.describe([[1, 2, 3]])
    with pytest.raises(ValueError, match="outside the image"):
        model.similarity(photo, [(10, 9999)])
    with pytest.raises(ValueError, match="two points"):
        model.segment(photo, points=[(1, 1)])
    with pytest.raises(ValueError, match="either points or k"):
        model.segment(photo)
    with pytest.raises(ValueError, match="multiples of 32"):
        model.describe_at_own_size(photo[:100, :100])
    with pytest.raises(FileNotFoundError):
        matseg.Model.load("/nonexistent/run")
    with pytest.raises(FileNotFoundError, match="no such file"):
        matseg.read_image("/nonexistent.jpg")


def test_arrays_cross_as_buffers_with_no_copy(model, photo):
    # A photo and the model's answers are numpy views of the native
    # module's buffers: writable, and kept alive by the array.
    from matseg import _core

    def owner(array):
        while isinstance(array, np.ndarray) and array.base is not None:
            array = array.base
        return array.obj if isinstance(array, memoryview) else array

    assert photo.flags.writeable and photo.flags.c_contiguous
    assert isinstance(owner(photo), _core.Buffer) and len(owner(photo)) == photo.nbytes
    maps = model.similarity(photo[:64, :96], [(10.0, 10.0)])
    assert maps.flags.writeable
    assert isinstance(owner(maps), _core.Buffer) and len(owner(maps)) == maps.nbytes
    maps[0, 0, 0] = 2.0
    assert maps[0, 0, 0] == 2.0
    # A non-contiguous view is made contiguous before it crosses; the
    # native module reads the size from the array and refuses other shapes.
    flipped = photo[::-1]
    assert np.array_equal(model.describe(flipped[:64, :96]), model.describe(np.ascontiguousarray(flipped[:64, :96])))
    for bad in (photo[:64, :96, :2].copy(), photo[:64, :96, 0].copy(), photo[:0, :96].copy()):
        with pytest.raises(ValueError, match=r"^image: "):
            model._native.describe(bad)
    with pytest.raises(ValueError, match="not C-contiguous"):
        model._native.describe(photo[:64, :96])
