#!/usr/bin/env python3
"""The first click on a photo of many pixels and few bytes, in `matseg serve`.

Usage: scripts/serve-black-png.py MATSEG [SIDE] [CACHE_MB]

Writes an all-black SIDE x SIDE PNG (6000 by default: 36 megapixels in
about 100 KB) into a temporary folder, starts `MATSEG serve --json --port 0
--cache-mb CACHE_MB --data FOLDER` (256 by default), asks for the selection
of a click in its middle (what the segment page asks for), and prints the
server's time for it (`Server-Timing`), the memory it holds for described
photos (`GET /api/status`) and its resident memory (VmRSS and VmHWM, MiB)
before and after. The standard library only; Linux (/proc).
"""

import json
import struct
import subprocess
import sys
import tempfile
import urllib.request
import zlib
from pathlib import Path


def black_png(path: Path, side: int) -> None:
    row = b"\x00" + bytes(3 * side)
    raw = zlib.compress(row * side, 9)

    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = zlib.crc32(kind + data) & 0xFFFFFFFF
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)

    header = struct.pack(">IIBBBBB", side, side, 8, 2, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", raw) + chunk(b"IEND", b"")
    )


def memory_mib(pid: int) -> tuple[float, float]:
    status = Path(f"/proc/{pid}/status").read_text()
    field = {l.split(":")[0]: l.split()[1] for l in status.splitlines() if l.startswith("Vm")}
    return int(field["VmRSS"]) / 1024, int(field["VmHWM"]) / 1024


def main() -> None:
    if len(sys.argv) < 2:
        sys.exit(__doc__.strip().splitlines()[2])
    program = sys.argv[1]
    side = int(sys.argv[2]) if len(sys.argv) > 2 else 6000
    cache_mb = sys.argv[3] if len(sys.argv) > 3 else "256"
    with tempfile.TemporaryDirectory() as folder:
        photo = Path(folder) / "black.png"
        black_png(photo, side)
        server = subprocess.Popen(
            [program, "serve", "--json", "--port", "0", "--cache-mb", cache_mb, "--data", folder],
            stdout=subprocess.PIPE,
        )
        try:
            ready = json.loads(server.stdout.readline())
            base, token = f"http://{ready['address']}", ready["token"]

            def get(path: str):
                request = urllib.request.Request(base + path, headers={"x-matseg-token": token})
                with urllib.request.urlopen(request, timeout=600) as answer:
                    return answer.headers.get("server-timing"), answer.read()

            idle = memory_mib(server.pid)
            middle = side // 2
            timing, body = get(f"/api/select?root=data0&path=black.png&positive={middle},{middle}")
            _, status = get("/api/status")
            after = memory_mib(server.pid)
            print(
                json.dumps(
                    {
                        "png_bytes": photo.stat().st_size,
                        "side": side,
                        "first_click_server_ms": float(timing.split("dur=")[1]),
                        "answer_bytes": len(body),
                        "described_mib": json.loads(status)["described_mib"],
                        "bound_mib": json.loads(status)["bound_mib"],
                        "rss_idle_mib": idle[0],
                        "rss_after_mib": after[0],
                        "rss_peak_mib": after[1],
                    }
                )
            )
        finally:
            server.terminate()
            server.wait()


if __name__ == "__main__":
    main()
