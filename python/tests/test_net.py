"""The PyTorch net against the Rust one: same weights files, same descriptors."""

import numpy as np
import pytest
import torch

import matseg
import matseg.net as mn
from matseg import safetensors


def rgb_tensor(image):
    return torch.from_numpy(image).permute(2, 0, 1)[None].float()


def test_the_default_model_gives_the_rust_descriptors_in_pytorch():
    model = matseg.Model.load("default")
    net, run_json = mn.load("default")
    assert net.config == run_json["net"]
    image = matseg.Generator("2d", seed=3)[1]["image"]
    for h, w in ((224, 256), (96, 160)):
        crop = np.ascontiguousarray(image[:h, :w])
        rust = model.describe_at_own_size(crop)
        with torch.no_grad():
            torch_d = net(mn.normalise(rgb_tensor(crop)))[0].numpy()
        assert torch_d.shape == rust.shape == (model.dim, h, w)
        assert np.abs(torch_d - rust).max() < 1e-4


def test_a_pytorch_checkpoint_loads_in_rust_with_the_same_descriptors(tmp_path):
    torch.manual_seed(0)
    _, default_run = mn.load("default")
    config = default_run["net"]
    net = mn.MaterialNet(config)
    # Perturbed BatchNorm statistics, so eval mode is not the identity.
    for name, b in net.named_buffers():
        if name.endswith("running_var"):
            b.uniform_(0.5, 2.0)
        elif name.endswith("running_mean"):
            b.normal_(0, 0.1)
    net.eval()
    run_json = {"net": config, "options": default_run["options"], "init": "scratch", "data": "online"}
    mn.save(net, run_json, tmp_path)
    image = matseg.Generator("2d", seed=5)[0]["image"][:128, :160].copy()
    rust = matseg.Model.load(tmp_path).describe_at_own_size(image)
    with torch.no_grad():
        torch_d = net(mn.normalise(rgb_tensor(image)))[0].numpy()
    assert np.abs(torch_d - rust).max() < 1e-4


def test_safetensors_round_trip(tmp_path):
    tensors: dict[str, np.ndarray] = {"a.weight": np.arange(12, dtype=np.float32).reshape(3, 4),
                                      "b": np.array([1.5], np.float16), "c": np.array([7, -2], np.int64)}
    safetensors.write(tmp_path / "t.safetensors", tensors, {"source": "test"})
    back, meta = safetensors.read(tmp_path / "t.safetensors")
    assert meta == {"source": "test"}
    assert set(back) == set(tensors)
    for k in tensors:
        assert back[k].dtype == tensors[k].dtype and np.array_equal(back[k], tensors[k])


def test_adaptive_pooling_matches_pytorch():
    x = torch.randn(2, 3, 13, 10)
    for h, w in ((7, 5), (1, 1), (4, 10), (13, 3)):
        ours = mn.adaptive_avg_pool(x, h, w)
        assert torch.allclose(ours, torch.nn.functional.adaptive_avg_pool2d(x, (h, w)), atol=1e-6)
    assert [mn.pooled_side(n, 2) for n in (1, 2, 3, 5)] == [1, 1, 2, 3]
    assert [mn.pooled_side(n, 8) for n in (1, 3, 4, 12)] == [1, 1, 1, 2]


def test_the_pytorch_loss_is_the_rust_loss():
    import matseg.torch as mt
    from matseg import _core

    plan = matseg.BatchPlan(min_side=64, max_side=96, pixels=3 * 80 * 80, min_images=2, max_images=4, p_augment=0.5)
    net, _ = mn.load("default")
    for step in range(3):
        b = mt.BatchStream(matseg.Generator("2d", seed=2), plan, seed=1).batch(step)
        with torch.no_grad():
            d = net(b["images"])
        loss = mn.matseg_loss(d, b["weights"], b["roi"])
        assert loss is not None, "the batch has two materials or more"
        ours = float(loss)
        k = b["weights"].shape[1]
        desc, weights, roi = (np.ascontiguousarray(t.numpy(), np.float32) for t in (d, b["weights"], b["roi"]))
        rust = _core.matseg_loss(desc, weights, roi, tuple(d.shape), k)
        assert rust is not None and abs(ours - rust) < 1e-5 * max(1.0, abs(rust))
    # Fewer than two materials: no loss on either side.
    one = torch.zeros(1, 1, 4, 4)
    one[0, 0] = 1.0
    d = mn.l2_normalise(torch.randn(1, 8, 4, 4))
    assert mn.matseg_loss(d, one, torch.ones(1, 4, 4)) is None
    assert _core.matseg_loss(d.numpy(), one.numpy(), torch.ones(1, 4, 4).numpy(), (1, 8, 4, 4), 1) is None
    # The arrays cross as buffers: bytes are not float32 values.
    with pytest.raises(ValueError, match="descriptors: not an array of f32"):
        _core.matseg_loss(d.numpy().tobytes(), one.numpy(), torch.ones(1, 4, 4).numpy(), (1, 8, 4, 4), 1)
