"""matseg.Model.track against `matseg track` on a frame folder, and its
errors."""

import numpy as np
import pytest
from conftest import ROOT, run
from PIL import Image

import matseg

TEXTURES = ROOT / "assets" / "textures"
FRAMES = 8


@pytest.fixture(scope="module")
def model():
    return matseg.Model.load("default")


@pytest.fixture(scope="module")
def frames():
    """A square of gravel sliding right across grass, 8 frames of 256x192."""
    grass = np.asarray(Image.open(TEXTURES / "grass.jpg").convert("RGB"))[:192, :256]
    gravel = np.asarray(Image.open(TEXTURES / "gravel.jpg").convert("RGB"))[100:180, 100:180]
    out = []
    for i in range(FRAMES):
        frame = grass.copy()
        frame[56:136, 30 + 16 * i:110 + 16 * i] = gravel
        out.append(frame)
    return out


def test_tracking_matches_matseg_track(model, frames, matseg_bin, tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, frame in enumerate(frames):
        Image.fromarray(frame).save(folder / f"{i:06}.png")
    out = tmp_path / "tracked"
    run([matseg_bin, "track", folder, "--point", "100,96", "--point", "200,20", "--frame", "2",
         "--preview", "--out", out])
    # A generator of frames, clicked on the third.
    tracked = list(model.track((f for f in frames), [(100, 96), (200, 20)], frame=2))
    assert len(tracked) == FRAMES
    for i, t in enumerate(tracked):
        assert t.labels.shape == (192, 256) and t.labels.dtype == np.uint8
        assert t.probability.shape == (2, 192, 256) and t.probability.dtype == np.float32
        cli = np.asarray(Image.open(out / "labels" / f"{i:06}.png"))
        assert (t.labels == cli).all(), f"frame {i}"
        for k in range(2):
            grey = np.asarray(Image.open(out / "similarity" / str(k) / f"{i:06}.png"))
            ours = np.round(np.clip(t.probability[k], 0, 1) * 255).astype(int)
            assert np.abs(ours - grey.astype(int)).max() <= 1, f"frame {i}, point {k}"
        assert t.areas == pytest.approx([(t.labels == k + 1).mean() for k in range(2)])
    # The gravel keeps its label as it moves: its centre on the last frame.
    last = tracked[-1].labels
    assert last[96, 70 + 16 * (FRAMES - 1)] == 1 and last[20, 10] == 2


def test_negative_clicks_are_followed_but_never_reported(model, frames, matseg_bin, tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, frame in enumerate(frames):
        Image.fromarray(frame).save(folder / f"{i:06}.png")
    out = tmp_path / "tracked"
    run([matseg_bin, "track", folder, "--point", "100,96", "--not", "200,20", "--preview",
         "--out", out])
    tracked = list(model.track(frames, [(100, 96)], negative=[(200, 20)]))
    for i, t in enumerate(tracked):
        assert t.probability.shape == (1, 192, 256) and len(t.areas) == 1
        assert set(np.unique(t.labels)) <= {0, 1}
        cli = np.asarray(Image.open(out / "labels" / f"{i:06}.png"))
        assert (t.labels == cli).all(), f"frame {i}"
    last = tracked[-1].labels
    assert last[96, 70 + 16 * (FRAMES - 1)] == 1 and last[20, 10] == 0


def test_bad_frames_and_settings_raise(model, frames):
    with pytest.raises(IndexError, match="past the end"):
        list(model.track(frames[:2], [(100, 96)], frame=5))
    with pytest.raises(ValueError, match="outside"):
        list(model.track(frames, [(100, 9999)]))
    with pytest.raises(ValueError, match="one size"):
        list(model.track([frames[0], frames[1][:100]], [(100, 96)]))
    with pytest.raises(ValueError, match="temperature"):
        list(model.track(frames, [(100, 96)], temperature=0))
    with pytest.raises(TypeError, match="dtype uint8"):
        list(model.track([frames[0].astype(np.float32)], [(100, 96)]))
