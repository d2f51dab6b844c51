"""Training the matseg net with PyTorch, on one process or many under
torchrun (DistributedDataParallel: gloo on CPUs, nccl on GPUs). It reads
the same batches as `matseg train` (online 2D scenes or a stored dataset,
the same batch plan, or a feature cache of `matseg features`) and writes
the same run folder (run.json,
model.safetensors, metrics.jsonl, checkpoint.safetensors), which `matseg
segment`, `matseg eval` and `matseg serve` load. `--resume RUN` continues
a run from its last checkpoint, its own or `matseg train`'s, with the next
batch of the stream; `matseg train --resume` continues this trainer's runs
of one process.

    python -m matseg.train --out runs/a --steps 2000
    python -m matseg.train --out runs/b --features CACHE --steps 8000
    torchrun --nproc_per_node 8 -m matseg.train --out runs/a --data DATA --device cuda
    torchrun --nproc_per_node 8 -m matseg.train --resume runs/a --device cuda
"""

from . import _requires

_requires.torch("python -m matseg.train")

import argparse
import hashlib
import json
import os
import shutil
import sys
import time
from collections.abc import Sequence
from typing import IO, Any

import torch
import torch.distributed as dist
from torch import Tensor
from torch.nn.parallel import DistributedDataParallel
from torch.utils.data import DataLoader

from . import _core, checkpoint
from . import net as netlib
from .data import BatchPlan, Dataset, FeatureCache, Generator
from .streams import BatchStream, FeatureStream

DEFAULTS = _core.train_defaults()
METRICS_FILE = netlib.CONSTANTS["metrics_file"]
PLOT_FILE = netlib.CONSTANTS["plot_file"]
BEST_MODEL_FILE = netlib.CONSTANTS["best_model_file"]


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    """The arguments of `python -m matseg.train`."""
    p = argparse.ArgumentParser(prog="python -m matseg.train", description=__doc__.split("\n\n")[0])
    p.add_argument("--out", help="run folder to write (a new one)")
    p.add_argument("--resume", metavar="RUN",
                   help="continue RUN from its last checkpoint, with its own settings (a run of "
                        "python -m matseg.train or matseg train)")
    p.add_argument("--data", help="stored dataset (folders or shards); default: online 2D scenes")
    p.add_argument("--features", metavar="CACHE",
                   help="a feature cache (matseg features): the encoder stays frozen and the rest of "
                        "the net trains on the cached taps, with the loss on the stride-4 grid")
    p.add_argument("--mix-data", metavar="DIR",
                   help="a stored dataset (e.g. matseg generate --kind 3d renders) mixed into the training data")
    p.add_argument("--mix-fraction", type=float, default=DEFAULTS["mix_fraction"],
                   help="the share of samples taken from --mix-data")
    p.add_argument("--sources", nargs="+", help="photo folders of the online scenes (default: corpus, else bundled)")
    p.add_argument("--textures", nargs="+", help="texture folders of the online scenes")
    p.add_argument("--init",
                   help="initial weights: default (the shipped model), a run folder or weights file, or "
                        "scratch; with --features, the cache's model unless given (it must be the "
                        "cache's encoder). Default: default")
    p.add_argument("--encoder", default=DEFAULTS["encoder"], help="encoder preset (with --init scratch)")
    p.add_argument("--steps", type=int, default=DEFAULTS["steps"], help="batches per process")
    p.add_argument("--lr", type=float, help="peak learning rate (default: matseg train's for the init)")
    p.add_argument("--warmup", type=int, default=DEFAULTS["warmup"], help="steps of linear warm-up")
    p.add_argument("--decay", type=int, default=0, help="final steps of linear fall to 0")
    p.add_argument("--seed", type=int, default=0, help="batch stream seed")
    p.add_argument("--max-side", type=int, help="largest batch side (multiple of 32)")
    p.add_argument("--min-side", type=int, help="smallest batch side (multiple of 32)")
    p.add_argument("--batch-pixels", type=int, help="pixels per batch to aim at")
    p.add_argument("--checkpoint-every", type=int, default=DEFAULTS["checkpoint_every"],
                   help="steps between checkpoints and validations")
    p.add_argument("--validation-batches", type=int, default=DEFAULTS["validation_batches"],
                   help="held-out generated batches per validation (0: none)")
    p.add_argument("--val-points", metavar="BENCH",
                   help="a point benchmark (MatSeg layout) to score each checkpoint on (val_points in the "
                        "metrics; the best checkpoint's weights in best.safetensors); also with --resume")
    p.add_argument("--val-max-side", type=int, default=DEFAULTS["val_max_side"],
                   help="longer side of the --val-points photos, in pixels (0: as they are)")
    p.add_argument("--workers", type=int, default=2, help="DataLoader workers per process")
    p.add_argument("--device", default="cpu", help="cpu or cuda")
    args = p.parse_args(argv)
    if (args.out is None) == (args.resume is None):
        p.error("give --out RUN for a new run or --resume RUN")
    if args.features and (args.data or args.mix_data):
        p.error("--features: a run on a feature cache takes its data from the cache")
    return args


