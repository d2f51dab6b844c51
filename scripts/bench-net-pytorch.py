"""The matseg net (crates/matseg-net) in plain PyTorch, timed like
`matseg bench-net`: inference forward, and a training step (forward, MatSeg
loss, backward, AdamW) on a synthetic batch. For the PyTorch ratio in
BENCHMARKS.md; run it with scripts/bench-net-pytorch.sh, which makes a
throw-away venv.

    python bench-net-pytorch.py --encoder mobilenet-v2 --side 256 --batch 4
"""

import argparse
import json
import statistics
import time

import torch
import torch.nn.functional as F
from torch import nn

TEMPERATURE = 0.2
REGION_THRESHOLD = 0.5
MATERIALS = 3


class ConvBnGelu(nn.Sequential):
    def __init__(self, c_in, c_out, k):
        super().__init__(
            nn.Conv2d(c_in, c_out, k, padding=k // 2, bias=False),
            nn.BatchNorm2d(c_out),
            nn.GELU(),
        )


class ConvBnRelu6(nn.Sequential):
    def __init__(self, c_in, c_out, k, stride=1, groups=1):
        super().__init__(
            nn.Conv2d(c_in, c_out, k, stride, k // 2, groups=groups, bias=False),
            nn.BatchNorm2d(c_out),
            nn.ReLU6(),
        )


class InvertedResidual(nn.Module):
    def __init__(self, c_in, c_out, stride, expand):
        super().__init__()
        hidden = c_in * expand
        layers = [] if expand == 1 else [ConvBnRelu6(c_in, hidden, 1)]
        layers += [
            ConvBnRelu6(hidden, hidden, 3, stride, groups=hidden),
            nn.Conv2d(hidden, c_out, 1, bias=False),
            nn.BatchNorm2d(c_out),
        ]
        self.conv = nn.Sequential(*layers)
        self.residual = stride == 1 and c_in == c_out

    def forward(self, x):
        y = self.conv(x)
        return x + y if self.residual else y


class MobileNetV2(nn.Module):
    """torchvision's layout; taps after features 3, 6, 13 and 18."""

    SETTINGS = [(1, 16, 1, 1), (6, 24, 2, 2), (6, 32, 3, 2), (6, 64, 4, 2),
                (6, 96, 3, 1), (6, 160, 3, 2), (6, 320, 1, 1)]
    TAPS = (3, 6, 13, 18)
    CHANNELS = (24, 32, 96, 1280)

    def __init__(self):
        super().__init__()
        layers = [ConvBnRelu6(3, 32, 3, 2)]
        c = 32
        for t, out, n, s in self.SETTINGS:
            for i in range(n):
                layers.append(InvertedResidual(c, out, s if i == 0 else 1, t))
                c = out
        layers.append(ConvBnRelu6(c, 1280, 1))
        self.features = nn.Sequential(*layers)

    def forward(self, x):
        taps = []
        for i, layer in enumerate(self.features):
            x = layer(x)
            if i in self.TAPS:
                taps.append(x)
        return taps


class ChannelNorm(nn.LayerNorm):
    def forward(self, x):
        return super().forward(x.permute(0, 2, 3, 1)).permute(0, 3, 1, 2)


class ConvNextBlock(nn.Module):
    def __init__(self, dim):
        super().__init__()
        self.dwconv = nn.Conv2d(dim, dim, 7, padding=3, groups=dim)
        self.norm = nn.LayerNorm(dim, eps=1e-6)
        self.pwconv1 = nn.Linear(dim, 4 * dim)
        self.pwconv2 = nn.Linear(4 * dim, dim)
        self.gamma = nn.Parameter(torch.full((dim,), 1e-6))

    def forward(self, x):
        y = self.dwconv(x).permute(0, 2, 3, 1)
        y = self.pwconv2(F.gelu(self.pwconv1(self.norm(y)))) * self.gamma
        return x + y.permute(0, 3, 1, 2)


class ConvNext(nn.Module):
    def __init__(self, depths, dims):
        super().__init__()
        self.downsample = nn.ModuleList()
        self.stages = nn.ModuleList()
        for i in range(4):
            if i == 0:
                down = nn.Sequential(nn.Conv2d(3, dims[0], 4, 4), ChannelNorm(dims[0], eps=1e-6))
            else:
                down = nn.Sequential(ChannelNorm(dims[i - 1], eps=1e-6),
                                     nn.Conv2d(dims[i - 1], dims[i], 2, 2))
            self.downsample.append(down)
            self.stages.append(nn.Sequential(*[ConvNextBlock(dims[i]) for _ in range(depths[i])]))
        self.CHANNELS = tuple(dims)

    def forward(self, x):
        taps = []
        for down, stage in zip(self.downsample, self.stages):
            x = stage(down(x))
            taps.append(x)
        return taps


class Psp(nn.Module):
    SCALES = (1.0, 0.5, 0.25, 0.125)

    def __init__(self, c_in, branch, c_out):
        super().__init__()
        self.branches = nn.ModuleList([ConvBnGelu(c_in, branch, 3) for _ in self.SCALES])
        self.fuse = ConvBnGelu(branch * len(self.SCALES), c_out, 3)

    def forward(self, x):
        h, w = x.shape[2:]
        outs = []
        for branch, scale in zip(self.branches, self.SCALES):
            if scale == 1.0:
                outs.append(branch(x))
                continue
            size = (max(1, round(h * scale)), max(1, round(w * scale)))
            pooled = F.adaptive_avg_pool2d(x, size)
            outs.append(F.interpolate(branch(pooled), (h, w), mode="bilinear", align_corners=False))
        return self.fuse(torch.cat(outs, 1))


class MaterialNet(nn.Module):
    def __init__(self, encoder, psp_branch, psp_out, decoder, dim=128):
        super().__init__()
        self.encoder = encoder
        taps = encoder.CHANNELS
        self.psp = Psp(taps[3], psp_branch, psp_out)
        self.convs = nn.ModuleList()
        self.skips = nn.ModuleList()
        c = psp_out
        for width, skip in zip(decoder, (taps[2], taps[1], taps[0])):
            self.convs.append(ConvBnGelu(c, width, 3))
            self.skips.append(ConvBnGelu(skip, width, 1))
            c = width
        self.head = nn.Conv2d(decoder[2], dim, 1)

    def forward(self, x):
        h, w = x.shape[2:]
        taps = self.encoder(x)
        y = self.psp(taps[3])
        for conv, skip, tap in zip(self.convs, self.skips, (taps[2], taps[1], taps[0])):
            y = F.interpolate(conv(y), tap.shape[2:], mode="bilinear", align_corners=False) + skip(tap)
        y = F.interpolate(self.head(y), (h, w), mode="bilinear", align_corners=False)
        return F.normalize(y, dim=1, eps=1e-12)


def preset(name):
    if name == "mobilenet-v2":
        return MaterialNet(MobileNetV2(), 128, 256, (128, 128, 128))
    depths, dims = {
        "convnext-tiny": ((3, 3, 9, 3), (96, 192, 384, 768)),
        "convnext-base": ((3, 3, 27, 3), (128, 256, 512, 1024)),
    }[name]
    return MaterialNet(ConvNext(depths, dims), dims[3] // 2, dims[3], (dims[2], dims[1], 128))


def matseg_loss(desc, weights, roi):
    """SPEC 8, as crates/matseg-net/src/loss.rs: one softmax over all
    materials of the batch, soft targets, ROI-masked, mean over B*H*W."""
    b, d, h, w = desc.shape
    n = h * w
    flat = desc.reshape(b, d, n)
    wts = weights.reshape(b, -1, n)
    materials, owned = [], []
    for i in range(b):
        region = (wts[i] > REGION_THRESHOLD).to(desc.dtype)
        counts = region.sum(1)
        mine = [k for k in range(region.shape[0]) if counts[k] > 0]
        for k in mine:
            materials.append(F.normalize(flat[i] @ region[k] / counts[k], dim=0, eps=1e-12))
        owned.append(mine)
    if len(materials) < 2:
        return None
    materials = torch.stack(materials)
    total, first = desc.new_zeros(()), 0
    for i in range(b):
        mine = owned[i]
        if not mine:
            continue
        log_p = torch.log_softmax(materials @ flat[i] / TEMPERATURE, 0)
        cross = (log_p[first:first + len(mine)] * wts[i][mine]).sum(0)
        total = total - (cross * roi[i].reshape(n)).sum()
        first += len(mine)
    return total / (b * n)


def synthetic_batch(batch, side, generator):
    rgb = torch.randint(0, 256, (batch, 3, side, side), generator=generator).float()
    band = torch.arange(side).float() / side * MATERIALS - 0.5
    planes = torch.stack([(1 - (band - m).abs()).clamp(0, 1) for m in range(MATERIALS)])
    weights = planes[:, :, None].expand(MATERIALS, side, side).expand(batch, MATERIALS, side, side)
    mean = torch.tensor([123.68, 116.78, 103.94]).view(1, 3, 1, 1)
    return (rgb - mean) / 65.0, weights.contiguous(), torch.ones(batch, side, side)


def timed(warmup, repeats, f, sync):
    for _ in range(warmup):
        f()
    sync()
    out = []
    for _ in range(repeats):
        start = time.perf_counter()
        f()
        sync()
        out.append((time.perf_counter() - start) * 1e3)
    return statistics.median(out)


def peak_rss_mib():
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    return None


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--encoder", default="mobilenet-v2")
    parser.add_argument("--side", type=int, default=256)
    parser.add_argument("--batch", type=int, default=4)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--warmup", type=int, default=1)
    parser.add_argument("--device", default="cpu")
    args = parser.parse_args()
    torch.manual_seed(0)
    device = torch.device(args.device)
    net = preset(args.encoder).to(device)
    optimizer = torch.optim.AdamW(net.parameters(), lr=1e-4, weight_decay=4e-5)
    batch = synthetic_batch(args.batch, args.side, torch.Generator().manual_seed(1))
    images, weights, roi = (t.to(device) for t in batch)

    def sync():
        if device.type == "cuda":
            torch.cuda.synchronize()

    def forward():
        net.eval()
        with torch.no_grad():
            net(images)

    def step():
        net.train()
        optimizer.zero_grad()
        loss = matseg_loss(net(images), weights, roi)
        loss.backward()
        optimizer.step()

    f = timed(args.warmup, args.repeats, forward, sync)
    s = timed(args.warmup, args.repeats, step, sync)
    print(json.dumps({
        "encoder": args.encoder, "side": args.side, "batch": args.batch, "device": args.device,
        "threads": torch.get_num_threads(), "torch": torch.__version__,
        "forward_ms": f, "train_step_ms": s, "peak_rss_mib": peak_rss_mib(),
    }))


if __name__ == "__main__":
    main()
