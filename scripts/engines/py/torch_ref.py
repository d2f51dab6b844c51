"""Inputs, libtorch reference (timing + output), ONNX export and comparison.

Run with the project's .venv/bin/python from the repository's root (the
run folder `default` resolves from there); scripts/engines/run.sh does:

    prep      photo -> data/input_{W}x{H}.f32 (normalised as net.rs)
    ref       torch (2 threads): median of 5 after 2 warm-ups, data/out_torch_{W}x{H}.f32
    onnx      data/learned.onnx: the learned part (encoder, PSP, decoder, head)
    compare   per-cell cosine between all data/out_*_{W}x{H}.f32
"""

import glob
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "data")
SIZES = [(704, 512), (704, 384)]
# the other three sizes of the multi-size pass for the project's 1333x750 benchmark photo
EXTRA = [(448, 256), (256, 160), (128, 64)]
if os.environ.get("EXTRA"):
    SIZES = SIZES + EXTRA
PHOTO = os.path.join(HERE, "..", "..", "..", "assets", "photos", "seeding_by_Clements_Engelhardt.jpg")
MEAN = np.array([123.68, 116.78, 103.94], np.float32)
SCALE = 65.0


def prep():
    from PIL import Image

    img = Image.open(PHOTO).convert("RGB")
    for w, h in SIZES:
        a = np.asarray(img.resize((w, h), Image.BILINEAR), np.float32)  # h, w, 3
        x = ((a - MEAN) / SCALE).transpose(2, 0, 1).copy()
        x.astype("<f4").tofile(os.path.join(DATA, f"input_{w}x{h}.f32"))
        print(f"input_{w}x{h}.f32", x.shape, float(x.mean()), float(x.std()))


def learned_module():
    import torch
    from torch import nn

    # the venv's installed matseg (with its compiled _core)
    from matseg import net as netlib

    net, _ = netlib.load("default")

    class Learned(nn.Module):
        def __init__(self, net):
            super().__init__()
            self.net = net

        def forward(self, x):
            taps = self.net.encoder(x)
            return self.net.head(self.net.decoder(self.net.psp(taps[3]), taps))

    return Learned(net).eval(), netlib, torch


def load_input(w, h):
    return np.fromfile(os.path.join(DATA, f"input_{w}x{h}.f32"), "<f4").reshape(1, 3, h, w)


def ref():
    m, netlib, torch = learned_module()
    torch.set_num_threads(int(os.environ.get("THREADS", "2")))
    import resource
    print("torch", torch.__version__, "threads", torch.get_num_threads(),
          "maxrss after import+load MB", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
    for w, h in SIZES:
        x = torch.from_numpy(load_input(w, h))
        times = []
        with torch.inference_mode():
            for i in range(7):
                t0 = time.perf_counter()
                y = m(x)
                ms = (time.perf_counter() - t0) * 1e3
                if i >= 2:
                    times.append(ms)
                print(f"torch {w}x{h} run {i}: {ms:.1f} ms", file=sys.stderr)
        y.numpy().astype("<f4").tofile(os.path.join(DATA, f"out_torch_{w}x{h}.f32"))
        s = sorted(times)
        print(f"RESULT torch-{torch.__version__} {w}x{h} median_ms={s[2]:.1f} min_ms={s[0]:.1f} "
              f"max_ms={s[-1]:.1f} runs={[round(t, 1) for t in times]} shape={tuple(y.shape)} "
              f"maxrss_MB={resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f}")


def onnx():
    m, netlib, torch = learned_module()
    out = os.path.join(DATA, "learned.onnx")
    blocks_h = torch.export.Dim("blocks_h", min=1, max=4096 // 32)
    blocks_w = torch.export.Dim("blocks_w", min=1, max=4096 // 32)
    torch.onnx.export(
        m, (torch.zeros(1, 3, 64, 96),), out, input_names=["image"], output_names=["learned"],
        dynamic_shapes={"x": {2: 32 * blocks_h, 3: 32 * blocks_w}},
        opset_version=18, dynamo=True, external_data=False, verbose=False,
    )
    import onnx as onnxlib

    model = onnxlib.load(out)
    del model.graph.value_info[:]
    onnxlib.save(model, out)
    ops = {}
    for n in model.graph.node:
        ops[n.op_type] = ops.get(n.op_type, 0) + 1
    print(out, os.path.getsize(out) / 1e6, "MB", ops)


def compare():
    for w, h in SIZES:
        files = sorted(glob.glob(os.path.join(DATA, f"out_*_{w}x{h}.f32")))
        outs = {}
        for f in files:
            name = os.path.basename(f)[4:-len(f"_{w}x{h}.f32")]
            a = np.fromfile(f, "<f4").astype(np.float64)
            if a.size != 128 * (h // 4) * (w // 4):
                print(f"{name}: wrong size {a.size}")
                continue
            outs[name] = a.reshape(128, -1)
        names = list(outs)
        print(f"== {w}x{h} (128 x {h // 4} x {w // 4})")
        for i, a in enumerate(names):
            for b in names[i + 1:]:
                x, y = outs[a], outs[b]
                cos = (x * y).sum(0) / (np.linalg.norm(x, axis=0) * np.linalg.norm(y, axis=0))
                rel = np.linalg.norm(x - y) / np.linalg.norm(y)
                print(f"{a:>16} vs {b:<16} 1-cos max {1 - cos.min():.2e} mean {1 - cos.mean():.2e} (cos min {cos.min():.9f} mean {cos.mean():.9f}) "
                      f"rel_l2 {rel:.2e} max_abs {np.abs(x - y).max():.2e}")


if __name__ == "__main__":
    {"prep": prep, "ref": ref, "onnx": onnx, "compare": compare}[sys.argv[1]]()
