"""The matseg net in PyTorch (the `matseg` package's `matseg.net`, which
gives the Rust net's descriptors to 1e-4), timed like `matseg bench-net`:
inference forward, and a training step (forward, MatSeg loss, backward,
AdamW) on a synthetic batch. For the PyTorch ratio in BENCHMARKS.md; run it
with scripts/bench-net-pytorch.sh, which installs the package into the
project's .venv.

    python bench-net-pytorch.py --encoder mobilenet-v2 --side 256 --batch 4
"""

import argparse
import json
import statistics
import time

import torch

from matseg import _core
from matseg.net import MaterialNet, matseg_loss, normalise

MATERIALS = 3


def preset(name):
    """The net `matseg bench-net --encoder NAME` times, in PyTorch."""
    return MaterialNet(json.loads(_core.net_preset(name, False, False)))


def synthetic_batch(batch, side, generator):
    rgb = torch.randint(0, 256, (batch, 3, side, side), generator=generator).float()
    band = torch.arange(side).float() / side * MATERIALS - 0.5
    planes = torch.stack([(1 - (band - m).abs()).clamp(0, 1) for m in range(MATERIALS)])
    weights = planes[:, :, None].expand(MATERIALS, side, side).expand(batch, MATERIALS, side, side)
    return normalise(rgb), weights.contiguous(), torch.ones(batch, side, side)


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
