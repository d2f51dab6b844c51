"""The matseg net (crates/matseg-net) in PyTorch, variable for variable:
it loads and saves the same `run.json` + `model.safetensors` run folders
as `matseg train`, and computes the same descriptors (tested to 1e-4).

    net, run = matseg.net.load("default")      # eval mode, on the CPU
    d = net(net.normalise(rgb))                 # rgb: Bx3xHxW 0..255, sides multiples of 32
"""

from . import _requires

_requires.torch("matseg.net")

import hashlib
import json
import math
import os
import struct
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor, nn

from . import _core, tensor_files

CONSTANTS = _core.net_constants()
MODEL_FILE = CONSTANTS["model_file"]
RUN_FILE = CONSTANTS["run_file"]


def l2_normalise(x: Tensor, dim: int = 1) -> Tensor:
    """`x` scaled to unit length along `dim` (zero vectors stay zero)."""
    return F.normalize(x, dim=dim, eps=1e-12)


def resize(x: Tensor, h: int, w: int) -> Tensor:
    """Bilinear, half-pixel centres (as the Rust net's resize_bilinear)."""
    return F.interpolate(x, (h, w), mode="bilinear", align_corners=False)


class ConvBnGelu(nn.Module):
    """k x k convolution (same padding, no bias), BatchNorm, GELU."""

    def __init__(self, c_in: int, c_out: int, k: int) -> None:
        super().__init__()
        self.conv = nn.Conv2d(c_in, c_out, k, padding=k // 2, bias=False)
        self.bn = nn.BatchNorm2d(c_out)

    def forward(self, x: Tensor) -> Tensor:
        """Convolution, batch norm, GELU."""
        return F.gelu(self.bn(self.conv(x)))


class ConvBnRelu6(nn.Sequential):
    """Convolution, batch norm and ReLU6, as torchvision's MobileNetV2."""

    def __init__(self, c_in: int, c_out: int, k: int, stride: int = 1, groups: int = 1) -> None:
        super().__init__(nn.Conv2d(c_in, c_out, k, stride, k // 2, groups=groups, bias=False),
                         nn.BatchNorm2d(c_out), nn.Hardtanh(0.0, 6.0))


class InvertedResidual(nn.Module):
    """MobileNetV2's block: expand, depthwise 3x3, project; residual when
    the shape is kept."""

    def __init__(self, c_in: int, c_out: int, stride: int, expand: int) -> None:
        super().__init__()
        hidden = c_in * expand
        layers: list[nn.Module] = [] if expand == 1 else [ConvBnRelu6(c_in, hidden, 1)]
        layers += [ConvBnRelu6(hidden, hidden, 3, stride, groups=hidden),
                   nn.Conv2d(hidden, c_out, 1, bias=False), nn.BatchNorm2d(c_out)]
        self.conv = nn.Sequential(*layers)
        self.residual = stride == 1 and c_in == c_out

    def forward(self, x: Tensor) -> Tensor:
        """The block on `x`."""
        y = self.conv(x)
        return x + y if self.residual else y


class MobileNetV2(nn.Module):
    """torchvision's layout; taps after features 3, 6, 13 and the last."""

    SETTINGS = [(1, 16, 1, 1), (6, 24, 2, 2), (6, 32, 3, 2), (6, 64, 4, 2),
                (6, 96, 3, 1), (6, 160, 3, 2), (6, 320, 1, 1)]
    TAPS = (3, 6, 13)
    channels = (24, 32, 96, 1280)

    def __init__(self) -> None:
        super().__init__()
        layers: list[nn.Module] = [ConvBnRelu6(3, 32, 3, 2)]
        c = 32
        for t, out, n, s in self.SETTINGS:
            for i in range(n):
                layers.append(InvertedResidual(c, out, s if i == 0 else 1, t))
                c = out
        layers.append(ConvBnRelu6(c, 1280, 1))
        self.features = nn.Sequential(*layers)

    def forward(self, x: Tensor) -> list[Tensor]:
        """The four taps of RGB input `x`, finest first."""
        taps = []
        for i, layer in enumerate(self.features):
            x = layer(x)
            if i in self.TAPS:
                taps.append(x)
        return taps + [x]


class ChannelNorm(nn.LayerNorm):
    """LayerNorm over the channels of an NCHW tensor."""

    def forward(self, x: Tensor) -> Tensor:
        """`x` normalised over its channels."""
        return super().forward(x.permute(0, 2, 3, 1)).permute(0, 3, 1, 2)


class ConvNextBlock(nn.Module):
    """ConvNeXt's block: depthwise 7x7, LayerNorm, MLP, layer scale, residual."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.dwconv = nn.Conv2d(dim, dim, 7, padding=3, groups=dim)
        self.norm = nn.LayerNorm(dim, eps=1e-6)
        self.pwconv1 = nn.Linear(dim, 4 * dim)
        self.pwconv2 = nn.Linear(4 * dim, dim)
        self.gamma = nn.Parameter(torch.full((dim,), 1e-6))

    def forward(self, x: Tensor) -> Tensor:
        """The block on `x`."""
        y = self.pwconv2(F.gelu(self.pwconv1(self.norm(self.dwconv(x).permute(0, 2, 3, 1)))))
        return x + (y * self.gamma).permute(0, 3, 1, 2)


class ConvNext(nn.Module):
    """The ConvNeXt encoder: four stages of `depths` blocks at widths `dims`."""

    def __init__(self, depths: Sequence[int], dims: Sequence[int]) -> None:
        super().__init__()
        self.downsample_layers = nn.ModuleList()
        self.stages = nn.ModuleList()
        for i in range(4):
            if i == 0:
                down = nn.Sequential(nn.Conv2d(3, dims[0], 4, 4), ChannelNorm(dims[0], eps=1e-6))
            else:
                down = nn.Sequential(ChannelNorm(dims[i - 1], eps=1e-6), nn.Conv2d(dims[i - 1], dims[i], 2, 2))
            self.downsample_layers.append(down)
            self.stages.append(nn.Sequential(*[ConvNextBlock(dims[i]) for _ in range(depths[i])]))
        self.channels = tuple(dims)

    def forward(self, x: Tensor) -> list[Tensor]:
        """The four stages' outputs of RGB input `x`, finest first."""
        taps = []
        for down, stage in zip(self.downsample_layers, self.stages, strict=True):
            x = stage(down(x))
            taps.append(x)
        return taps


def pooled_side(n: int, divisor: int) -> int:
    """Rust's max(1, round(n / divisor)) in integer arithmetic (exportable
    with symbolic sizes): halves round up, as f64::round does here."""
    return max(1, (2 * n + divisor) // (2 * divisor))


def pooling_matrix(n_in: int, n_out: int, like: Tensor) -> Tensor:
    """The n_out x n_in matrix of adaptive average pooling along one axis:
    row i averages inputs floor(i n_in / n_out) .. ceil((i+1) n_in / n_out)."""
    i = torch.arange(n_out, device=like.device).unsqueeze(1)
    j = torch.arange(n_in, device=like.device).unsqueeze(0)
    start = (i * n_in) // n_out
    end = ((i + 1) * n_in + n_out - 1) // n_out
    inside = ((j >= start) & (j < end)).to(like.dtype)
    return inside / inside.sum(1, keepdim=True)


def adaptive_avg_pool(x: Tensor, h: int, w: int) -> Tensor:
    """F.adaptive_avg_pool2d(x, (h, w)) as two matrix products, which
    export to ONNX with dynamic sizes."""
    rows = pooling_matrix(x.shape[2], h, x)
    cols = pooling_matrix(x.shape[3], w, x)
    return rows @ x @ cols.T


class Psp(nn.Module):
    """The pyramid pooling module: branches at 1, 1/2, 1/4 and 1/8 of the
    coarsest tap, resized back and fused."""

    DIVISORS = (1, 2, 4, 8)

    def __init__(self, c_in: int, branch: int, c_out: int) -> None:
        super().__init__()
        self.branches = nn.ModuleList([ConvBnGelu(c_in, branch, 3) for _ in self.DIVISORS])
        self.fuse = ConvBnGelu(branch * len(self.DIVISORS), c_out, 3)

    def forward(self, x: Tensor) -> Tensor:
        """The fused pyramid of `x`."""
        h, w = x.shape[2:]
        outs = []
        for branch, divisor in zip(self.branches, self.DIVISORS, strict=True):
            if divisor == 1:
                outs.append(branch(x))
                continue
            pooled = adaptive_avg_pool(x, pooled_side(h, divisor), pooled_side(w, divisor))
            outs.append(resize(branch(pooled), h, w))
        return self.fuse(torch.cat(outs, 1))


class DecoderStep(nn.Module):
    """One decoder step: the coarser features convolved and upsampled, plus
    a 1x1 of the skip tap."""

    def __init__(self, c_in: int, width: int, skip: int) -> None:
        super().__init__()
        self.conv = ConvBnGelu(c_in, width, 3)
        self.skip = ConvBnGelu(skip, width, 1)


class Decoder(nn.Module):
    """The decoder: from the PSP output up through the three finer taps."""

    def __init__(self, c_in: int, widths: Sequence[int], taps: Sequence[int]) -> None:
        super().__init__()
        self.steps = nn.ModuleList()
        for width, skip in zip(widths, (taps[2], taps[1], taps[0]), strict=True):
            self.steps.append(DecoderStep(c_in, width, skip))
            c_in = width

    def forward(self, psp: Tensor, taps: Sequence[Tensor]) -> Tensor:
        """Features at the finest tap's stride."""
        x = psp
        for step, skip in zip(self.steps, (taps[2], taps[1], taps[0]), strict=True):
            x = resize(step.conv(x), *skip.shape[2:]) + step.skip(skip)
        return x


class SplitMix64:
    """The colour part's fixed random draws (as crates/matseg-net/src/colour.rs)."""

    MASK = (1 << 64) - 1

    def __init__(self, seed: int) -> None:
        self.state = seed

    def next(self) -> int:
        """The next 64-bit draw."""
        self.state = (self.state + 0x9E3779B97F4A7C15) & self.MASK
        z = self.state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & self.MASK
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & self.MASK
        return z ^ (z >> 31)

    def uniform(self) -> float:
        """A uniform draw in (0, 1)."""
        return ((self.next() >> 11) + 0.5) / float(1 << 53)

    def standard_normal(self) -> float:
        """A standard normal draw (Box-Muller)."""
        u, v = self.uniform(), self.uniform()
        return math.sqrt(-2.0 * math.log(u)) * math.cos(2 * math.pi * v)


def srgb_to_lab(rgb: Tensor) -> Tensor:
    """CIE L*a*b* (D65) of 0..255 sRGB, Bx3xHxW."""
    c = rgb / 255.0
    linear = torch.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    m = torch.tensor(CONSTANTS["linear_srgb_to_xyz"], dtype=torch.float32)
    wx, wz = torch.tensor(CONSTANTS["d65_white_xz"], dtype=torch.float32)
    m = torch.stack([m[0] / wx, m[1], m[2] / wz]).to(rgb.dtype).to(rgb.device)
    xyz = (linear.permute(0, 2, 3, 1) @ m.T).permute(0, 3, 1, 2)
    eps, kappa = CONSTANTS["lab_epsilon"], CONSTANTS["lab_kappa"]
    f = torch.where(xyz > eps, xyz.clamp_min(eps) ** (1.0 / 3.0), (xyz * kappa + 16.0) / 116.0)
    fx, fy, fz = f[:, 0], f[:, 1], f[:, 2]
    return torch.stack([fy * 116.0 - 16.0, (fx - fy) * 500.0, (fy - fz) * 200.0], 1)


def cell_lab(x: Tensor, h4: int, w4: int) -> Tensor:
    """Each cell's mean L*a*b* colour, Bx3xh4xw4, of the net's input x."""
    return adaptive_avg_pool(srgb_to_lab(denormalise(x).clamp(0.0, 255.0)), h4, w4)


class ColourPart(nn.Module):
    """Each stride-4 cell's mean colour as random Fourier features of its
    L*a*b* value (a Gaussian kernel of learned bandwidth), with a learned
    weight."""

    def __init__(self) -> None:
        super().__init__()
        n = CONSTANTS["colour_features"]
        draws = SplitMix64(CONSTANTS["colour_seed"])
        normals = [draws.standard_normal() for _ in range(n * 3)]
        phases = [draws.uniform() * 2 * math.pi for _ in range(n)]
        self.register_buffer("projection", torch.tensor(normals, dtype=torch.float32).view(n, 3))
        self.register_buffer("phase", torch.tensor(phases, dtype=torch.float32))
        self.log_weight = nn.Parameter(torch.zeros(1))
        self.log_bandwidth = nn.Parameter(torch.full((1,), math.log(CONSTANTS["colour_initial_bandwidth"])))

    def forward(self, x: Tensor, h4: int, w4: int) -> Tensor:
        """The colour part of 0..255 RGB `x` on its h4 x w4 stride-4 grid."""
        return self.from_cells(cell_lab(x, h4, w4))

    def from_cells(self, lab: Tensor) -> Tensor:
        """The weighted part of cells whose mean L*a*b* colours Bx3xhxw are given."""
        lab = lab / self.log_bandwidth.exp()
        angles = (lab.permute(0, 2, 3, 1) @ self.projection.T).permute(0, 3, 1, 2)
        angles = angles + self.phase.view(1, -1, 1, 1)
        return l2_normalise(torch.cos(angles)) * self.log_weight.exp()


def _mean(like: Tensor) -> Tensor:
    """The input mean, 1x3x1x1, in `like`'s dtype and on its device."""
    return torch.tensor(CONSTANTS["input_mean"], dtype=like.dtype, device=like.device).view(1, 3, 1, 1)


def normalise(rgb: Tensor) -> Tensor:
    """The net's input from 0..255 RGB Bx3xHxW: (x - mean) / scale."""
    return (rgb - _mean(rgb)) / CONSTANTS["input_scale"]


def denormalise(x: Tensor) -> Tensor:
    """0..255 RGB back from the net's input: the inverse of `normalise`."""
    return x * CONSTANTS["input_scale"] + _mean(x)


class MaterialNet(nn.Module):
    """Encoder, PSP, decoder, 1x1 head at stride 4; with encoder_features
    and colour_features the weighted parts beside it; resized to the input
    and L2-normalised per pixel. `config` is run.json's "net"."""

    def __init__(self, config: Mapping[str, Any]) -> None:
        super().__init__()
        self.config = dict(config)
        enc = config["encoder"]
        if enc["kind"] == "mobilenet-v2":
            self.encoder: MobileNetV2 | ConvNext = MobileNetV2()
        elif enc["kind"] == "convnext":
            self.encoder = ConvNext(enc["depths"], enc["dims"])
        else:
            raise ValueError(f"net: unknown encoder kind '{enc['kind']}'")
        taps = self.encoder.channels
        self.psp = Psp(taps[3], config["psp_branch"], config["psp_out"])
        self.decoder = Decoder(config["psp_out"], config["decoder"], taps)
        self.head = nn.Conv2d(config["decoder"][2], config["descriptor_dim"], 1)
        if config.get("encoder_features"):
            self.part_log_weights: nn.Parameter | None = nn.Parameter(torch.zeros(4))
        else:
            self.part_log_weights = None
        self.colour = ColourPart() if config.get("colour_features") else None

    normalise = staticmethod(normalise)

    def coarse(self, x: Tensor) -> Tensor:
        """Descriptors on the stride-4 grid, not yet normalised."""
        taps = self.encoder(x)
        lab = cell_lab(x, *taps[0].shape[2:]) if self.colour is not None else None
        return self.coarse_from_taps(taps, lab)

    def coarse_from_taps(self, taps: Sequence[Tensor], lab: Tensor | None = None) -> Tensor:
        """`coarse` from the encoder's four taps (and, with a colour part,
        the cells' colours `cell_lab` on the stride-4 grid): everything
        after the encoder, for training on cached features."""
        learned = self.head(self.decoder(self.psp(taps[3]), taps))
        if self.part_log_weights is None and self.colour is None:
            return learned
        h4, w4 = learned.shape[2:]
        if self.part_log_weights is not None:
            weights = self.part_log_weights.exp()
            parts = [l2_normalise(resize(t, h4, w4)) * weights[i]
                     for i, t in enumerate((learned, taps[0], taps[1], taps[2]))]
        else:
            parts = [l2_normalise(learned)]
        if self.colour is not None:
            parts.append(self.colour.from_cells(lab))
        return torch.cat(parts, 1)

    def forward(self, x: Tensor) -> Tensor:
        """Unit descriptors BxDxHxW of normalised input Bx3xHxW."""
        h, w = x.shape[2:]
        return l2_normalise(resize(self.coarse(x), h, w))


def state_names(net: nn.Module) -> list[str]:
    """The names of the net's stored variables (parameters and BatchNorm
    statistics, as matseg's safetensors files hold them)."""
    return [k for k in net.state_dict() if not k.endswith("num_batches_tracked")]


def encoder_digest(net: nn.Module) -> str:
    """SHA-256 of the encoder's stored variables, as `matseg features`
    records it for a cache (matseg_net::features::encoder_digest): names
    under `encoder.` sorted, each its name's length and bytes, its shape
    and its float32 values."""
    h = hashlib.sha256()
    for name, a in sorted(state_arrays(net).items()):
        if not name.startswith("encoder."):
            continue
        h.update(struct.pack("<Q", len(name.encode())))
        h.update(name.encode())
        for d in a.shape:
            h.update(struct.pack("<q", d))
        h.update(np.ascontiguousarray(a, "<f4").tobytes())
    return h.hexdigest()


def state_arrays(net: nn.Module) -> dict[str, np.ndarray]:
    """The net's stored variables as float32 numpy arrays, by name."""
    state = net.state_dict()
    return {k: state[k].detach().to("cpu", torch.float32).contiguous().numpy() for k in state_names(net)}


def run_files(name: str | os.PathLike[str]) -> tuple[str, str]:
    """(run folder, weights file) of a model name: `default`, a run folder
    or a weights file with run.json beside it (as `matseg segment` finds them)."""
    folder, weights = _core.run_files(os.fspath(name))
    return os.fspath(folder), os.fspath(weights)


def load_weights(net: nn.Module, path: str | os.PathLike[str]) -> None:
    """Loads a safetensors file into `net` (every variable, no others)."""
    tensors, _ = tensor_files.read(path)
    load_arrays(net, tensors, path)


def load_arrays(net: nn.Module, tensors: Mapping[str, np.ndarray], path: str | os.PathLike[str]) -> None:
    """Copies name -> numpy array into `net` (every variable, no others);
    errors name `path`, where the arrays came from."""
    names = set(state_names(net))
    missing, extra = sorted(names - tensors.keys()), sorted(tensors.keys() - names)
    if missing or extra:
        raise ValueError(f"{path}: does not fit the net (missing {missing[:5]}, unexpected {extra[:5]})")
    state = net.state_dict()
    with torch.no_grad():
        for k in names:
            value = torch.from_numpy(tensors[k]).to(torch.float32)
            if tuple(value.shape) != tuple(state[k].shape):
                raise ValueError(f"{path}: {k} is {tuple(value.shape)}, the net's {tuple(state[k].shape)}")
            state[k].copy_(value)


def load(name: str | os.PathLike[str] = "default") -> tuple[MaterialNet, dict[str, Any]]:
    """The net of a run (eval mode, CPU) and its run.json as a dict."""
    folder, weights = run_files(name)
    run_path = os.path.join(folder, RUN_FILE)
    if not os.path.isfile(run_path):
        raise FileNotFoundError(f"{name}: not a run: no {RUN_FILE} beside the weights")
    with open(run_path) as f:
        run = json.load(f)
    net = MaterialNet(run["net"])
    load_weights(net, weights)
    return net.eval(), run


def save(net: nn.Module, run: Mapping[str, Any], folder: str | os.PathLike[str],
         arrays: dict[str, np.ndarray] | None = None) -> None:
    """Writes `folder/model.safetensors` (32-bit floats) and `run.json`;
    `arrays`: the net's `state_arrays` when the caller has them already."""
    os.makedirs(folder, exist_ok=True)
    tensor_files.write(os.path.join(folder, MODEL_FILE), state_arrays(net) if arrays is None else arrays)
    tmp = os.path.join(folder, f"{RUN_FILE}.{os.getpid()}.tmp")
    with open(tmp, "w") as f:
        json.dump(run, f, indent=2)
    os.replace(tmp, os.path.join(folder, RUN_FILE))


def matseg_loss(desc: Tensor, weights: Tensor, roi: Tensor) -> Tensor | None:
    """The MatSeg loss (crates/matseg-net/src/loss.rs): one softmax over
    all materials of the batch, soft targets, ROI-masked, mean over B*H*W.
    None when the batch has fewer than two materials."""
    b, d, h, w = desc.shape
    n = h * w
    # One unbind: indexing the batch tensor per use would make the backward
    # pass add a zero-filled batch-sized gradient for every use.
    flat = desc.reshape(b, d, n).unbind(0)
    wts = weights.reshape(b, -1, n).to(desc.dtype)
    materials, owned = [], []
    for i in range(b):
        region = (wts[i] > CONSTANTS["region_threshold"]).to(desc.dtype)
        counts = region.sum(1)
        mine = [k for k in range(region.shape[0]) if counts[k] > 0]
        if mine:
            means = (flat[i] @ region[mine].T) / counts[mine]
            materials.append(l2_normalise(means, dim=0).T)
        owned.append(mine)
    if sum(len(m) for m in owned) < 2:
        return None
    materials = torch.cat(materials)
    total, first = desc.new_zeros(()), 0
    for i in range(b):
        mine = owned[i]
        if not mine:
            continue
        log_p = torch.log_softmax(materials @ flat[i] / CONSTANTS["temperature"], 0)
        cross = (log_p[first:first + len(mine)] * wts[i][mine]).sum(0)
        total = total - (cross * roi[i].reshape(n).to(desc.dtype)).sum()
        first += len(mine)
    return total / (b * n)
