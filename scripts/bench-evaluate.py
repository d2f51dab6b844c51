"""How much time `matseg.evaluate` itself takes beside the model it scores:
the shipped model (through `matseg.Model`) on a benchmark, the time inside
the model's calls against the whole evaluation.

    .venv/bin/python scripts/bench-evaluate.py [--bench benchmarks/real-dev] [--protocol points] [--runs 3] [--stride 1]

Prints, per run, the evaluation's wall time, the time inside the model's
`describe` calls and the rest (the harness: reading and resizing photos,
handing arrays across, pooling, scoring) as a share of the model's time;
then the median share. `--stride N` hands over every Nth row and column
of the descriptors, as a model with a coarse feature map would (matseg
then resizes them to the photo).
"""

import argparse
import statistics
import time

import numpy as np

import matseg
import matseg.evaluate


class Timed:
    """The shipped model's descriptors as a model outside matseg answers:
    C-contiguous (h, w, d) float32, with the time spent making them."""

    def __init__(self, model: matseg.Model, stride: int) -> None:
        self.model = model
        self.stride = stride
        self.name = "default"
        self.seconds = 0.0

    def describe(self, image):
        started = time.perf_counter()
        d = self.model.describe(image)[:, ::self.stride, ::self.stride]
        out = np.ascontiguousarray(d.transpose(1, 2, 0))
        self.seconds += time.perf_counter() - started
        return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--bench", default="benchmarks/real-dev")
    parser.add_argument("--protocol", choices=["points", "masks"], default="points")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--stride", type=int, default=1)
    args = parser.parse_args()
    evaluate = getattr(matseg.evaluate, args.protocol)
    model = matseg.Model.load("default")
    shares = []
    for run in range(args.runs):
        timed = Timed(model, args.stride)
        started = time.perf_counter()
        evaluate(args.bench, timed, progress=False)
        total = time.perf_counter() - started
        harness = total - timed.seconds
        shares.append(harness / timed.seconds)
        print(f"run {run + 1}: {total:.1f} s in all, {timed.seconds:.1f} s in the model, "
              f"{harness:.2f} s in the harness ({100 * shares[-1]:.1f}% of the model's time)")
    print(f"median: the harness takes {100 * statistics.median(shares):.1f}% of the model's time")


if __name__ == "__main__":
    main()
