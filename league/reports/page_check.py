"""A report page checked in headless Chromium, driven over the DevTools protocol (``python -m league.browser_check``).

Chromium is driven through the DevTools protocol over a pipe (``--remote-debugging-pipe``:
JSON messages ending in NUL on file descriptors 3 and 4), so nothing but the standard
library is needed. Its console log on stderr cannot tell an error from a warning; the
protocol can.
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome")
FLAGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    # Software WebGL (SwiftShader) for the 3D scenes: without a GPU, Chromium only falls back
    # to it with a deprecation warning, and will stop doing so.
    "--enable-unsafe-swiftshader",
]
WIDTH, HEIGHT = 1300, 900


def find_chromium() -> str | None:
    return next((path for name in CHROMIUM_NAMES if (path := shutil.which(name))), None)


@dataclass
class PageCheck:
    errors: list[str] = field(default_factory=list)  # console errors and uncaught exceptions
    fetched: list[str] = field(default_factory=list)  # URLs requested besides the page (offline: none)
    figures: int = 0  # rendered plotly figures
    scenes: int = 0  # 3D scenes with a WebGL canvas
    screenshot: bytes = b""  # PNG of the first trajectory scene

    def problems(self) -> list[str]:
        """Why the page fails the check, one line each (empty: it passes)."""
        found = []
        if self.errors:
            found.append(f"{len(self.errors)} console errors (listed above)")
        if self.fetched:
            found.append(f"{len(self.fetched)} requests besides the page (listed above): a report page is self-contained")
        if self.scenes == 0 and self.figures == 0:
            found.append("no plotly figure and no 3D scene: not a report page (league.report writes RUN_DIR/report/index.html)")
        elif self.scenes == 0:
            found.append(f"{self.figures} figures but no 3D scene with a WebGL canvas: a report page draws its trajectories in 3D")
        return found


class DevTools:
    """A minimal DevTools protocol client over Chromium's pipe."""

    def __init__(self, chromium: str, profile: Path):
        to_chrome_r, self.to_chrome = os.pipe()
        self.from_chrome, from_chrome_w = os.pipe()

        def child_fds() -> None:  # the pipe ends must be fds 3 (Chromium reads) and 4 (Chromium writes)
            # Copied above 10 first, so that placing one cannot overwrite the other.
            read_end, write_end = fcntl.fcntl(to_chrome_r, fcntl.F_DUPFD, 10), fcntl.fcntl(from_chrome_w, fcntl.F_DUPFD, 10)
            os.dup2(read_end, 3)  # inheritable; every other fd of ours is not (PEP 446)
            os.dup2(write_end, 4)

        self.proc = subprocess.Popen(
            [chromium, *FLAGS, "--remote-debugging-pipe", f"--user-data-dir={profile}", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            preexec_fn=child_fds, close_fds=False,
        )
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self.buffer = b""
        self.next_id = 0
        self.events: list[dict[str, Any]] = []

    def close(self) -> None:
        self.proc.kill()
        self.proc.wait()
        os.close(self.to_chrome)
        os.close(self.from_chrome)

    def receive(self) -> dict[str, Any]:
        while b"\0" not in self.buffer:
            chunk = os.read(self.from_chrome, 1 << 20)
            if not chunk:
                raise RuntimeError("Chromium closed the DevTools pipe")
            self.buffer += chunk
        message, self.buffer = self.buffer.split(b"\0", 1)
        return json.loads(message)

    def call(self, method: str, session: str | None = None, **params: Any) -> dict[str, Any]:
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params}
        if session:
            message["sessionId"] = session
        os.write(self.to_chrome, json.dumps(message).encode() + b"\0")
        while True:
            reply = self.receive()
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)

    def wait_for(self, method: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while not any(e.get("method") == method for e in self.events):
            if time.monotonic() > deadline:
                raise TimeoutError(f"no {method} within {timeout:.0f} s")
            self.events.append(self.receive())


def errors_in(events: list[dict[str, Any]]) -> list[str]:
    errors = []
    for event in events:
        method, params = event.get("method"), event.get("params", {})
        if method == "Runtime.exceptionThrown":
            details = params["exceptionDetails"]
            errors.append(details.get("exception", {}).get("description") or details.get("text", "exception"))
        elif method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
            errors.append(" ".join(str(a.get("value", a.get("description", ""))) for a in params.get("args", [])))
        elif method == "Log.entryAdded" and params["entry"]["level"] == "error":
            errors.append(params["entry"]["text"])
    return errors


def fetched_urls(events: list[dict[str, Any]], page_url: str) -> list[str]:
    urls = (e["params"]["request"]["url"] for e in events if e.get("method") == "Network.requestWillBeSent")
    return [url for url in urls if url != page_url and not url.startswith(("data:", "blob:", "about:"))]


COUNT_SCRIPT = """JSON.stringify({
  figures: document.querySelectorAll('.js-plotly-plot').length,
  scenes: Array.from(document.querySelectorAll('.js-plotly-plot'))
    .filter(div => div._fullLayout && div._fullLayout.scene && div.querySelector('.gl-container canvas')).length,
})"""
SCENE_BOX_SCRIPT = """(() => {
  const scene = document.querySelector('[id^="trajectory-"]');
  if (!scene) return null;
  scene.scrollIntoView();
  const box = scene.getBoundingClientRect();
  return JSON.stringify({x: box.left + window.scrollX, y: box.top + window.scrollY, width: box.width, height: box.height});
})()"""


def check_page(page: Path, chromium: str, settle_seconds: float = 3.0, timeout: float = 300.0) -> PageCheck:
    """Load ``page`` in headless Chromium and report what a reader would see."""
    # Chromium's helper processes may still write the profile while it is removed: a leftover is harmless.
    with tempfile.TemporaryDirectory(prefix="report-browser-", ignore_cleanup_errors=True) as profile:
        tools = DevTools(chromium, Path(profile))
        try:
            target = tools.call("Target.createTarget", url="about:blank")["targetId"]
            session = tools.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
            for domain in ("Runtime", "Log", "Page", "Network"):
                tools.call(f"{domain}.enable", session)
            tools.call("Emulation.setDeviceMetricsOverride", session, width=WIDTH, height=HEIGHT,
                       deviceScaleFactor=1, mobile=False)
            tools.call("Page.navigate", session, url=page.resolve().as_uri())
            tools.wait_for("Page.loadEventFired", timeout)
            time.sleep(settle_seconds)  # WebGL scenes draw after the load event
            value = tools.call("Runtime.evaluate", session, expression=COUNT_SCRIPT, returnByValue=True)
            counts = json.loads(value["result"]["value"])
            check = PageCheck(figures=counts["figures"], scenes=counts["scenes"])
            box = tools.call("Runtime.evaluate", session, expression=SCENE_BOX_SCRIPT, returnByValue=True)
            if box["result"].get("value"):
                clip = {**json.loads(box["result"]["value"]), "scale": 1}
                time.sleep(0.5)
                shot = tools.call("Page.captureScreenshot", session, format="png", clip=clip, captureBeyondViewport=True)
                check.screenshot = base64.b64decode(shot["data"])
            check.errors = errors_in(tools.events)
            check.fetched = fetched_urls(tools.events, page.resolve().as_uri())
            return check
        finally:
            tools.close()
