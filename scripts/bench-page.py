#!/usr/bin/env python3
"""Click-to-picture time of `matseg serve`'s segment page in a real browser.

    .venv/bin/python scripts/bench-page.py [--matseg PROGRAM] [--pages DIR]
        [--photo FILE] [--megapixels 1.5] [--window 1920x1080] [--clicks 20]
        [--warm 2] [--profile] [--json]

Writes FILE (default: the bundled coffee photo) scaled to the given
megapixels as a JPEG into a temporary folder, starts `PROGRAM serve --json
--port 0 --data FOLDER` (default: the release build in target/ or
$CARGO_TARGET_DIR), opens the segment page on it in the project's headless
Chromium (.venv/chromium/chromium, or $MATSEG_CHROMIUM) with a window of
the given size, and once the photo is described clicks it `--clicks` times
(after `--warm` clicks not counted), each click alone on a point of a grid
over the photo (Esc clears the previous one first, and the page is let
settle). For each click it measures, in the page's own clock:

- mouse-down: the `mousedown` event's time stamp (when the browser took
  the press);
- answered: when the page marks the canvas answered (`data-answered`,
  which the page sets in the same task as it draws the answer);
- painted: the end of the first frame after that (a task posted from that
  frame's requestAnimationFrame callback, which runs once the frame's
  style, layout and paint are done);

and prints the median and the slowest of mouse-down to painted, and of
mouse-down to answered, with the server's own time of the click
(`Server-Timing` of the page's `/api/select` requests, from the browser's
resource timing), the Chromium version, the photo's size and the window's.

`--pages DIR` serves the pages from DIR (a copy of
crates/matseg-serve/src/static, e.g. an older commit's, taken with
`git archive`) instead of those built into the server, so that two
versions of the pages can be compared with one server build.
`--profile` samples the page's JavaScript during the counted clicks
(DevTools' CPU profiler) and prints the functions that took the most time.

The browser is driven over the DevTools protocol through a pipe
(`--remote-debugging-pipe`); Pillow (scripts/python-env.sh) scales the
photo; nothing else beyond the standard library.
"""

import argparse
import base64
import fcntl
import json
import os
import queue
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from PIL import Image

ROOT = Path(__file__).resolve().parent.parent

# What the page is given before its own scripts run: the times of each
# mouse-down, and for each answer the time it was marked and the end of
# the frame it is painted in.
INSTRUMENT = """
window.__bench = { down: null, answers: [] };
addEventListener("mousedown", (event) => { window.__bench.down = event.timeStamp; }, true);
new MutationObserver(() => {
  const answered = performance.now();
  const down = window.__bench.down;
  requestAnimationFrame(() => {
    const frame = performance.now();
    const channel = new MessageChannel();
    channel.port1.onmessage = () => {
      window.__bench.answers.push({ down, answered, frame, painted: performance.now() });
    };
    channel.port2.postMessage(0);
  });
}).observe(document, { subtree: true, attributes: true, attributeFilter: ["data-answered"] });
"""


