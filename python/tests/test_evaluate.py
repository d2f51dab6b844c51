"""matseg.evaluate: models written in Python, and maps written as files,
scored by matseg's protocols exactly as `matseg eval` scores its own."""

import importlib.util
import json

import numpy as np
import pytest
from conftest import ROOT, run

import matseg
import matseg.evaluate

REAL_DEV = ROOT / "benchmarks" / "real-dev"
REAL_MASKS = ROOT / "benchmarks" / "real-masks"
F32 = np.float32


def rgb(image):
    """The built-in rgb baseline in numpy: R, G, B / 255."""
    return image.astype(F32) / F32(255)


def lab(image):
    """The built-in lab baseline in numpy float32, operation by operation
    as matseg_image::lab computes it (so every value is the same bit for
    bit): sRGB levels to linear light, to XYZ over the D65 white, to L*a*b*."""
    c = np.arange(256, dtype=F32) / F32(255)
    with np.errstate(invalid="ignore"):
        curve = np.power((c + F32(0.055)) / F32(1.055), F32(2.4))
    table = np.where(c <= F32(0.04045), c / F32(12.92), curve).astype(F32)
    r, g, b = (table[image[..., k]] for k in range(3))
    m = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]], dtype=F32)
    x = (m[0, 0] * r + m[0, 1] * g + m[0, 2] * b) / F32(0.95047)
    y = m[1, 0] * r + m[1, 1] * g + m[1, 2] * b
    z = (m[2, 0] * r + m[2, 1] * g + m[2, 2] * b) / F32(1.08883)
    epsilon, kappa = F32(216.0) / F32(24389.0), F32(24389.0) / F32(27.0)

    def f(t):
        return np.where(t > epsilon, np.cbrt(t), (kappa * t + F32(16.0)) / F32(116.0)).astype(F32)

    fx, fy, fz = f(x), f(y), f(z)
    return np.stack([F32(116.0) * fy - F32(16.0), F32(500.0) * (fx - fy), F32(200.0) * (fy - fz)], axis=-1)


class Colour:
    """A colour baseline as a model object, compared by distance."""

    comparison = "euclidean"

    def __init__(self, name, describe):
        self.name = name
        self.describe = describe


def cli(matseg_bin, *args):
    return json.loads(run([matseg_bin, "eval", *args, "--json"]).stdout)


def close(ours, theirs, fields):
    for field in fields:
        assert ours[field] == pytest.approx(theirs[field], abs=1e-6), field


POINT_FIELDS = ["all_by_material", "all_by_point", "soft_by_material", "soft_by_point", "top1_by_material",
                "top1_by_point"]


def test_numpy_colour_baselines_score_what_the_built_in_ones_score(matseg_bin):
    builtin = cli(matseg_bin, "points", REAL_DEV, "--baseline", "rgb", "lab", "--model", "none")["models"]
    for ours, describe in zip(builtin, (rgb, lab), strict=True):
        theirs = matseg.evaluate.points(REAL_DEV, Colour(ours["model"], describe), progress=False)
        model = theirs["models"][0]
        assert model["model"] == ours["model"]
        assert model["counts"] == ours["counts"]
        close(model, ours, POINT_FIELDS)
        for a, b in zip(model["images"], ours["images"], strict=True):
            close(a, b, POINT_FIELDS[:2])
    builtin = cli(matseg_bin, "masks", REAL_MASKS, "--baseline", "rgb", "--model", "none")["models"][0]
    theirs = matseg.evaluate.masks(REAL_MASKS, Colour("rgb", rgb), progress=False)["models"][0]
    assert (theirs["queries"], theirs["masks"]) == (builtin["queries"], builtin["masks"])
    close(theirs, builtin, ["mean_iou"])


