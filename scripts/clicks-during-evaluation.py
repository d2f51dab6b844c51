"""Click latency of a `matseg serve` build while the evaluate page's
evaluation of a point benchmark runs, for builds that `matseg bench-serve
--while-evaluating` cannot measure (older ones, which print no token).

    python3 scripts/clicks-during-evaluation.py MATSEG [idle|eval] [BENCH]

Starts MATSEG serve on five bundled photos and BENCH (default:
benchmarks/real-dev), describes two photos, starts the evaluation (the
model and the rgb, lab, texture, position baselines) unless `idle`, clicks
the two described photos one after the other for 10 s, then clicks three
new photos once each; prints the clicks' round trips and where the
evaluation stands.
"""
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main() -> None:
    binary, mode = sys.argv[1], sys.argv[2]
    bench = sys.argv[3] if len(sys.argv) > 3 else os.path.join(ROOT, "benchmarks/real-dev")
    with tempfile.TemporaryDirectory() as photos:
        bundled = os.path.join(ROOT, "assets/photos")
        names = sorted(n for n in os.listdir(bundled) if n.endswith(".jpg"))[:5]
        for name in names:
            shutil.copy(os.path.join(bundled, name), photos)
        server = subprocess.Popen(
            [binary, "serve", "--json", "--port", "0", "--data", photos, "--bench", bench],
            stdout=subprocess.PIPE,
        )
        try:
            measure(server, names, mode, binary)
        finally:
            server.terminate()
            server.wait()


def measure(server: subprocess.Popen, names: list, mode: str, binary: str) -> None:
    ready = json.loads(server.stdout.readline())
    base, token = "http://" + ready["address"], ready.get("token")

    def call(path: str, method: str = "GET") -> tuple:
        request = urllib.request.Request(base + path, method=method)
        if token:
            request.add_header("x-matseg-token", token)
        if method == "POST":
            request.add_header("content-type", "application/json")
        started = time.time()
        body = urllib.request.urlopen(request).read()
        return (time.time() - started) * 1e3, body

    def click(name: str, x: int, y: int) -> float:
        return call(f"/api/similarity?root=data0&path={name}&points={x},{y}")[0]

    for name in names[:2]:
        click(name, 50, 50)
    if mode == "eval":
        call("/api/evaluate?root=bench0&baselines=rgb,lab,texture,position", "POST")
        time.sleep(2)
    warm, started = [], time.time()
    while time.time() - started < 10:
        warm.append(click(names[len(warm) % 2], 60 + len(warm) % 100, 70))
    seconds = time.time() - started
    first = [click(name, 50, 50) for name in names[2:5]]
    state = json.loads(call("/api/evaluate?root=bench0")[1])["state"]
    warm.sort()
    print(
        f"{binary} {mode}: clicks on described photos: median {statistics.median(warm):.1f} ms, "
        f"99th percentile {warm[max(0, int(0.99 * len(warm)) - 1)]:.1f} ms, longest {warm[-1]:.0f} ms "
        f"({len(warm)} clicks in {seconds:.1f} s); first click on three new photos: "
        f"{', '.join(f'{f:.0f}' for f in first)} ms; the evaluation at the end: {state}"
    )


if __name__ == "__main__":
    main()
