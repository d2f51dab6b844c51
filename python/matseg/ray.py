"""Generating a dataset on a Ray cluster: the dataset's jobs (as `matseg
generate --num-shards K --shard-index I`) run as Ray tasks, each writing
its samples or shards into the shared output folder. Resumable: a job
skips the samples already complete, so rerunning after a failure only
makes what is missing. The output is byte for byte what one `matseg
generate` process writes.

    python -m matseg.ray generate --out /shared/data -n 100000 --num-shards 64 --address auto
"""

import argparse
import sys
import time
from collections.abc import Sequence
from typing import Any


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    """The arguments of `python -m matseg.ray`."""
    p = argparse.ArgumentParser(prog="python -m matseg.ray", description="matseg on a Ray cluster.")
    sub = p.add_subparsers(dest="command", required=True)
    g = sub.add_parser("generate", help="write a dataset as Ray tasks")
    g.add_argument("--out", required=True, help="output folder (shared by the cluster's nodes)")
    g.add_argument("-n", "--samples", type=int, required=True, help="samples in the whole dataset")
    g.add_argument("--kind", default="2d", choices=["2d", "3d"])
    g.add_argument("--seed", type=int, default=0)
    g.add_argument("--sources", nargs="+", help="photo folders (default: corpus, else bundled)")
    g.add_argument("--textures", nargs="+", help="texture folders (2d)")
    g.add_argument("--materials", nargs="+", help="PBR material folders (3d)")
    g.add_argument("--meshes", nargs="+", help="mesh files or folders (3d)")
    g.add_argument("--hdris", nargs="+", help="HDRI files or folders (3d)")
    g.add_argument("--recipe", help="TOML recipe (docs/recipe.md)")
    g.add_argument("--size", type=int, help="image side (3d)")
    g.add_argument("--spp", type=int, help="samples per pixel (3d)")
    g.add_argument("--format", default="folders", choices=["folders", "wds"])
    g.add_argument("--shard-size", type=int, default=1000, help="samples per tar shard (wds)")
    g.add_argument("--num-shards", type=int, required=True, help="jobs to split the dataset into")
    g.add_argument("--cpus-per-task", type=int, default=1, help="CPUs (and threads) of each job")
    g.add_argument("--address", default="auto",
                   help="Ray cluster: auto (the running one), local (start one here), or ray://HOST:PORT")
    g.add_argument("--num-cpus", type=int, help="CPUs of a local cluster (--address local)")
    return p.parse_args(argv)


def generator_args(args: argparse.Namespace) -> dict[str, Any]:
    """The `matseg.Generator` keyword arguments the command line gives."""
    return dict(kind=args.kind, sources=args.sources, seed=args.seed, recipe=args.recipe,
                samples=args.samples, textures=args.textures, materials=args.materials,
                meshes=args.meshes, hdris=args.hdris, size=args.size, spp=args.spp)


def run_job(gen_args: dict[str, Any], out: str, format: str, shard_size: int, num_shards: int,
            index: int) -> tuple[int, dict[str, int]]:
    """One job, in a Ray worker: job `index` of `num_shards`."""
    import matseg

    report = matseg.Generator(**gen_args).write(
        out, format=format, shard_size=shard_size, num_shards=num_shards, shard_index=index)
    return index, report


def generate(args: argparse.Namespace) -> None:
    """`python -m matseg.ray generate`: the dataset's jobs spread over the cluster's workers."""
    import ray

    import matseg

    if args.num_shards < 1:
        raise SystemExit("--num-shards: at least 1")
    # Checks the sources and recipe here, before any task starts.
    matseg.Generator(**generator_args(args))
    env = {"env_vars": {"RAYON_NUM_THREADS": str(args.cpus_per_task)}}
    if args.address == "local":
        ray.init(num_cpus=args.num_cpus, runtime_env=env, include_dashboard=False)
    else:
        ray.init(address=args.address, runtime_env=env)
    task = ray.remote(num_cpus=args.cpus_per_task, max_retries=2)(run_job)
    started = time.perf_counter()
    pending = [task.remote(generator_args(args), args.out, args.format, args.shard_size, args.num_shards, i)
               for i in range(args.num_shards)]
    totals = {"generated": 0, "skipped": 0, "bytes": 0}
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            index, report = ray.get(done[0])
            for k in totals:
                totals[k] += report[k]
            print(f"job {index}: {report['generated']} generated, {report['skipped']} already complete", flush=True)
    finally:
        ray.shutdown()
    seconds = time.perf_counter() - started
    print(f"{args.out}: {totals['generated']} samples generated, {totals['skipped']} already complete, "
          f"{totals['bytes'] / 1e6:.1f} MB in {seconds:.1f} s "
          f"({totals['generated'] / max(seconds, 1e-9):.1f} samples/s) by {args.num_shards} Ray tasks", flush=True)


def main(argv: Sequence[str] | None = None) -> None:
    """`python -m matseg.ray`: parses `argv` (default: the command line) and runs the command."""
    args = parse_args(sys.argv[1:] if argv is None else argv)
    if args.command == "generate":
        generate(args)


if __name__ == "__main__":
    main()
