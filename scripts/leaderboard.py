"""matseg's leaderboard: every built-in baseline, matseg's own models and
any model written in Python, scored on the real and generated benchmarks
by the same protocols, in one Markdown table.

    .venv/bin/python scripts/leaderboard.py [--out docs/leaderboard.md] [--model default]
        [--python examples/imagenet_features.py] [--matseg target/release/matseg]

The built-in baselines and `--model` runs are scored by the `matseg`
command (`matseg eval points|masks|clicks|track --json`); each `--python`
file's `model()` is scored by `matseg.evaluate`. The generated point
benchmark is made by `matseg bench-set make` into a temporary folder; the
tracking benchmark is `benchmarks/video-gen/data` when
`benchmarks/video-gen/make.sh` has made it (otherwise its column is
empty). Each row names the commands that scored it, and the page lists
them in full.
"""

import argparse
import datetime
import importlib.util
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from typing import Any

import matseg.evaluate

REAL_DEV = "benchmarks/real-dev"
REAL_MASKS = "benchmarks/real-masks"
TRACK = "benchmarks/video-gen/data"
BASELINES = ["rgb", "lab", "texture", "imagenet"]
#: The generated point benchmark's folder, in a temporary one (GENERATED
#: in the commands listed).
GENERATED_DIR = "generated-points"
COLUMNS = ["real-dev All", "real-dev Soft", "generated All", "generated Soft", "real-masks IoU",
           "clicks NoC@85", "clicks IoU@1", "track IoU"]


class Board:
    """Rows of scores by model, and the commands that made them."""

    def __init__(self) -> None:
        self.rows: dict[str, dict[str, float | None]] = {}
        self.how: dict[str, list[str]] = {}
        self.commands: list[str] = []
        #: Paths shown under another name in the commands listed.
        self.aliases: dict[str, str] = {}

    def put(self, model: str, column: str, value: float | None, how: str) -> None:
        self.rows.setdefault(model, {})[column] = value
        if how not in self.how.setdefault(model, []):
            self.how[model].append(how)

    def markdown(self, header: str) -> str:
        lines = [header, "", "| model | " + " | ".join(COLUMNS) + " | scored by |",
                 "|---|" + "---|" * (len(COLUMNS) + 1)]
        best = {column: self.best(column) for column in COLUMNS}
        for model, row in self.rows.items():
            cells = []
            for column in COLUMNS:
                value = row.get(column)
                cell = "" if value is None else f"{value:.2f}" if "NoC" in column else f"{value:.3f}"
                cells.append(f"**{cell}**" if value is not None and value == best[column] else cell)
            lines.append(f"| {model} | " + " | ".join(cells) + " | " + "; ".join(self.how[model]) + " |")
        lines += ["", "Commands, in the order they ran:", "", "```sh", *self.commands, "```", ""]
        return "\n".join(lines)


    def record(self, command: str) -> None:
        """Lists `command` (its aliased paths by their names) and shows it on stderr."""
        for path, name in self.aliases.items():
            command = command.replace(path, name)
        self.commands.append(command)
        print(command, file=sys.stderr, flush=True)

    def best(self, column: str) -> float | None:
        """The best value of `column` (the lowest for clicks needed)."""
        values = [v for row in self.rows.values() if (v := row.get(column)) is not None]
        if not values:
            return None
        return min(values) if "NoC" in column else max(values)


def cli(board: Board, matseg_bin: str, *args: str) -> dict[str, Any]:
    """`matseg eval ARGS --json`, recorded on the board."""
    board.record(" ".join(["matseg", "eval", *args, "--json"]))
    done = subprocess.run([matseg_bin, "eval", *args, "--json"], check=True, capture_output=True, text=True)
    result: dict[str, Any] = json.loads(done.stdout)
    return result


def put(board: Board, protocol: str, report: dict[str, Any], how: str, bench: str = "") -> None:
    """The scores of one model's `report` by `protocol` on the board
    (`bench` names the point benchmark's columns)."""
    model = report["model"]
    if protocol == "points":
        board.put(model, f"{bench} All", report["all_by_material"], how)
        board.put(model, f"{bench} Soft", report["soft_by_material"], how)
    elif protocol == "masks":
        board.put(model, "real-masks IoU", report["mean_iou"], how)
    elif protocol == "clicks":
        board.put(model, "clicks NoC@85", report["noc85"], how)
        board.put(model, "clicks IoU@1", report["miou_at"]["1"], how)
    else:
        board.put(model, "track IoU", report["with_memory"]["mean_iou"], how)