def test_numpy_baselines_score_what_the_built_in_ones_score_on_generated_benchmarks(matseg_bin, tmp_path):
    """A generated point benchmark (with mixtures, so Soft is scored) and
    the mask benchmark `bench-set masks` makes from generated scenes."""
    points = tmp_path / "points"
    run([matseg_bin, "bench-set", "make", "--out", points, "-n", 6, "--seed", 3])
    builtin = cli(matseg_bin, "points", points, "--baseline", "rgb", "lab", "--model", "none")["models"]
    for ours, describe in zip(builtin, (rgb, lab), strict=True):
        theirs = matseg.evaluate.points(points, Colour(ours["model"], describe), progress=False)["models"][0]
        close(theirs, ours, POINT_FIELDS)
    masks = tmp_path / "masks"
    run([matseg_bin, "bench-set", "masks", "--out", masks, "-n", 4, "--seed", 5])
    builtin = cli(matseg_bin, "masks", masks, "--baseline", "rgb", "--model", "none")["models"][0]
    theirs = matseg.evaluate.masks(masks, Colour("rgb", rgb), progress=False)["models"][0]
    assert (theirs["queries"], theirs["masks"]) == (builtin["queries"], builtin["masks"]) and builtin["queries"] > 0
    close(theirs, builtin, ["mean_iou"])


def test_maps_as_files_score_what_the_built_in_baseline_scores(matseg_bin, tmp_path):
    """The rgb baseline written as .npy files for `--maps`, at the photos'
    own size (--max-side 0), from the photos `maps-template` lists."""
    template = tmp_path / "template"
    run([matseg_bin, "eval", "maps-template", REAL_DEV, "--out", template, "--max-side", 0])
    listed = json.loads((template / "template.json").read_text())
    assert listed["protocol"] == "points" and len(listed["images"]) == 44
    maps = tmp_path / "rgb-maps"
    maps.mkdir()
    for image in listed["images"]:
        photo = matseg.read_image(template / "photos" / f"{image['name']}.png")
        assert photo.shape == (image["height"], image["width"], 3)
        np.save(maps / f"{image['name']}.npy", rgb(photo))
    (maps / "maps.json").write_text('{"comparison": "euclidean"}')
    both = cli(matseg_bin, "points", REAL_DEV, "--baseline", "rgb", "--model", "none", "--maps", maps,
               "--max-side", 0)["models"]
    assert [m["model"] for m in both] == ["rgb", "rgb-maps"]
    close(both[1], both[0], POINT_FIELDS)


def six_real_dev_photos(folder):
    """The first six photos of real-dev, with their points, in `folder`
    (nets are slow in a test build)."""
    for name in sorted(p.name for p in (REAL_DEV / "data").iterdir())[:6]:
        (folder / "data" / name).mkdir(parents=True)
        for file in (REAL_DEV / "data" / name).iterdir():
            (folder / "data" / name / file.name).write_bytes(file.read_bytes())
        (folder / "images").mkdir(exist_ok=True)
        photo = REAL_DEV / "images" / f"{name}.jpg"
        (folder / "images" / photo.name).write_bytes(photo.read_bytes())


def test_the_shipped_model_scores_what_matseg_eval_scores(matseg_bin, tmp_path):
    six_real_dev_photos(tmp_path)
    model = matseg.Model.load("default")
    ours = cli(matseg_bin, "points", tmp_path, "--model", "default")["models"][0]
    theirs = matseg.evaluate.points(tmp_path, model, progress=False)["models"][0]
    assert theirs["model"] == "default" and theirs["counts"]["images"] == 6
    for field in POINT_FIELDS:
        assert theirs[field] == ours[field], field


def test_similarity_models_are_scored_on_their_maps():
    """A model answering with similarity maps: minus the rgb distance to
    each point scores as the rgb descriptors do (at a point's own pixel)."""
    theirs = matseg.evaluate.masks(REAL_MASKS, Nearness(), radius=0.0, progress=False)["models"][0]
    ours = matseg.evaluate.masks(REAL_MASKS, Colour("rgb", rgb), radius=0.0, progress=False)["models"][0]
    assert theirs["model"] == "Nearness"
    # numpy sums the squared differences in float32, matseg in float64.
    assert theirs["mean_iou"] == pytest.approx(ours["mean_iou"], abs=1e-4)