class FromTaps(torch.nn.Module):
    """The net after its encoder, as one module (what DDP wraps in a run on
    cached features): unit descriptors on the stride-4 grid of the taps."""

    def __init__(self, net: netlib.MaterialNet) -> None:
        super().__init__()
        self.net = net

    def forward(self, taps: Sequence[Tensor], lab: Tensor | None) -> Tensor:
        """Unit descriptors of the encoder's taps and the cells' L*a*b* colours."""
        return netlib.l2_normalise(self.net.coarse_from_taps(taps, lab))


def check_cache_encoder(net: netlib.MaterialNet, run: dict[str, Any]) -> None:
    """Refuses a run on a feature cache whose net's encoder did not make it."""
    manifest = run["features"]["manifest"]
    where = os.path.join(run["features"]["cache"], "cache.json")
    if net.config["encoder"] != manifest["encoder"]:
        raise SystemExit(f"{where}: made by another encoder ({manifest['encoder']}) than this run's "
                         f"({net.config['encoder']})")
    if netlib.encoder_digest(net) != manifest["encoder_digest"]:
        raise SystemExit(f"{where}: made by the encoder of {manifest['model']}, whose weights differ from "
                         f"those of {run['init']}: start from the cache's model (--init cache)")


def open_cache(run: dict[str, Any]) -> FeatureCache:
    """The feature cache of a run on one, checked to be the one it started on."""
    cache = FeatureCache(run["features"]["cache"])
    what = cache.difference(run["features"]["manifest"])
    if what is not None:
        raise SystemExit(f"{os.path.join(cache.root, 'cache.json')}: is not the cache this run started "
                         f"on ({what} differs)")
    return cache


