"""The trame page of the viewer in a real headless browser (Debian's chromium), driven over the DevTools protocol."""

from __future__ import annotations

import asyncio
import base64
import io
import json
import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from pverosion.examples import load_cube
from pverosion.filters.weathering import Weathering
from pverosion.io import TimeSeriesWriter

ROOT = Path(__file__).resolve().parents[1]
BROWSER = shutil.which("chromium") or shutil.which("chromium-browser")

pytest.importorskip("trame", reason="the web viewer needs the view extra (pip install 'pverosion[view]')")
pytest.importorskip("trame_pyvista", reason="the web viewer needs trame-pyvista (pip install 'pverosion[view]')")
aiohttp = pytest.importorskip("aiohttp")
Image = pytest.importorskip("PIL.Image")
pytestmark = pytest.mark.skipif(BROWSER is None, reason="no chromium browser installed (apt-get install chromium)")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_for(check, *, limit: float, what: str):
    start = time.monotonic()
    while time.monotonic() - start < limit:
        value = check()
        if value:
            return value
        time.sleep(0.25)
    raise AssertionError(f"timed out after {limit} s waiting for {what}")


class DevTools:
    """A minimal Chrome DevTools Protocol client over one page's websocket."""

    def __init__(self, ws):
        self.ws = ws
        self.next_id = 0

    async def call(self, method: str, **params):
        self.next_id += 1
        await self.ws.send_str(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            message = json.loads((await self.ws.receive()).data)
            if message.get("id") == self.next_id:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message.get("result", {})

    async def evaluate(self, expression: str):
        result = await self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        return result.get("result", {}).get("value")

    async def screenshot(self) -> np.ndarray:
        data = (await self.call("Page.captureScreenshot", format="png"))["data"]
        return np.asarray(Image.open(io.BytesIO(base64.b64decode(data))).convert("RGB"), dtype=np.int16)


def _view_pixels(image: np.ndarray) -> int:
    """Pixels of the page's view area (below the toolbar) that are not the white background."""
    return int(np.count_nonzero(np.abs(image[80:-40] - 255).sum(axis=2) > 30))


@pytest.fixture(scope="module")
def small_series(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("web") / "cube.pvd"
    with TimeSeriesWriter(path) as series:
        Weathering(iterations=8).step_through(load_cube(resolution=6), list(range(9)),
                                              on_output=lambda t, r: series.write(r, time=t))
    return path


def test_page_renders_the_mesh_and_the_slider_moves_the_step(small_series, tmp_path):
    port, debug_port = _free_port(), _free_port()
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYVISTA_OFF_SCREEN": "true"}
    server = subprocess.Popen([sys.executable, "-m", "pverosion", "view", str(small_series), "--web", str(port),
                               "--window-size", "640", "480"], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, text=True)
    browser = None
    try:
        _wait_for(lambda: _answers(port), limit=120, what="the trame server")
        browser = subprocess.Popen(
            [BROWSER, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--user-data-dir={tmp_path / 'profile'}", f"--remote-debugging-port={debug_port}",
             "--window-size=1000,700", f"http://127.0.0.1:{port}/"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
        pages = _wait_for(lambda: _pages(debug_port), limit=60, what="the browser's DevTools endpoint")
        asyncio.run(_drive(pages[0]["webSocketDebuggerUrl"], tmp_path))
    finally:
        for process in (browser, server):
            if process is not None:
                process.terminate()
                try:
                    process.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait()


def _answers(port: int) -> bool:
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=2) as reply:
            return reply.status == 200
    except OSError:
        return False


def _pages(debug_port: int):
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{debug_port}/json", timeout=2) as reply:
            pages = [p for p in json.load(reply) if p.get("type") == "page"]
    except OSError:
        return None
    return pages or None


async def _drive(ws_url: str, folder: Path) -> None:
    async with aiohttp.ClientSession() as session, session.ws_connect(ws_url, max_msg_size=0) as ws:
        tools = DevTools(ws)
        await tools.call("Page.enable")

        async def until(check, limit: float, what: str):
            start = time.monotonic()
            while time.monotonic() - start < limit:
                value = await check()
                if value is not None:
                    return value
                await asyncio.sleep(0.5)
            raise AssertionError(f"timed out after {limit} s waiting for {what}")

        label = "(document.querySelector('.step-label') || {}).textContent || null"
        text = await until(lambda: tools.evaluate(label), 90, "the page's step label")
        assert text.strip().startswith("step 0 / 8")

        async def rendered():
            image = await tools.screenshot()
            return image if _view_pixels(image) > 5000 else None

        first = await until(rendered, 90, "the mesh in the page")
        Image.fromarray(first.astype(np.uint8)).save(folder / "page_step0.png")  # for a look when it fails
        box = await tools.evaluate(
            "(() => { const r = document.querySelector('.step-slider .v-slider-track').getBoundingClientRect();"
            " return [r.left, r.top, r.width, r.height]; })()")
        x, y = box[0] + 0.99 * box[2], box[1] + 0.5 * box[3]  # a click at the end of the track: the last step
        for kind in ("mousePressed", "mouseReleased"):
            await tools.call("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left", clickCount=1)

        async def moved():
            text = (await tools.evaluate(label)).strip()
            return text if text.startswith("step 8 / 8") else None

        await until(moved, 60, "the step label to reach step 8")

        async def changed():
            image = await tools.screenshot()
            return image if np.abs(image[80:-40] - first[80:-40]).max() > 50 else None

        last = await until(changed, 60, "the rendered view to show step 8")
        Image.fromarray(last.astype(np.uint8)).save(folder / "page_step8.png")