class Browser:
    """A headless Chromium driven over the DevTools protocol's pipe."""

    def __init__(self, program: str, width: int, height: int, profile: str):
        to_browser_read, self._write = os.pipe()
        self._read, from_browser_write = os.pipe()

        def descriptors() -> None:
            # The browser reads commands on fd 3 and writes on fd 4.
            a = fcntl.fcntl(to_browser_read, fcntl.F_DUPFD, 10)
            b = fcntl.fcntl(from_browser_write, fcntl.F_DUPFD, 10)
            os.dup2(a, 3)
            os.dup2(b, 4)

        self.process = subprocess.Popen(
            [
                program,
                "--no-sandbox",
                "--disable-gpu",
                "--hide-scrollbars",
                "--remote-debugging-pipe",
                f"--window-size={width},{height}",
                f"--user-data-dir={profile}",
                "about:blank",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            # No thread of this process runs yet (the reader starts after).
            pass_fds=(3, 4),
            preexec_fn=descriptors,  # noqa: PLW1509
        )
        os.close(to_browser_read)
        os.close(from_browser_write)
        self._next = 0
        self._answers: dict[int, queue.Queue] = {}
        self._lock = threading.Lock()
        self.handlers: dict[str, callable] = {}
        self.errors: list[str] = []
        threading.Thread(target=self._reader, daemon=True).start()
        self.session = None
        target = self.send("Target.createTarget", {"url": "about:blank"})
        attached = self.send(
            "Target.attachToTarget", {"targetId": target["targetId"], "flatten": True}
        )
        self.session = attached["sessionId"]
        self.send("Runtime.enable")
        self.send("Page.enable")
        self.send(
            "Emulation.setDeviceMetricsOverride",
            {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False},
        )

    def _reader(self) -> None:
        buffer = b""
        while True:
            chunk = os.read(self._read, 1 << 20)
            if not chunk:
                return
            buffer += chunk
            while b"\0" in buffer:
                message, buffer = buffer.split(b"\0", 1)
                answer = json.loads(message)
                if "id" in answer:
                    with self._lock:
                        waiting = self._answers.pop(answer["id"], None)
                    if waiting:
                        waiting.put(answer)
                elif answer.get("method") == "Runtime.exceptionThrown":
                    self.errors.append(
                        json.dumps(answer["params"]["exceptionDetails"])[:500]
                    )
                elif answer.get("method") in self.handlers:
                    self.handlers[answer["method"]](answer["params"])

    def post(self, method: str, params: dict | None = None) -> queue.Queue:
        """Sends a command to the page (or the browser before one is open)."""
        with self._lock:
            self._next += 1
            waiting = self._answers[self._next] = queue.Queue()
            message = {"id": self._next, "method": method, "params": params or {}}
        if self.session:
            message["sessionId"] = self.session
        os.write(self._write, json.dumps(message).encode() + b"\0")
        return waiting

    def send(
        self, method: str, params: dict | None = None, timeout: float = 120
    ) -> dict:
        answer = self.post(method, params).get(timeout=timeout)
        if "error" in answer:
            raise RuntimeError(f"{method}: {answer['error']}")
        return answer["result"]

    def eval(self, script: str, timeout: float = 120):
        result = self.send(
            "Runtime.evaluate",
            {"expression": script, "returnByValue": True, "awaitPromise": True},
            timeout,
        )
        if "exceptionDetails" in result:
            raise RuntimeError(f"{script}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def wait_for(self, script: str, seconds: float = 120) -> None:
        started = time.time()
        while not self.eval(f"Boolean({script})"):
            if self.errors:
                raise RuntimeError(f"JavaScript error on the page: {self.errors[0]}")
            if time.time() - started > seconds:
                status = self.eval("document.getElementById('status')?.textContent")
                raise RuntimeError(
                    f"timed out waiting for {script}; the page says {status!r}"
                )
            time.sleep(0.02)

    def mouse(self, x: float, y: float, button: str = "left") -> None:
        for kind in ("mousePressed", "mouseReleased"):
            self.send(
                "Input.dispatchMouseEvent",
                {"type": kind, "x": x, "y": y, "button": button, "clickCount": 1},
            )

    def key(self, key: str, code: int) -> None:
        for kind in ("rawKeyDown", "keyUp"):
            self.send(
                "Input.dispatchKeyEvent",
                {"type": kind, "key": key, "windowsVirtualKeyCode": code},
            )

    def close(self) -> None:
        self.process.kill()
        self.process.wait()


def serve_pages_from(browser: Browser, folder: Path, base: str) -> None:
    """Answers the server's page requests (not its API) with DIR's files."""
    kinds = {
        ".html": "text/html; charset=utf-8",
        ".js": "text/javascript; charset=utf-8",
        ".css": "text/css; charset=utf-8",
        ".svg": "image/svg+xml",
        ".png": "image/png",
    }

    def paused(params: dict) -> None:
        path = params["request"]["url"][len(base) :].split("?")[0].lstrip("/")
        if path.startswith("api/"):
            browser.post("Fetch.continueRequest", {"requestId": params["requestId"]})
            return
        name = path or "index.html"
        file = folder / name if (folder / name).is_file() else folder / f"{name}.html"
        if not file.is_file():
            browser.post(
                "Fetch.fulfillRequest",
                {"requestId": params["requestId"], "responseCode": 404},
            )
            return
        browser.post(
            "Fetch.fulfillRequest",
            {
                "requestId": params["requestId"],
                "responseCode": 200,
                "responseHeaders": [
                    {
                        "name": "content-type",
                        "value": kinds.get(file.suffix, "text/plain"),
                    }
                ],
                "body": base64.b64encode(file.read_bytes()).decode(),
            },
        )

    browser.handlers["Fetch.requestPaused"] = paused
    browser.send(
        "Fetch.enable",
        {"patterns": [{"urlPattern": f"{base}/*", "requestStage": "Request"}]},
    )


def default_matseg() -> str:
    for target in (os.environ.get("CARGO_TARGET_DIR"), ROOT / "target"):
        if target and (Path(target) / "release/matseg").is_file():
            return str(Path(target) / "release/matseg")
    sys.exit(
        "no release build of matseg: cargo build --release -p matseg-cli, or --matseg PROGRAM"
    )


def top_functions(profile: dict, count: int = 15) -> list[tuple[str, float]]:
    """The functions that took the most time in a CPU profile (self time)."""
    nodes = {node["id"]: node for node in profile["nodes"]}
    spent: dict[str, float] = {}
    deltas = profile["timeDeltas"]
    for sample, delta in zip(profile["samples"], deltas[1:] + [0]):
        frame = nodes[sample]["callFrame"]
        name = frame["functionName"] or "(anonymous)"
        where = (
            f"{name} {Path(frame['url']).name}:{frame['lineNumber'] + 1}"
            if frame["url"]
            else name
        )
        spent[where] = spent.get(where, 0) + delta / 1000
    return sorted(spent.items(), key=lambda item: -item[1])[:count]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument("--matseg")
    parser.add_argument("--pages", type=Path)
    parser.add_argument("--photo", type=Path, default=ROOT / "assets/photos/coffee.jpg")
    parser.add_argument("--megapixels", type=float, default=1.5)
    parser.add_argument("--window", default="1920x1080")
    parser.add_argument("--clicks", type=int, default=20)
    parser.add_argument("--warm", type=int, default=2)
    parser.add_argument("--profile", action="store_true")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    width, height = map(int, args.window.split("x"))
    matseg = args.matseg or default_matseg()
    chromium = os.environ.get("MATSEG_CHROMIUM", str(ROOT / ".venv/chromium/chromium"))
    version = subprocess.run(
        [chromium, "--version"], capture_output=True, text=True, check=True
    ).stdout.strip()

    with (
        tempfile.TemporaryDirectory() as folder,
        tempfile.TemporaryDirectory() as profile,
    ):
        photo = Image.open(args.photo).convert("RGB")
        scale = (args.megapixels * 1e6 / (photo.width * photo.height)) ** 0.5
        photo = photo.resize(
            (round(photo.width * scale), round(photo.height * scale)), Image.LANCZOS
        )
        photo.save(Path(folder) / "photo.jpg", quality=92)
        server = subprocess.Popen(
            [matseg, "serve", "--json", "--port", "0", "--data", folder],
            stdout=subprocess.PIPE,
        )
        browser = None
        try:
            ready = json.loads(server.stdout.readline())
            base = f"http://{ready['address']}"
            browser = Browser(chromium, width, height, profile)
            if args.pages:
                serve_pages_from(browser, args.pages, base)
            browser.send(
                "Page.addScriptToEvaluateOnNewDocument", {"source": INSTRUMENT}
            )
            browser.send(
                "Page.navigate",
                {"url": f"{base}/?root=data0&path=photo.jpg&token={ready['token']}"},
            )
            browser.wait_for(
                "document.getElementById('canvas')?.dataset.described === '1'", 300
            )
            times = measure(browser, photo.size, args)
        finally:
            if browser:
                browser.close()
            server.terminate()
            server.wait()

    painted = [t["painted"] for t in times["clicks"]]
    answered = [t["answered"] for t in times["clicks"]]
    sent = [t["sent"] for t in times["clicks"] if "sent" in t]
    received = [t["received"] for t in times["clicks"] if "received" in t]
    server_ms = times["server"]
    result = {
        "chromium": version,
        "photo": f"{photo.width}x{photo.height}",
        "megapixels": round(photo.width * photo.height / 1e6, 3),
        "window": args.window,
        "clicks": len(painted),
        "painted_median_ms": round(statistics.median(painted), 1),
        "painted_max_ms": round(max(painted), 1),
        "answered_median_ms": round(statistics.median(answered), 1),
        "answered_max_ms": round(max(answered), 1),
        "sent_median_ms": round(statistics.median(sent), 1) if sent else None,
        "received_median_ms": round(statistics.median(received), 1)
        if received
        else None,
        "server_median_ms": round(statistics.median(server_ms), 1)
        if server_ms
        else None,
        "server_max_ms": round(max(server_ms), 1) if server_ms else None,
        "painted_ms": [round(p, 1) for p in painted],
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(
            f"{version}; photo {result['photo']} ({result['megapixels']} MP); window {args.window}; "
            f"{len(painted)} clicks"
        )
        print(
            f"mouse-down to painted:  median {result['painted_median_ms']} ms, slowest {result['painted_max_ms']} ms"
        )
        print(
            f"mouse-down to answered: median {result['answered_median_ms']} ms, slowest {result['answered_max_ms']} ms"
        )
        if sent:
            print(
                f"mouse-down to the request sent: median {result['sent_median_ms']} ms; "
                f"to its answer received: median {result['received_median_ms']} ms"
            )
        if server_ms:
            print(
                f"server (Server-Timing): median {result['server_median_ms']} ms, slowest {result['server_max_ms']} ms"
            )
        print("each click, painted (ms):", " ".join(f"{p:.0f}" for p in painted))
    if times.get("profile"):
        print("JavaScript self time during the counted clicks (ms):")
        for name, ms in times["profile"]:
            print(f"  {ms:8.1f}  {name}")


def measure(browser: Browser, size: tuple[int, int], args) -> dict:
    """Clicks the photo: each click's times, the server's, the profile."""
    width, height = size
    total = args.warm + args.clicks
    columns = 5
    rows = (total + columns - 1) // columns
    grid = [
        (
            int(width * (0.1 + 0.8 * (i % columns) / (columns - 1))),
            int(height * (0.1 + 0.8 * (i // columns) / max(1, rows - 1))),
        )
        for i in range(total)
    ]
    clicks = []
    server = []
    for n, (x, y) in enumerate(grid):
        if n == args.warm and args.profile:
            browser.send("Profiler.enable")
            browser.send("Profiler.setSamplingInterval", {"interval": 200})
            browser.send("Profiler.start")
        # Cleared, and let settle: no click, the busy mark gone, two frames.
        browser.key("Escape", 27)
        browser.wait_for(
            "document.getElementById('canvas').dataset.clicks === '0'"
            " && !document.getElementById('view').classList.contains('busy')"
        )
        browser.eval(
            "new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done)))"
        )
        browser.eval(
            "performance.clearResourceTimings(); window.__bench.answers.length = 0"
        )
        at = browser.eval(f"""(() => {{ const c = document.getElementById('canvas');
            const b = c.getBoundingClientRect();
            return [b.left + ({x} + 0.5) * b.width / c.width, b.top + ({y} + 0.5) * b.height / c.height]; }})()""")
        browser.mouse(at[0], at[1])
        browser.wait_for("window.__bench.answers.length > 0", 60)
        answer = browser.eval("window.__bench.answers[0]")
        requests = (
            browser.eval("""performance.getEntriesByType('resource')
            .filter((e) => e.name.includes('/api/select?'))
            .map((e) => ({ server: (e.serverTiming.find((t) => t.name === 'app') || {}).duration,
                           sent: e.startTime, received: e.responseEnd }))""")
            or []
        )
        if n >= args.warm:
            down = answer["down"]
            clicks.append(
                {
                    "painted": answer["painted"] - down,
                    "answered": answer["answered"] - down,
                }
            )
            if requests:
                # The click's own request: the last one asked.
                clicks[-1]["sent"] = requests[-1]["sent"] - down
                clicks[-1]["received"] = requests[-1]["received"] - down
            server.extend(r["server"] for r in requests if r["server"] is not None)
    result = {"clicks": clicks, "server": server}
    if args.profile:
        result["profile"] = top_functions(browser.send("Profiler.stop")["profile"])
    return result


if __name__ == "__main__":
    main()
