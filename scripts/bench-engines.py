"""The shipped model's scores on both inference engines, on every benchmark:
`matseg eval` run twice with the same arguments, once on the pure-Rust
engine (`MATSEG_ENGINE=rust`, the CPU's default) and once on libtorch
(`MATSEG_ENGINE=libtorch`), and the scores side by side with their largest
difference; then the descriptors of every photo of those benchmarks
compared cell by cell (`cargo bench -p matseg-infer --bench maps`). Prints
Markdown tables (BENCHMARKS.md, "Inference without libtorch").

    .venv/bin/python scripts/bench-engines.py [--matseg target/release/matseg]

The benchmarks: benchmarks/real-dev (points), a generated point benchmark
(`matseg bench-set make -n 20 --seed 0`), benchmarks/real-masks (masks and
clicks), a generated mask benchmark (`matseg bench-set masks -n 12 --seed
0`, masks) and benchmarks/video-gen/data (tracking, when
benchmarks/video-gen/make.sh has made it). About 15 minutes on 2 cores.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from typing import Any

ENGINES = ["rust", "libtorch"]


def scores(protocol: str, report: dict[str, Any]) -> dict[str, float]:
    """The scores of one model's report by `protocol`."""
    if protocol == "points":
        return {"All": report["all_by_material"], "Soft": report["soft_by_material"]}
    if protocol == "masks":
        return {"IoU": report["mean_iou"]}
    if protocol == "clicks":
        return {"NoC@85": report["noc85"], "IoU@1": report["miou_at"]["1"], "IoU@3": report["miou_at"]["3"]}
    return {"IoU": report["with_memory"]["mean_iou"], "IoU, first frame only": report["first_frame_only"]["mean_iou"]}


def evaluate(matseg: str, engine: str, protocol: str, bench: str) -> tuple[dict[str, float], float]:
    """The shipped model's scores by `protocol` on `bench` on `engine`, and
    the seconds the command took."""
    args = [matseg, "eval", protocol, bench, "--model", "default", "--json"]
    env = dict(os.environ, MATSEG_ENGINE=engine)
    started = time.monotonic()
    done = subprocess.run(args, env=env, check=True, capture_output=True, text=True)
    seconds = time.monotonic() - started
    report: dict[str, Any] = json.loads(done.stdout)
    if protocol != "track":
        (report,) = [m for m in report["models"] if m["model"] == "default"]
    return scores(protocol, report), seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--matseg", default="target/release/matseg", help="the matseg command (built with libtorch)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        generated_points = os.path.join(scratch, "points")
        generated_masks = os.path.join(scratch, "masks")
        for what, out, n in [("make", generated_points, "20"), ("masks", generated_masks, "12")]:
            subprocess.run([args.matseg, "bench-set", what, "--out", out, "-n", n, "--seed", "0"],
                           check=True, capture_output=True)
        runs = [
            ("points", "benchmarks/real-dev", "real-dev"),
            ("points", generated_points, "generated points"),
            ("masks", "benchmarks/real-masks", "real-masks"),
            ("clicks", "benchmarks/real-masks", "real-masks"),
            ("masks", generated_masks, "generated masks"),
        ]
        if os.path.isdir("benchmarks/video-gen/data"):
            runs.append(("track", "benchmarks/video-gen/data", "video-gen"))
        print("| benchmark | protocol | score | rust | libtorch | difference | rust s | libtorch s |")
        print("|---|---|---|---|---|---|---|---|")
        worst = 0.0
        for protocol, bench, name in runs:
            (ours, our_s), (theirs, their_s) = (evaluate(args.matseg, e, protocol, bench) for e in ENGINES)
            for score in ours:
                difference = abs(ours[score] - theirs[score])
                if score != "NoC@85":
                    worst = max(worst, difference)
                print(f"| {name} | {protocol} | {score} | {ours[score]:.4f} | {theirs[score]:.4f} "
                      f"| {difference:.4f} | {our_s:.0f} | {their_s:.0f} |", flush=True)
        print(f"\nlargest difference of an accuracy or IoU: {worst:.4f}\n", flush=True)
        # The descriptors themselves, cell by cell, on every photo scored.
        folders = [os.path.abspath(f) for f in ["benchmarks/real-dev/images", "benchmarks/real-masks",
                                                  generated_points, generated_masks]]
        maps = subprocess.run(["cargo", "bench", "--quiet", "-p", "matseg-infer", "--bench", "maps", "--", *folders],
                              check=True, capture_output=True, text=True)
        print(maps.stdout.replace(scratch + os.sep, "").replace(os.getcwd() + os.sep, ""))
        if worst >= 0.0005:
            sys.exit("the engines' scores differ at the third decimal")


if __name__ == "__main__":
    main()