def built_in(board: Board, matseg_bin: str, models: list[str], generated: str) -> None:
    """The baselines and matseg's own models, by the `matseg` command."""
    chosen = ["--baseline", *BASELINES, "--model", *models] if models else ["--baseline", *BASELINES,
                                                                           "--model", "none"]

    def how(report: dict[str, Any], protocol: str) -> str:
        flag = "--baseline" if report["model"] in BASELINES else "--model"
        return f"`matseg eval {protocol} {flag} {report['model']}`"

    for bench, prefix in [(REAL_DEV, "real-dev"), (generated, "generated")]:
        for report in cli(board, matseg_bin, "points", bench, *chosen)["models"]:
            put(board, "points", report, how(report, "points"), prefix)
    for protocol in ["masks", "clicks"]:
        for report in cli(board, matseg_bin, protocol, REAL_MASKS, *chosen)["models"]:
            put(board, protocol, report, how(report, protocol))
    if os.path.isdir(TRACK):
        for model in models:
            report = cli(board, matseg_bin, "track", TRACK, "--model", model)
            put(board, "track", report, how(report, "track"))


def from_python(board: Board, path: str, generated: str) -> None:
    """The model `model()` of the file at `path` makes, by `matseg.evaluate`."""
    spec = importlib.util.spec_from_file_location("scored", path)
    if spec is None or spec.loader is None:
        raise SystemExit(f"{path}: not a Python file")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    model = module.model()
    how = f"`matseg.evaluate` on `{path}`"

    def run(protocol: Callable[..., dict[str, Any]], bench: str) -> dict[str, Any]:
        board.record(f"matseg.evaluate.{protocol.__name__}({bench!r}, model())  # {path}")
        return protocol(bench, model, progress=False)

    for bench, prefix in [(REAL_DEV, "real-dev"), (generated, "generated")]:
        put(board, "points", run(matseg.evaluate.points, bench)["models"][0], how, prefix)
    put(board, "masks", run(matseg.evaluate.masks, REAL_MASKS)["models"][0], how)
    put(board, "clicks", run(matseg.evaluate.clicks, REAL_MASKS)["models"][0], how)
    if os.path.isdir(TRACK) and getattr(model, "comparison", "cosine") == "cosine":
        put(board, "track", run(matseg.evaluate.track, TRACK), how)


#: The first lines of every page this script writes: a file at --out that
#: does not begin with them is someone else's.
OPENING = ["# Leaderboard", "",
           "Every built-in baseline, matseg's shipped model and models matseg did not train, scored by the same"]


def refuse_foreign(out: str) -> None:
    """Stops, before any work, when `out` is a folder or a file this
    script did not write."""
    if os.path.isdir(out):
        raise SystemExit(f"{out}: a folder; give --out a file name")
    if os.path.exists(out):
        opening = "\n".join(OPENING).encode()
        with open(out, "rb") as f:
            if f.read(len(opening)) != opening:
                raise SystemExit(f"{out}: not a leaderboard this script wrote; give another --out")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="docs/leaderboard.md")
    parser.add_argument("--model", action="append", default=None,
                        help="a model `matseg eval --model` takes (default: default)")
    parser.add_argument("--python", action="append", default=[],
                        help="a Python file whose model() is scored by matseg.evaluate")
    parser.add_argument("--matseg", default="target/release/matseg", help="the matseg command")
    args = parser.parse_args()
    models = args.model if args.model is not None else ["default"]
    refuse_foreign(args.out)
    board = Board()
    started = time.time()
    with tempfile.TemporaryDirectory() as scratch:
        generated = os.path.join(scratch, GENERATED_DIR)
        board.aliases = {repr(generated): "GENERATED", generated: "GENERATED"}
        board.record(f"matseg bench-set make --out {generated} -n 20 --seed 0")
        subprocess.run([args.matseg, "bench-set", "make", "--out", generated, "-n", "20", "--seed", "0"],
                       check=True, capture_output=True)
        built_in(board, args.matseg, models, generated)
        for path in args.python:
            from_python(board, path, generated)
    machine = f"{platform.machine()}, {os.cpu_count()} cores"
    header = "\n".join([
        *OPENING,
        "protocols (docs/eval.md): triplet accuracy by material (All, Soft) on `benchmarks/real-dev` and on a",
        "generated point benchmark (`matseg bench-set make -n 20 --seed 0`), mean IoU at the best threshold on",
        "`benchmarks/real-masks`, the click protocol on real-masks (NoC@85, lower is better; IoU after one",
        "click) and tracking IoU with memory on `benchmarks/video-gen` (nets and Python models that describe",
        "frames; `matseg eval track` has no baselines). Photos at longer side 700; the best of each column in",
        "bold. Written by:",
        "",
        "```sh",
        " ".join([".venv/bin/python", "scripts/leaderboard.py", *sys.argv[1:]]),
        "```",
        "",
        f"on {datetime.date.today().isoformat()} ({machine}, {(time.time() - started) / 60:.0f} minutes).",
    ])
    # Written beside the page under a name of its own, then put in its place.
    with tempfile.NamedTemporaryFile("w", dir=os.path.dirname(os.path.abspath(args.out)), prefix=".leaderboard-",
                                     suffix=".md", delete=False) as f:
        f.write(board.markdown(header))
    os.replace(f.name, args.out)
    print(f"{args.out}: {len(board.rows)} models", file=sys.stderr)


if __name__ == "__main__":
    main()