def param_groups(net: torch.nn.Module, lr_scales: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One group per learning-rate factor (later prefixes win, as matseg train)."""
    groups: dict[float, list[object]] = {}
    for name, p in net.named_parameters():
        scale = 1.0
        for rule in lr_scales:
            if name.startswith(rule["prefix"]):
                scale = rule["scale"]
        groups.setdefault(scale, []).append(p)
    return [{"params": ps, "scale": s} for s, ps in groups.items()]


def state_digest(net: torch.nn.Module) -> str:
    """SHA-256 of the stored variables (model.safetensors'), in name order:
    equal on every rank."""
    h = hashlib.sha256()
    for name, a in sorted(netlib.state_arrays(net).items()):
        h.update(name.encode())
        h.update(a.tobytes())
    return h.hexdigest()


def initial_net(args: argparse.Namespace, init: str) -> tuple[netlib.MaterialNet, dict[str, Any]]:
    """The net to start from (`init`) and the run.json fields it carries over."""
    if init == "scratch":
        config = json.loads(_core.net_preset(args.encoder, False, False))
        return netlib.MaterialNet(config), {"lr_scales": []}
    net, run = netlib.load(init)
    carried = {"lr_scales": run["options"].get("lr_scales", [])}
    for key in ("inference_side", "extra_inference_sides"):
        if key in run:
            carried[key] = run[key]
    return net, carried


def new_run(args: argparse.Namespace) -> tuple[netlib.MaterialNet, dict[str, Any]]:
    """The net and run.json of a new run from the arguments."""
    if os.path.isfile(os.path.join(args.out, netlib.RUN_FILE)):
        raise SystemExit(f"{args.out}: already holds a run; resume it (--resume), or choose another folder")
    cache = FeatureCache(args.features) if args.features else None
    init = args.init or "default"
    if cache is not None and args.init in (None, "cache"):
        init = cache.manifest["model"]
    sizes = {"min_side": args.min_side, "max_side": args.max_side, "pixels": args.batch_pixels}
    if cache is not None:
        # The batches are the cache's samples: the plan keeps their size.
        sides = (cache.manifest["width"], cache.manifest["height"])
        sizes.update(min_side=min(sides), max_side=max(sides))
    plan = BatchPlan(**{**BatchPlan.default().__dict__, **{k: v for k, v in sizes.items() if v is not None}})
    net, carried = initial_net(args, init)
    pretrained = init != "scratch"
    options = {
        "steps": args.steps,
        "lr": args.lr if args.lr is not None else DEFAULTS["lr_pretrained" if pretrained else "lr_scratch"],
        "warmup": args.warmup, "decay": args.decay, "weight_decay": DEFAULTS["weight_decay"],
        "plan": json.loads(plan.to_json()), "seed": args.seed,
        "checkpoint_every": args.checkpoint_every, "validation_batches": args.validation_batches,
        "lr_scales": carried.pop("lr_scales"),
    }
    run = {"net": net.config, "options": options, "init": init,
           "data": os.path.abspath(args.data) if args.data else "online", **carried}
    if cache is not None:
        # The encoder made the cache: it stays as it is.
        options["lr_scales"].append({"prefix": "encoder.", "scale": 0.0})
        run["features"] = {"cache": os.path.abspath(cache.root), "manifest": cache.manifest}
        run["data"] = cache.manifest["data"]
        check_cache_encoder(net, run)
    if args.mix_data:
        if not 0.0 <= args.mix_fraction <= 1.0:
            raise SystemExit(f"--mix-fraction {args.mix_fraction}: not in 0..1")
        run["mix"] = {"data": os.path.abspath(args.mix_data), "fraction": args.mix_fraction}
    return net, run


def resumed_run(folder: str) -> tuple[netlib.MaterialNet, dict[str, Any]]:
    """The net (weights still to load) and run.json of the run in `folder`."""
    path = os.path.join(folder, netlib.RUN_FILE)
    if not os.path.isfile(path):
        raise SystemExit(f"{path}: no such file: not a run folder")
    with open(path) as f:
        run = json.load(f)
    return netlib.MaterialNet(run["net"]), run


def batch_stream(run: dict[str, Any], args: argparse.Namespace,
                 first_batch: int) -> BatchStream | FeatureStream:
    """The run's batches from `first_batch` on: from its feature cache, its
    stored dataset or online 2D scenes of the run's seed (and
    --sources/--textures), with its mixed-in dataset."""
    options = run["options"]
    if "features" in run:
        return FeatureStream(open_cache(run), BatchPlan(**options["plan"]), options["seed"],
                             first_step=first_batch)
    source: Dataset | Generator
    if run["data"] != "online":
        source = Dataset(run["data"])
    else:
        source = Generator("2d", args.sources, textures=args.textures, seed=options["seed"])
    mix = (Dataset(run["mix"]["data"]), run["mix"]["fraction"]) if "mix" in run else None
    return BatchStream(source, BatchPlan(**options["plan"]), options["seed"], first_step=first_batch, mix=mix)


def held_out_batches(run: dict[str, Any], args: argparse.Namespace) -> list[dict[str, Any]]:
    """matseg train's validation batches: `validation_batches` batches of
    2D scenes from a generator and a batch stream of their own seeds."""
    options = run["options"]
    count = options.get("validation_batches", 0)
    if count == 0:
        return []
    seed = options["seed"]
    scenes = Generator("2d", args.sources, textures=args.textures, seed=seed ^ DEFAULTS["validation_generator_seed"])
    stream = BatchStream(scenes, BatchPlan(**options["plan"]), seed ^ DEFAULTS["validation_seed"])
    return [stream.batch(i) for i in range(count)]


def validation_loss(net: torch.nn.Module, batches: Sequence[dict[str, Any]],
                    device: torch.device) -> float | None:
    """The mean loss of `net` in inference mode over the batches that have
    two materials or more (None when none has)."""
    net.eval()
    with torch.no_grad():
        losses = [netlib.matseg_loss(net(b["images"].to(device)), b["weights"].to(device), b["roi"].to(device))
                  for b in batches]
    net.train()
    values = [float(loss) for loss in losses if loss is not None]
    return sum(values) / len(values) if values else None


def open_metrics(folder: str, next_step: int) -> tuple[IO[str], float]:
    """metrics.jsonl of `folder` holding the records of the steps before
    `next_step` (those a resumed run keeps), open for appending, and the
    best val_points among them (-inf: none)."""
    path = os.path.join(folder, METRICS_FILE)
    kept = []
    if next_step > 0 and os.path.isfile(path):
        with open(path) as f:
            kept = [(line, r) for line in f if line.strip() for r in [json.loads(line)] if r["step"] < next_step]
    tmp = f"{path}.{os.getpid()}.tmp"
    with open(tmp, "w") as f:
        f.writelines(line for line, _ in kept)
    os.replace(tmp, path)
    best = max((r["val_points"] for _, r in kept if r.get("val_points") is not None), default=float("-inf"))
    return open(path, "a"), best


def main(argv: Sequence[str] | None = None) -> None:
    """`python -m matseg.train`: parses `argv` (default: the command line) and trains."""
    args = parse_args(sys.argv[1:] if argv is None else argv)
    world = int(os.environ.get("WORLD_SIZE", "1"))
    rank = int(os.environ.get("RANK", "0"))
    local = int(os.environ.get("LOCAL_RANK", "0"))
    if args.device == "cuda":
        device = torch.device("cuda", local)
        torch.cuda.set_device(device)
    elif args.device == "cpu":
        device = torch.device("cpu")
    else:
        raise SystemExit(f"--device: '{args.device}': expected cpu or cuda")
    # Every rank checks the folder before any of them can start training.
    net, run = resumed_run(args.resume) if args.resume else new_run(args)
    folder = args.resume or args.out
    if world > 1:
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")

    options = run["options"]
    features = "features" in run
    if features:
        # The cache's encoder stays frozen (and out of DDP's reduction).
        for p in net.encoder.parameters():
            p.requires_grad_(False)
    net = net.to(device)
    groups = param_groups(net, options.get("lr_scales", []))
    betas = tuple(DEFAULTS["betas"])
    optimizer = torch.optim.AdamW(groups, lr=options["lr"], betas=betas, eps=DEFAULTS["eps"],
                                  weight_decay=options["weight_decay"])
    updates, first_step, first_batch = checkpoint.read(folder, net, optimizer) if args.resume else (0, 0, 0)
    if features and args.resume:
        check_cache_encoder(net, run)
    if first_step >= options["steps"]:
        if rank == 0:
            print(f"{folder}: all {options['steps']} steps are trained", flush=True)
        if world > 1:
            dist.destroy_process_group()
        return
    net.train()
    module = FromTaps(net) if features else net
    device_ids = [local] if device.type == "cuda" else None
    model = DistributedDataParallel(module, device_ids=device_ids) if world > 1 else module
    loader = DataLoader(batch_stream(run, args, first_batch), batch_size=None, num_workers=args.workers,
                        persistent_workers=args.workers > 0)

    metrics, held_out, best = None, [], float("-inf")
    if rank == 0:
        os.makedirs(folder, exist_ok=True)
        metrics, best = open_metrics(folder, first_step)
        held_out = held_out_batches(run, args)
    schedule = _core.lr_schedule(json.dumps(options))
    steps = options["steps"]
    started, images = time.perf_counter(), 0
    batches = iter(loader)
    for step in range(first_step, steps):
        step_started = time.perf_counter()
        batch = next(batches)
        data_seconds = time.perf_counter() - step_started
        lr = schedule[step]
        for g in optimizer.param_groups:
            g["lr"] = lr * g["scale"]
        if features:
            taps = [t.to(device, non_blocking=True) for t in batch["taps"]]
            desc = model(taps, batch["lab"].to(device))
            count, (height, width) = taps[0].shape[0], [4 * n for n in taps[0].shape[2:]]
        else:
            x = batch["images"].to(device, non_blocking=True)
            desc = model(x)
            count, (height, width) = x.shape[0], x.shape[2:]
        loss = netlib.matseg_loss(desc, batch["weights"].to(device), batch["roi"].to(device))
        # A batch with fewer than two materials teaches nothing: one process
        # skips it, as matseg train does; under DDP every rank still takes
        # part in the gradient reduction, with a zero loss.
        skipped = loss is None
        if skipped and world > 1:
            loss = desc.sum() * 0.0
        if loss is not None:
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            updates += 1
        loss_value = None if skipped or loss is None else float(loss.detach())
        if device.type == "cuda":
            torch.cuda.synchronize(device)
        step_seconds = time.perf_counter() - step_started
        images += count
        done = step + 1
        at_checkpoint = done % options["checkpoint_every"] == 0 or done == steps
        if metrics is not None:
            # Rank 0 alone: matseg train's fields (StepMetrics), and the batch's index in the stream.
            record = {"step": step, "loss": loss_value, "lr": lr, "images": count,
                      "width": int(width), "height": int(height), "seconds": step_seconds,
                      "data_seconds": data_seconds, "batch": batch["step"]}
            if at_checkpoint:
                # The weights first: the point benchmark scores the saved run.
                arrays = netlib.state_arrays(net)
                netlib.save(net, run, folder, arrays)
                if held_out:
                    record["validation"] = validation_loss(net, held_out, device)
                if args.val_points:
                    record["val_points"] = _core.score_points(folder, args.val_points, args.val_max_side)
            metrics.write(json.dumps(record) + "\n")
            metrics.flush()
            if at_checkpoint:
                next_batch = first_batch + world * (done - first_step)
                checkpoint.write(folder, arrays, net, optimizer, updates, done, next_batch)
                if record.get("val_points", float("-inf")) > best:
                    best = record["val_points"]
                    best_path = os.path.join(folder, BEST_MODEL_FILE)
                    shutil.copyfile(os.path.join(folder, netlib.MODEL_FILE), f"{best_path}.{os.getpid()}.tmp")
                    os.replace(f"{best_path}.{os.getpid()}.tmp", best_path)
                _core.plot_losses(os.path.join(folder, METRICS_FILE), os.path.join(folder, PLOT_FILE))
    seconds = time.perf_counter() - started

    if world > 1:
        # Parameters agree after every step; BatchNorm's running statistics
        # are rank 0's, as DDP broadcasts them before each forward pass.
        for b in net.buffers():
            dist.broadcast(b, 0)
        totals = torch.tensor([images], dtype=torch.float64, device=device)
        dist.all_reduce(totals)
        images = int(totals.item())
    print(f"rank {rank}: weights sha256 {state_digest(net)}", flush=True)
    if metrics is not None:
        trained = steps - first_step
        metrics.close()
        print(f"{folder}: {trained} steps x {world} process(es), {images} images in {seconds:.1f} s "
              f"({images / max(seconds, 1e-9):.2f} images/s)", flush=True)
    if world > 1:
        dist.barrier()
        dist.destroy_process_group()


if __name__ == "__main__":
    main()