def first_photo_fails(answer):
    calls = []

    def describe(image):
        calls.append(image.shape)
        return answer(image)

    with pytest.raises(matseg.MatsegError) as raised:
        matseg.evaluate.points(REAL_DEV, describe, progress=False)
    assert len(calls) == 1, "the first photo stops it"
    return raised.value


def test_wrong_answers_are_errors_naming_the_photo():
    message = str(first_photo_fails(lambda image: rgb(image)[..., 0]))
    assert "balance" in message and "shape [" in message and "expected (h, w, d) descriptors" in message, message
    message = str(first_photo_fails(lambda image: np.full(image.shape, np.nan, F32)))
    assert "value NaN at index 0 for photo balance" in message, message
    message = str(first_photo_fails(lambda image: None))
    assert "photo balance: the model raised TypeError: describe returned NoneType" in message, message

    def raises(image):
        raise ValueError("out of memory")

    error = first_photo_fails(raises)
    assert "photo balance: the model raised ValueError: out of memory" in str(error)
    assert isinstance(error.__cause__, ValueError)

    def interrupted(image):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        matseg.evaluate.points(REAL_DEV, interrupted, progress=False)
    with pytest.raises(TypeError, match="has none of describe"):
        matseg.evaluate.points(REAL_DEV, object())


def two_mask_photos(folder):
    """The first two photos of real-masks, with their masks, in `folder`."""
    photos = sorted(p.stem for p in REAL_MASKS.glob("*.jpg"))[:2]
    for photo in photos:
        for file in REAL_MASKS.glob(f"{photo}.*"):
            (folder / file.name).write_bytes(file.read_bytes())
    return photos


class Nearness:
    """Similarity maps: minus the rgb distance to each point's colour."""

    def __init__(self):
        self.asked = []

    def similarity(self, image, points):
        self.asked.append(points.shape)
        colours = rgb(image)
        picked = colours[points[:, 1].astype(int), points[:, 0].astype(int)]
        return -np.linalg.norm(colours[None] - picked[:, None, None], axis=-1)


def test_similarity_and_selecting_models_are_scored_by_clicks(tmp_path):
    two_mask_photos(tmp_path)
    nearness = Nearness()
    report = matseg.evaluate.clicks(tmp_path, nearness, max_clicks=5, max_side=200, progress=False)
    model = report["models"][0]
    assert model["masks"] > 0 and len(model["miou_curve"]) == 5
    assert set(nearness.asked) == {(1, 2)}, "one map asked for at each click"
    assert len(nearness.asked) >= model["masks"]

    class Everything:
        """Selects the whole photo whatever the clicks, and records them."""

        def __init__(self):
            self.clicks = []

        def select(self, image, positives, negatives):
            assert image.dtype == np.uint8 and image.shape[2] == 3 and max(image.shape) == 200
            assert positives.dtype == np.float32 and positives.shape[1] == 2 and negatives.shape[1] == 2
            self.clicks.append((len(positives), len(negatives)))
            return np.ones(image.shape[:2], dtype=bool)

    everything = Everything()
    model = matseg.evaluate.clicks(tmp_path, everything, max_clicks=5, max_side=200, progress=False)["models"][0]
    assert model["model"] == "Everything" and model["masks"] > 0
    # The whole photo never gets better: the IoU stays the first click's,
    # and each later click is the negative one on the largest spill.
    assert model["miou_curve"] == [model["miou_at"]["1"]] * 5 and model["drops"]["lowering"] == 0
    assert everything.clicks[:5] == [(1, 0), (1, 1), (1, 2), (1, 3), (1, 4)]
    with pytest.raises(matseg.MatsegError, match="only selects from clicks"):
        matseg.evaluate.masks(tmp_path, everything, progress=False)

    class Flat(Everything):
        def select(self, image, positives, negatives):
            return np.ones(image.shape[:2][::-1], dtype=np.float32)

    wrong = r"shape \[188, 200\] for photo balance: select must return its \(200, 188\) selection"
    with pytest.raises(matseg.MatsegError, match=wrong):
        matseg.evaluate.clicks(tmp_path, Flat(), max_clicks=5, max_side=200, progress=False)


