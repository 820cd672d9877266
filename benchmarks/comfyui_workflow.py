"""Run examples/comfyui_relight.json in a real ComfyUI server and compare its images with the CLI's (issue 51).

    python benchmarks/comfyui_workflow.py --comfyui /tmp/ComfyUI --python /tmp/comfy-venv/bin/python [--out DIR]

``--comfyui``: a checkout of ComfyUI (github:comfyanonymous/ComfyUI), ``--python``: the Python environment its
requirements are installed in (with relight_rt importable, or this checkout is found by the node package).
The server runs headless on 127.0.0.1 with ``--cpu`` and ``--base-directory`` a temporary folder, so nothing is
written into the checkout: its custom_nodes/ holds a link to this repository's comfyui/, its input/ the example
photo. The workflow (two relights and the Passes node's normal map) goes in through the HTTP API (POST /prompt); a
small websocket reader (standard library) times each node from ComfyUI's "executing" messages (a node runs until
the next one starts, the last until "execution_success"); the saved images are read from the output folder and
compared with ``relight-rt relight`` of the same photo under the same lights (the lamp written as an SH light
file), 8-bit against 8-bit. Prints a JSON summary (and writes it with the images into --out).
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import time
import urllib.request
import uuid
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
WORKFLOW = REPO / "examples" / "comfyui_relight.json"
PHOTO = REPO / "relight_rt" / "data" / "example_scene.jpg"
NODE_LINK = "ComfyUI-relight-rt"  # not "relight_rt": ComfyUI imports the folder under its own name


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def prepare_base(base: Path) -> None:
    """ComfyUI's base directory: custom_nodes/ with the link to comfyui/, input/ with the photo, output/."""
    (base / "custom_nodes").mkdir(parents=True)
    (base / "custom_nodes" / NODE_LINK).symlink_to(REPO / "comfyui", target_is_directory=True)
    (base / "input").mkdir()
    (base / "output").mkdir()
    shutil.copyfile(PHOTO, base / "input" / PHOTO.name)


