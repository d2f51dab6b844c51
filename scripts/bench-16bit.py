"""16-bit inference on the CPU: the shipped net's descriptor pass (the
coarse grid `matseg track` uses) at 320 x 192, a 720p frame at its
default --side 320 rounded to the net's multiple of 32, in 32-bit floats,
under autocast to bfloat16 and float16, and with the weights themselves
in 16 bits. Prints the median of 7 runs after 2 warm-ups (range) and each
16-bit pass's cosine to the 32-bit descriptors.

    .venv/bin/python scripts/bench-16bit.py PHOTO      # the matseg package installed (make test)
"""

import copy
import sys
import time

import numpy as np
import torch
from PIL import Image

import matseg.net

torch.set_num_threads(2)
net, _ = matseg.net.load("default")
photo = Image.open(sys.argv[1]).convert("RGB").resize((320, 192))
x = net.normalise(torch.from_numpy(np.asarray(photo).copy()).permute(2, 0, 1)[None].float())


def timed(run, n=7):
    for _ in range(2):
        run()
    times = []
    for _ in range(n):
        started = time.perf_counter()
        out = run()
        times.append(time.perf_counter() - started)
    return np.median(times) * 1e3, min(times) * 1e3, max(times) * 1e3, out


def report(name, run, reference=None):
    median, low, high, out = timed(run)
    line = f"{name}: {median:.1f} ms ({low:.1f}-{high:.1f})"
    if reference is not None:
        cos = torch.nn.functional.cosine_similarity(out.float(), reference, dim=1)
        line += f", cosine to 32-bit min {cos.min():.4f} mean {cos.mean():.5f}"
    print(line)
    return out


with torch.inference_mode():
    full = report("32-bit", lambda: net.coarse(x))
    for name, dtype in [("bfloat16", torch.bfloat16), ("float16", torch.float16)]:
        def autocast():
            with torch.autocast("cpu", dtype=dtype):
                return net.coarse(x)
        report(f"autocast to {name}", autocast, full)
        half = copy.deepcopy(net).to(dtype)
        report(f"{name} weights", lambda: half.coarse(x.to(dtype)), full)
