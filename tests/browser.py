"""Open an HTML page in headless Chromium and see it as drawn (a helper for tests, not a test).

    from browser import find_chromium, render_page
    if find_chromium() is None: pytest.skip("no chromium: ...")
    page = render_page(path, width=1000, height=800)
    page.images        # every <img>: src, complete, naturalWidth/Height; width, height, left,
                       # top as drawn (page pixels: the screenshot's)
    page.console       # console messages, uncaught exceptions, failed loads: "level: text"
    page.values        # {name: value} of the JavaScript expressions asked for (evaluate=)
    page.dom           # the document's HTML after its scripts ran
    page.screenshot    # a PNG of the whole page, width wide (screenshot=PATH, else a temp file)
    page.seconds       # how long Chromium took

Chromium is driven through its DevTools protocol over a pipe (``--remote-debugging-pipe``:
JSON messages ending in a NUL byte on file descriptors 3 and 4), so nothing beyond the standard
library is needed and nothing is injected into the page: it is measured after its load event
(every image loaded or failed), with the page's own scripts run.
"""

from __future__ import annotations

import base64
import fcntl
import functools
import json
import os
import select
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome")

# every <img> as drawn: its size and place on the page in CSS pixels, which are the
# screenshot's pixels (the page is drawn at scale 1)
IMAGES_JS = """[...document.images].map(i => ({src: i.getAttribute("src"), complete: i.complete,
  naturalWidth: i.naturalWidth, naturalHeight: i.naturalHeight,
  width: i.getBoundingClientRect().width, height: i.getBoundingClientRect().height,
  left: i.getBoundingClientRect().left + window.scrollX,
  top: i.getBoundingClientRect().top + window.scrollY}))"""


@dataclass
class Page:
    dom: str
    images: list[dict[str, Any]]
    console: list[str]
    values: dict[str, Any]
    screenshot: Path
    seconds: float
    size: tuple[int, int] = (0, 0)          # the whole page's width and height (CSS pixels)
    log: list[dict] = field(default_factory=list, repr=False)   # every protocol event


@functools.lru_cache(maxsize=None)
def find_chromium() -> Optional[str]:
    """The path of a Chromium (or Chrome) executable that runs (``--version`` answers: Ubuntu's
    ``chromium-browser`` may be a stub asking for a snap); ``$CHROMIUM`` wins; None if none."""
    named = os.environ.get("CHROMIUM")
    for name in [named] if named else NAMES:
        found = shutil.which(name)
        if found and _runs(found):
            return found
    return None


def _runs(exe: str) -> bool:
    try:
        return subprocess.run([exe, "--version"], capture_output=True, timeout=20,
                              stdin=subprocess.DEVNULL).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def render_page(html_path, width: int = 1000, height: int = 800,
                evaluate: Optional[dict[str, str]] = None, timeout: float = 30.0,
                chromium: Optional[str] = None, screenshot=None) -> Page:
    """Load ``html_path`` in headless Chromium with a ``width`` x ``height`` window, wait for its
    load event, and return the page as drawn (see the module docstring).  ``evaluate``: name ->
    JavaScript expression, evaluated in the page after it loaded (values must be JSON).  The
    screenshot is of the whole page, at most 8000 pixels tall, written to ``screenshot`` (a
    path; by default a temporary file that is left for the caller)."""
    exe = chromium or find_chromium()
    if exe is None:
        raise FileNotFoundError("no chromium executable found (install chromium)")
    url = Path(html_path).resolve().as_uri()
    tmp = Path(tempfile.mkdtemp(prefix="pipegen-browser-"))
    start = time.monotonic()
    with _Browser(exe, tmp, width, height, timeout) as b:
        session = b.open_page()
        for domain in ("Runtime", "Log", "Page"):
            b.call(f"{domain}.enable", session=session)
        b.call("Emulation.setDeviceMetricsOverride", session=session, width=width,
               height=height, deviceScaleFactor=1, mobile=False)
        since = len(b.events)
        b.call("Page.navigate", session=session, url=url)
        b.wait_event("Page.loadEventFired", session, since)
        value = lambda expr: b.evaluate(session, expr)   # noqa: E731
        images = value(IMAGES_JS)
        values = {name: value(expr) for name, expr in (evaluate or {}).items()}
        dom = value("document.documentElement.outerHTML")
        full = value("[document.documentElement.scrollWidth, "
                     "document.documentElement.scrollHeight]")
        shot_h = min(int(full[1]), 8000)
        shot = b.call("Page.captureScreenshot", session=session, format="png",
                      captureBeyondViewport=True,
                      clip={"x": 0, "y": 0, "width": width, "height": shot_h, "scale": 1})
        if screenshot is None:
            fd, screenshot = tempfile.mkstemp(prefix="pipegen-page-", suffix=".png")
            os.close(fd)
        screenshot = Path(screenshot)
        screenshot.write_bytes(base64.b64decode(shot["data"]))
        console = _console(b.events)
        events = list(b.events)
    return Page(dom=dom, images=images, console=console, values=values,
                screenshot=screenshot, seconds=time.monotonic() - start,
                size=(int(full[0]), int(full[1])), log=events)