class Server:
    """ComfyUI started headless on 127.0.0.1 (a process of its own, ended by ``close``)."""

    def __init__(self, comfyui: Path, python: str, base: Path, log_path: Path, port: int | None = None):
        self.port = port or free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        env = dict(os.environ, PYTHONPATH=str(REPO))  # relight_rt from this checkout in the server too
        cmd = [python, "main.py", "--cpu", "--listen", "127.0.0.1", "--port", str(self.port), "--base-directory",
               str(base), "--disable-auto-launch", "--database-url", "sqlite:///:memory:"]
        self._log = open(log_path, "wb")  # noqa: SIM115 (closed in close())
        self.process = subprocess.Popen(cmd, cwd=comfyui, env=env, stdout=self._log, stderr=subprocess.STDOUT)

    def wait(self, timeout: float = 240.0) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                raise RuntimeError(f"ComfyUI exited with {self.process.returncode} (see its log)")
            try:
                with urllib.request.urlopen(self.url + "/system_stats", timeout=2) as r:
                    if r.status == 200:
                        return
            except OSError:
                time.sleep(0.5)
        raise RuntimeError(f"ComfyUI did not answer on {self.url} within {timeout:.0f} s")

    def get(self, path: str):
        with urllib.request.urlopen(self.url + path, timeout=30) as r:
            return json.loads(r.read())

    def post(self, path: str, body: dict):
        req = urllib.request.Request(self.url + path, json.dumps(body).encode(), {"Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=30) as r:
            return json.loads(r.read())

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(20)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._log.close()


class Messages:
    """ComfyUI's websocket (/ws?clientId=...) read with the standard library: text frames only, as JSON."""

    def __init__(self, port: int, client_id: str):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=600)
        key = base64.b64encode(os.urandom(16)).decode()
        request = (f"GET /ws?clientId={client_id} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                   f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n")
        self.sock.sendall(request.encode())
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(1)
            if not chunk:
                raise RuntimeError("websocket: the server closed the connection during the handshake")
            head += chunk
        if b" 101 " not in head.split(b"\r\n")[0]:
            raise RuntimeError(f"websocket: handshake refused: {head.splitlines()[0]!r}")

    def _exactly(self, n: int) -> bytes:
        data = b""
        while len(data) < n:
            chunk = self.sock.recv(n - len(data))
            if not chunk:
                raise RuntimeError("websocket: connection closed")
            data += chunk
        return data

    def next(self) -> dict | None:
        """The next JSON message (binary frames, previews, are skipped); None when the server closes."""
        while True:
            b0, b1 = self._exactly(2)
            opcode, size = b0 & 0x0F, b1 & 0x7F
            if size == 126:
                size = struct.unpack(">H", self._exactly(2))[0]
            elif size == 127:
                size = struct.unpack(">Q", self._exactly(8))[0]
            mask = self._exactly(4) if b1 & 0x80 else None
            payload = self._exactly(size)
            if mask:
                payload = bytes(c ^ mask[i % 4] for i, c in enumerate(payload))
            if opcode == 8:
                return None
            if opcode == 1:
                return json.loads(payload)

    def close(self) -> None:
        self.sock.close()


def run_prompt(server: Server, workflow: dict) -> tuple[str, dict[str, float], float]:
    """POST the workflow, follow it on the websocket; (prompt id, seconds per node id, seconds in all)."""
    client_id = uuid.uuid4().hex
    ws = Messages(server.port, client_id)
    try:
        start = time.perf_counter()
        prompt_id = server.post("/prompt", {"prompt": workflow, "client_id": client_id})["prompt_id"]
        times: dict[str, float] = {}
        current, since = None, None
        while True:
            msg = ws.next()
            if msg is None:
                raise RuntimeError("websocket closed before the workflow finished")
            kind, data = msg.get("type"), msg.get("data", {})
            if data.get("prompt_id") not in (None, prompt_id):
                continue
            if kind == "execution_error":
                raise RuntimeError(f"ComfyUI: node {data.get('node_id')} failed: {data.get('exception_message')}")
            now = time.perf_counter()
            if kind in ("executing", "execution_success") and current is not None:  # the node before has ended
                times[current] = now - since
                current = None
            if kind == "executing":
                current, since = data.get("node"), now
                if current is None:  # sent after ComfyUI's bookkeeping (history, caches): the end of it all
                    return prompt_id, times, now - start
    finally:
        ws.close()


def cli_images(out: Path, workflow: dict) -> dict[str, np.ndarray]:
    """The CLI's images for the workflow's two lights: the night preset, and the lamp as an SH light file."""
    sys.path.insert(0, str(REPO))
    from comfyui.nodes import RelightLight
    from relight_rt import save_light

    lamp = workflow["5"]["inputs"]
    light = RelightLight.spec(**{k: v for k, v in lamp.items()}).resolve(dtype=np.float64)
    save_light(out / "lamp_light.json", light)
    env = dict(os.environ, PYTHONPATH=str(REPO))
    images = {}
    for name, light_args in (("night", ["--preset", "night"]), ("lamp", ["--light", str(out / "lamp_light.json")])):
        target = out / f"cli_{name}.png"
        subprocess.run([sys.executable, "-m", "relight_rt", "relight", str(PHOTO), *light_args, "--device", "cpu",
                        "-o", str(target)], check=True, env=env)
        images[name] = cv2.cvtColor(cv2.imread(str(target)), cv2.COLOR_BGR2RGB)
    return images


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--comfyui", required=True, type=Path, help="ComfyUI checkout (with main.py)")
    p.add_argument("--python", default=sys.executable, help="the Python that has ComfyUI's requirements")
    p.add_argument("--out", type=Path, default=None, help="folder for the images and summary.json")
    args = p.parse_args(argv)
    out = args.out or Path(tempfile.mkdtemp(prefix="comfyui_run_"))
    out.mkdir(parents=True, exist_ok=True)
    workflow = json.loads(WORKFLOW.read_text())
    commit = subprocess.run(["git", "-C", str(args.comfyui), "rev-parse", "HEAD"], capture_output=True, text=True)
    with tempfile.TemporaryDirectory(prefix="comfyui_base_") as tmp:
        base = Path(tmp)
        prepare_base(base)
        started = time.perf_counter()
        server = Server(args.comfyui, args.python, base, out / "server.log")
        try:
            server.wait()
            startup = time.perf_counter() - started
            prompt_id, times, total = run_prompt(server, workflow)
            history = server.get(f"/history/{prompt_id}")[prompt_id]
        finally:
            server.close()
        saved = {}
        for node, name in (("8", "night"), ("9", "lamp"), ("11", "normal")):
            info = history["outputs"][node]["images"][0]
            src = base / "output" / info.get("subfolder", "") / info["filename"]
            shutil.copyfile(src, out / f"comfyui_{name}.png")
            saved[name] = cv2.cvtColor(cv2.imread(str(out / f"comfyui_{name}.png")), cv2.COLOR_BGR2RGB)
        del saved["normal"]  # kept as a file to look at; the CLI has no 8-bit normal map to compare it with
    cli = cli_images(out, workflow)
    diff = {name: int(np.abs(saved[name].astype(np.int16) - cli[name]).max()) for name in saved}
    summary = {
        "comfyui_commit": commit.stdout.strip() or None,
        "server_start_s": round(startup, 2),
        "workflow_s": round(total, 3),
        "node_s": {f"{node} {workflow[node]['class_type']}": round(t, 3) for node, t in times.items()},
        "max_abs_diff_8bit": diff,
        "shape": {name: list(saved[name].shape) for name in saved},
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary, indent=2))
    return 0 if all(d <= 1 for d in diff.values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