def test_progress_names_each_photo(capfd, tmp_path):
    photos = two_mask_photos(tmp_path)
    report = matseg.evaluate.clicks(tmp_path, Colour("rgb", rgb), max_clicks=5, max_side=200)
    assert report["models"][0]["masks"] > 0
    lines = capfd.readouterr().err.splitlines()
    assert lines == [f"matseg.evaluate.clicks rgb: photo {k + 1} {p}" for k, p in enumerate(photos)]


@pytest.fixture(scope="module")
def sequence(matseg_bin, tmp_path_factory):
    """One generated sequence of 4 frames of a 128 px scene of two materials."""
    folder = tmp_path_factory.mktemp("track")
    recipe = folder / "recipe.toml"
    recipe.write_text("p_single_object = 1.0\np_many_materials = 0.0\ndistinct_materials = true\n"
                      "p_transmissive = 0.0\np_metal = 0.0\np_ground = 0.0\np_distractors = 0.0\n"
                      "map_scale_log10 = [-0.3, 0.2]\n")
    run([matseg_bin, "generate", "--kind", "3d", "--frames", 4, "-n", 1, "--seed", 6, "--size", 128, "--spp", 4,
         "--config", recipe, "--threads", 2, "--out", folder / "seq"])
    return folder / "seq"


def test_tracking_scores_what_matseg_eval_track_scores(matseg_bin, sequence, capfd):
    ours = json.loads(run([matseg_bin, "eval", "track", sequence, "--json"]).stdout)
    theirs = matseg.evaluate.track(sequence, matseg.Model.load("default"), progress=False)
    assert theirs == {**ours, "benchmark": str(sequence)} and theirs["model"] == "default"
    assert theirs["frames"] == 4 and theirs["queries"] >= 1

    class Colours:
        """Unit rgb descriptors at a stride of 4, recording the frames."""

        def __init__(self):
            self.frames = []

        def describe(self, image):
            self.frames.append(image.shape)
            return rgb(image)[2::4, 2::4] + F32(0.1)

    colours = Colours()
    report = matseg.evaluate.track(sequence, colours, side=64)
    assert colours.frames == [(64, 64, 3)] * 4, "one call a frame, at the side asked"
    assert report["model"] == "Colours" and report["side"] == 64
    assert [q["point"] for q in report["per_query"]] == [q["point"] for q in ours["per_query"]]
    for scores in (report["with_memory"], report["first_frame_only"]):
        assert 0.0 < scores["mean_iou"] <= 1.0
    lines = capfd.readouterr().err.splitlines()
    assert lines == [f"matseg.evaluate.track Colours: photo {f + 1} sequence 0 frame {f}" for f in range(4)]

    with pytest.raises(matseg.MatsegError, match="track needs describe"):
        matseg.evaluate.track(sequence, Colour("rgb", rgb), progress=False)
    with pytest.raises(matseg.MatsegError, match="value NaN at index 0 for photo sequence 0 frame 0"):
        matseg.evaluate.track(sequence, lambda image: np.full(image.shape, np.nan, F32), progress=False)


def test_the_worked_example_scores_near_the_built_in_imagenet_baseline(matseg_bin, tmp_path):
    """examples/imagenet_features.py (torchvision's ImageNet MobileNetV2 in
    plain PyTorch, joined on a stride-4 grid) against the built-in
    `imagenet` baseline (the same blocks, joined at the photo's size), on
    six real-dev photos."""
    pytest.importorskip("torch", reason="the worked example is written in PyTorch")
    spec = importlib.util.spec_from_file_location("imagenet_features", ROOT / "examples" / "imagenet_features.py")
    assert spec is not None and spec.loader is not None
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    six_real_dev_photos(tmp_path)
    ours = cli(matseg_bin, "points", tmp_path, "--baseline", "imagenet", "--model", "none")["models"][0]
    model = example.model()
    theirs = matseg.evaluate.points(tmp_path, model, progress=False)["models"][0]
    assert theirs["model"] == model.name and theirs["counts"] == ours["counts"]
    for field in ("all_by_material", "soft_by_material"):
        assert theirs[field] == pytest.approx(ours[field], abs=0.03), field
