"""A small driver of headless Chromium over its DevTools protocol (the test
suite's browser: Debian's ``chromium``, no browser download, no extra
package — the websocket client is tornado's, which dask.distributed brings).

Open a local HTML file with every network request blocked and recorded,
collect console errors and uncaught exceptions, evaluate JavaScript, and
take screenshots (PNG bytes).
"""

from __future__ import annotations

import asyncio
import base64
import json
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

__all__ = ["find_chromium", "Browser", "INSTALL"]

INSTALL = "apt-get install -y --no-install-recommends chromium"


def find_chromium() -> str | None:
    """The Chromium executable (``$CHROMIUM``, else chromium on PATH), or None."""
    env = os.environ.get("CHROMIUM")
    if env and Path(env).is_file():
        return env
    for name in ("chromium", "chromium-browser"):
        p = shutil.which(name)
        if p:
            return p
    return None


class Browser:
    """One headless Chromium process and one page (a tab) in it."""

    def __init__(self, exe: str, *, width: int = 1400, height: int = 1000, timeout: float = 60):
        self.loop = asyncio.new_event_loop()
        self.timeout = timeout
        self.profile = tempfile.mkdtemp(prefix="tipgeo-chromium-")
        self.proc = subprocess.Popen(
            [exe, "--headless", "--no-sandbox", "--disable-gpu-sandbox", "--no-first-run",
             "--no-default-browser-check", "--disable-extensions", "--disable-sync",
             "--disable-background-networking", "--disable-component-update",
             "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
             "--remote-debugging-port=0", f"--user-data-dir={self.profile}",
             f"--window-size={width},{height}", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        url = None
        for _ in range(400):
            line = self.proc.stderr.readline().decode("utf-8", "replace")
            if not line and self.proc.poll() is not None:
                break
            m = re.search(r"DevTools listening on (ws://\S+)", line)
            if m:
                url = m.group(1)
                break
        if url is None:
            self.close()
            raise RuntimeError("chromium did not start its DevTools endpoint")
        import threading  # keep reading its stderr: a full pipe would stall it

        threading.Thread(target=lambda f=self.proc.stderr: [None for _ in f], daemon=True).start()
        self._id = 0
        self.events: list[dict] = []
        self.ws = self.loop.run_until_complete(self._connect(url))
        tid = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=tid,
                                 flatten=True)["sessionId"]
        for m in ("Page.enable", "Runtime.enable", "Log.enable", "Network.enable"):
            self.call(m, session=True)
        self.call("Network.setBlockedURLs", session=True,
                  urls=["http://*", "https://*", "ws://*", "wss://*", "ftp://*"])
        self.call("Emulation.setDeviceMetricsOverride", session=True, width=width,
                  height=height, deviceScaleFactor=1, mobile=False)

    async def _connect(self, url):
        from tornado.websocket import websocket_connect

        return await websocket_connect(url, max_message_size=512 * 1024 * 1024)

    async def _call(self, method, params, session):
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params}
        if session:
            msg["sessionId"] = self.session
        await self.ws.write_message(json.dumps(msg))
        while True:
            raw = await asyncio.wait_for(self.ws.read_message(), self.timeout)
            if raw is None:
                raise RuntimeError("chromium closed the DevTools connection")
            r = json.loads(raw)
            if r.get("id") == self._id:
                if "error" in r:
                    raise RuntimeError(f"{method}: {r['error']}")
                return r.get("result", {})
            if "method" in r:
                self.events.append(r)

    def call(self, method: str, *, session: bool = False, **params):
        return self.loop.run_until_complete(self._call(method, params, session))

    def drain(self, seconds: float = 0.2) -> None:
        """Read the events that arrive within ``seconds``."""
        async def go():
            try:
                while True:
                    raw = await asyncio.wait_for(self.ws.read_message(), seconds)
                    if raw is None:
                        return
                    r = json.loads(raw)
                    if "method" in r:
                        self.events.append(r)
            except asyncio.TimeoutError:
                return
        self.loop.run_until_complete(go())

    def open(self, path: Path, *, ready: str, wait_s: float = 60.0) -> None:
        """Navigate to a local file and wait until the JS expression ``ready``
        is true (polled)."""
        self.events.clear()
        self.call("Page.navigate", session=True, url=Path(path).resolve().as_uri())
        for _ in range(int(wait_s / 0.25)):
            if self.eval(f"!!({ready})"):
                self.drain(0.5)
                return
            self.drain(0.25)
        raise TimeoutError(f"{path}: the page did not get ready ({ready})")

    def eval(self, expr: str):
        r = self.call("Runtime.evaluate", session=True, expression=expr, returnByValue=True,
                      awaitPromise=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expr}: {r['exceptionDetails'].get('text')} "
                               f"{r['exceptionDetails'].get('exception', {}).get('description')}")
        return r["result"].get("value")

    def screenshot(self, clip: dict | None = None) -> bytes:
        kw = {"format": "png"}
        if clip:
            kw["clip"] = {**clip, "scale": 1}
            kw["captureBeyondViewport"] = True
        return base64.b64decode(self.call("Page.captureScreenshot", session=True, **kw)["data"])

    def errors(self) -> list[str]:
        """Console errors and uncaught exceptions seen since the last open."""
        out = []
        for e in self.events:
            m, p = e["method"], e.get("params", {})
            if m == "Runtime.exceptionThrown":
                d = p["exceptionDetails"]
                out.append(f"exception: {d.get('text')} "
                           f"{d.get('exception', {}).get('description', '')}")
            elif m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
                out.append("console: " + " ".join(str(a.get("value", a.get("description")))
                                                  for a in p.get("args", [])))
            elif m == "Log.entryAdded" and p["entry"].get("level") == "error":
                out.append(f"log: {p['entry'].get('text')} {p['entry'].get('url', '')}")
        return out

    def requests(self) -> list[str]:
        """URLs the page requested (other than its own file and data: URLs)."""
        urls = []
        for e in self.events:
            if e["method"] == "Network.requestWillBeSent":
                u = e["params"]["request"]["url"]
                if not u.startswith(("file:", "data:", "blob:", "about:")):
                    urls.append(u)
        return urls

    def close(self) -> None:
        try:
            if getattr(self, "ws", None) is not None:
                self.ws.close()
        finally:
            if self.proc.poll() is None:
                self.proc.terminate()
                try:
                    self.proc.wait(10)
                except subprocess.TimeoutExpired:
                    self.proc.kill()
                    self.proc.wait(10)
            shutil.rmtree(self.profile, ignore_errors=True)
            self.loop.close()