def _console(events: list[dict]) -> list[str]:
    """What the page said: console calls, uncaught exceptions and log entries (a failed image
    load is a Log.entryAdded with level "error")."""
    out = []
    for e in events:
        method, p = e.get("method"), e.get("params", {})
        if method == "Runtime.consoleAPICalled":
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in p["args"])
            out.append(f"{p['type']}: {text}")
        elif method == "Runtime.exceptionThrown":
            d = p["exceptionDetails"]
            text = d.get("exception", {}).get("description") or d.get("text", "")
            out.append(f"exception: {text} (line {d.get('lineNumber', 0) + 1})")
        elif method == "Log.entryAdded":
            entry = p["entry"]
            out.append(f"{entry['level']}: {entry['text']} {entry.get('url', '')}".rstrip())
    return out


class _Browser:
    """One headless Chromium process and its protocol pipe."""

    def __init__(self, exe: str, tmp: Path, width: int, height: int, timeout: float):
        self.exe, self.tmp, self.size, self.timeout = exe, tmp, (width, height), timeout
        self.events: list[dict] = []
        self.next_id = 0
        self.buffer = b""

    def __enter__(self) -> "_Browser":
        to_chrome_r, self.to_chrome = os.pipe()
        self.from_chrome, from_chrome_w = os.pipe()

        def fds() -> None:     # in the child: the protocol's descriptors are 3 (in), 4 (out)
            # (the pipes may themselves be 3 or 4: move both out of the way first; every
            # other descriptor is closed after this runs, except pass_fds.  3 and 4 are open
            # in this process: the two pipes took the lowest free descriptors)
            high_r = fcntl.fcntl(to_chrome_r, fcntl.F_DUPFD, 10)
            high_w = fcntl.fcntl(from_chrome_w, fcntl.F_DUPFD, 10)
            os.dup2(high_r, 3)
            os.dup2(high_w, 4)

        args = [self.exe, "--headless", "--no-sandbox", "--disable-gpu",
                "--remote-debugging-pipe", f"--user-data-dir={self.tmp / 'profile'}",
                f"--window-size={self.size[0]},{self.size[1]}", "--hide-scrollbars",
                "--no-first-run", "--no-default-browser-check", "--disable-extensions",
                "--disable-background-networking", "--mute-audio", "about:blank"]
        with open(self.tmp / "chromium.log", "wb") as log:
            self.proc = subprocess.Popen(args, stdin=subprocess.DEVNULL,
                                         stdout=subprocess.DEVNULL, stderr=log,
                                         preexec_fn=fds, pass_fds=(3, 4))
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self.deadline = time.monotonic() + self.timeout
        return self

    def __exit__(self, *exc) -> None:
        try:
            if self.proc.poll() is None:
                self._send({"id": -1, "method": "Browser.close"})
                self.proc.wait(timeout=5)
        except (OSError, subprocess.TimeoutExpired):
            self.proc.kill()
            self.proc.wait()
        finally:
            os.close(self.to_chrome)
            os.close(self.from_chrome)
            shutil.rmtree(self.tmp, ignore_errors=True)

    def _log(self) -> str:
        return (self.tmp / "chromium.log").read_text(errors="replace")[-2000:]

    def _send(self, message: dict) -> None:
        os.write(self.to_chrome, json.dumps(message).encode() + b"\0")

    def _receive(self) -> dict:
        while b"\0" not in self.buffer:
            left = self.deadline - time.monotonic()
            if left <= 0 or not select.select([self.from_chrome], [], [], left)[0]:
                raise TimeoutError(f"chromium did not answer within {self.timeout} s; the end "
                                   f"of its log:\n{self._log()}")
            chunk = os.read(self.from_chrome, 1 << 20)
            if not chunk:
                raise RuntimeError(f"chromium exited (status {self.proc.wait()}); the end of "
                                   f"its log:\n{self._log()}")
            self.buffer += chunk
        message, self.buffer = self.buffer.split(b"\0", 1)
        return json.loads(message)

    def call(self, method: str, session: Optional[str] = None, **params) -> dict:
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params}
        if session:
            message["sessionId"] = session
        self._send(message)
        while True:
            reply = self._receive()
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply["result"]
            if "method" in reply:
                self.events.append(reply)

    def wait_event(self, method: str, session: str, since: int = 0) -> dict:
        for e in self.events[since:]:
            if e["method"] == method and e.get("sessionId") == session:
                return e
        while True:
            reply = self._receive()
            if "method" in reply:
                self.events.append(reply)
                if reply["method"] == method and reply.get("sessionId") == session:
                    return reply

    def open_page(self) -> str:
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        return self.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]

    def evaluate(self, session: str, expression: str) -> Any:
        r = self.call("Runtime.evaluate", session=session, expression=expression,
                      returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"evaluating {expression[:60]!r}: {r['exceptionDetails']}")
        return r["result"].get("value")
