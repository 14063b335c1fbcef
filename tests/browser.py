"""Drive headless Chromium over the Chrome DevTools Protocol, stdlib only.

The browser is started with --remote-debugging-pipe: it reads CDP messages
(JSON, each terminated by a NUL byte) from its fd 3 and writes replies and
events to its fd 4.  Every wait is bounded by select() with a deadline, so a
hung browser fails the calling test instead of hanging it.

    with Browser() as b:
        load = b.open("report.html")
        assert not load.console_errors and not load.exceptions
        stats = b.colour_stats(b.screenshot())

Run this file directly for a self-test.
"""
from __future__ import annotations

import base64
import fcntl
import json
import math
import os
import select
import shutil
import signal
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

DEFAULT_READY = "document.documentElement.dataset.ready === 'true'"


@dataclass
class PageLoad:
    url: str = ""
    console_errors: list[str] = field(default_factory=list)
    exceptions: list[str] = field(default_factory=list)
    requests: list[str] = field(default_factory=list)

    def external_requests(self, page_url: str) -> list[str]:
        """Requested URLs other than the page itself and data:/blob: URLs.

        page_url may be a URL or a filesystem path (turned into a file:// URL)."""
        if "://" not in page_url:
            page_url = Path(page_url).resolve().as_uri()
        page_url = page_url.split("#", 1)[0]
        return [u for u in self.requests
                if u.split("#", 1)[0] != page_url and not u.startswith(("data:", "blob:"))]


def _remote_text(arg: dict) -> str:
    """Render a Runtime.RemoteObject (a console argument) as text."""
    if "value" in arg:
        return arg["value"] if isinstance(arg["value"], str) else json.dumps(arg["value"])
    return arg.get("description", arg.get("unserializableValue", arg.get("type", "?")))


class Browser:
    def __init__(self, chromium: str = "chromium", width: int = 1280, height: int = 900,
                 timeout_s: float = 60):
        self.chromium, self.width, self.height, self.timeout_s = chromium, width, height, timeout_s
        self._proc: subprocess.Popen | None = None
        self._tmp: str | None = None
        self._next_id = 0
        self._buf = bytearray()
        self._replies: dict[int, dict] = {}
        self._pages: dict[str, PageLoad] = {}   # sessionId -> collector
        self._loaded: set[str] = set()          # sessions that have seen Page.loadEventFired
        self._session: str | None = None
        self._target: str | None = None

    # ---------------------------------------------------------------- lifecycle
    def __enter__(self) -> "Browser":
        self._tmp = tempfile.mkdtemp(prefix="xgauge-chromium-")
        self._log_path = os.path.join(self._tmp, "chromium.log")
        # Pipes: we write to_child_w -> child's fd 3; child's fd 4 -> from_child_r.
        to_child_r, self._wfd = os.pipe()
        self._rfd, from_child_w = os.pipe()
        os.set_blocking(self._wfd, False)  # partial writes, so _send can also drain replies

        def place_fds():  # runs in the child between fork and exec
            # Copy both ends above 4 first so the dup2s below cannot clobber each other.
            a = fcntl.fcntl(to_child_r, fcntl.F_DUPFD, 10)
            b = fcntl.fcntl(from_child_w, fcntl.F_DUPFD, 10)
            os.dup2(a, 3)
            os.dup2(b, 4)  # dup2 clears close-on-exec on 3 and 4

        args = [shutil.which(self.chromium) or self.chromium, "--headless", "--no-sandbox",
                "--disable-gpu", "--remote-debugging-pipe",
                f"--user-data-dir={os.path.join(self._tmp, 'profile')}", "--no-first-run",
                "--no-default-browser-check", "--disable-extensions",
                "--disable-background-networking", "--disable-sync", "--metrics-recording-only",
                "--mute-audio", "--hide-scrollbars", f"--window-size={self.width},{self.height}",
                "about:blank"]
        try:
            with open(self._log_path, "wb") as log:
                # fds 3 and 4 are necessarily open here (the pipes took the lowest free fds),
                # which subprocess requires of pass_fds; close_fds then closes all the others.
                self._proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=log,
                                              stderr=log, pass_fds=(3, 4), preexec_fn=place_fds,
                                              start_new_session=True)
        finally:
            os.close(to_child_r)
            os.close(from_child_w)
        try:
            self._call("Browser.getVersion")  # fails fast if the browser did not come up
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self._proc is not None:
            try:  # polite shutdown first, so the profile is released cleanly
                self._send("Browser.close", deadline=time.monotonic() + 1)
                self._proc.wait(timeout=3)
            except Exception:
                pass
            try:  # then kill whatever is left of the process group we created
                os.killpg(self._proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
            self._proc.wait()
            self._proc = None
            for fd in (self._rfd, self._wfd):
                os.close(fd)
        if self._tmp is not None:
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None

    def _log_tail(self, n: int = 3000) -> str:
        try:
            with open(self._log_path, "rb") as f:
                f.seek(max(0, os.path.getsize(self._log_path) - n))
                return f.read().decode(errors="replace")
        except OSError:
            return "(no log)"

    def _fail(self, cls: type[Exception], msg: str) -> Exception:
        return cls(f"{msg}\n--- chromium log tail ---\n{self._log_tail()}")

    # ---------------------------------------------------------------- transport
    def _send(self, method: str, params: dict | None = None, session: str | None = None,
              *, deadline: float) -> int:
        self._next_id += 1
        msg = {"id": self._next_id, "method": method, "params": params or {}}
        if session:  # flatten mode: page commands go over the browser pipe, tagged
            msg["sessionId"] = session
        data = memoryview(json.dumps(msg).encode() + b"\0")
        while data:
            # Keep reading while writing large messages: the browser may block writing
            # events to us, and stop reading, if we do not.
            r, w, _ = select.select([self._rfd], [self._wfd], [], max(0, deadline - time.monotonic()))
            if r:
                self._read_available()
            if w:
                try:
                    data = data[os.write(self._wfd, data):]
                except BlockingIOError:
                    pass
            if not (r or w):
                raise self._fail(TimeoutError, f"timed out sending {method}")
        return self._next_id

    def _pump(self, until: float) -> None:
        """Process input arriving before `until` (returns early after the first read)."""
        r, _, _ = select.select([self._rfd], [], [], max(0, until - time.monotonic()))
        if r:
            self._read_available()

    def _read_available(self) -> None:
        chunk = os.read(self._rfd, 1 << 20)
        if not chunk:
            raise self._fail(RuntimeError, "chromium closed the DevTools pipe (crashed or exited)")
        start = len(self._buf)
        self._buf += chunk
        while (end := self._buf.find(b"\0", start)) >= 0:
            msg = json.loads(self._buf[:end])
            del self._buf[:end + 1]
            start = 0
            if "id" in msg:
                self._replies[msg["id"]] = msg
            else:
                self._dispatch(msg)

    def _call(self, method: str, params: dict | None = None, session: str | None = None,
              deadline: float | None = None) -> dict:
        deadline = deadline or time.monotonic() + self.timeout_s
        id_ = self._send(method, params, session, deadline=deadline)
        while id_ not in self._replies:  # events seen meanwhile are dispatched by _pump
            if time.monotonic() >= deadline:
                raise self._fail(TimeoutError, f"no reply to {method} within {self.timeout_s}s")
            self._pump(deadline)
        reply = self._replies.pop(id_)
        if "error" in reply:
            raise RuntimeError(f"{method} failed: {reply['error']}")
        return reply.get("result", {})

    def _dispatch(self, msg: dict) -> None:
        session = msg.get("sessionId")
        page = self._pages.get(session)
        if page is None:
            return
        method, p = msg.get("method"), msg.get("params", {})
        if method == "Page.loadEventFired":
            self._loaded.add(session)
        elif method == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            page.console_errors.append(" ".join(_remote_text(a) for a in p.get("args", [])))
        elif method == "Log.entryAdded" and p["entry"].get("level") == "error":
            e = p["entry"]
            page.console_errors.append(f"{e.get('text', '')} ({e.get('url', '')})")
        elif method == "Runtime.exceptionThrown":
            d = p.get("exceptionDetails", {})
            page.exceptions.append(f"{d.get('text', '')} {d.get('exception', {}).get('description', '')}".strip())
        elif method == "Network.requestWillBeSent":
            page.requests.append(p["request"]["url"])

    # ---------------------------------------------------------------- pages
    def open(self, path: str, ready_expression: str = DEFAULT_READY) -> PageLoad:
        deadline = time.monotonic() + self.timeout_s
        url = Path(path).resolve().as_uri()
        if self._target:  # one page at a time: drop the previous one
            self._pages.pop(self._session, None)
            self._call("Target.closeTarget", {"targetId": self._target}, deadline=deadline)
            self._target = self._session = None
        # A fresh blank target, so the domains are enabled before the real navigation starts.
        self._target = self._call("Target.createTarget", {"url": "about:blank"},
                                  deadline=deadline)["targetId"]
        s = self._session = self._call("Target.attachToTarget",
                                       {"targetId": self._target, "flatten": True},
                                       deadline=deadline)["sessionId"]
        load = self._pages[s] = PageLoad(url=url)
        for domain in ("Runtime", "Log", "Network", "Page"):
            self._call(f"{domain}.enable", session=s, deadline=deadline)
        self._call("Emulation.setDeviceMetricsOverride",
                   {"width": self.width, "height": self.height, "deviceScaleFactor": 1,
                    "mobile": False}, s, deadline)
        self._loaded.discard(s)
        nav = self._call("Page.navigate", {"url": url}, s, deadline)
        if nav.get("errorText"):
            raise RuntimeError(f"navigating to {path} failed: {nav['errorText']}")
        while s not in self._loaded:
            if time.monotonic() >= deadline:
                raise self._fail(TimeoutError, f"{path}: no load event within {self.timeout_s}s")
            self._pump(deadline)
        last = None
        while True:
            try:
                last = self.evaluate(ready_expression)
            except RuntimeError as e:  # e.g. the page's globals are not defined yet
                last = f"threw: {e}"
            if last is True:
                return load
            if time.monotonic() >= deadline:
                raise TimeoutError(f"{path}: {ready_expression!r} not true after "
                                   f"{self.timeout_s}s; last value {last!r}")
            self._pump(min(deadline, time.monotonic() + 0.05))  # sleep, but keep collecting

    def _current(self) -> str:
        if not self._session:
            raise RuntimeError("no page open; call open() first")
        return self._session

    def evaluate(self, expression: str, await_promise: bool = False):
        r = self._call("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                            "awaitPromise": await_promise}, self._current())
        if "exceptionDetails" in r:
            d = r["exceptionDetails"]
            raise RuntimeError(f"evaluate threw: {d.get('text', '')} "
                               f"{d.get('exception', {}).get('description', '')}".strip())
        return r["result"].get("value")

    def screenshot(self, path: str | None = None, full_page: bool = True) -> bytes:
        s = self._current()
        params: dict = {"format": "png"}
        if full_page:
            size = self._call("Page.getLayoutMetrics", session=s)["cssContentSize"]
            params["captureBeyondViewport"] = True
            params["clip"] = {"x": 0, "y": 0, "width": math.ceil(size["width"]),
                              "height": math.ceil(size["height"]), "scale": 1}
        png = base64.b64decode(self._call("Page.captureScreenshot", params, s)["data"])
        if path:
            Path(path).write_bytes(png)
        return png

    def colour_stats(self, png: bytes) -> dict:
        """Colour statistics of a PNG, decoded by the browser in the current page.

        Pixels are quantised to 4 bits per channel (alpha ignored).  The image is
        decoded from a Blob via createImageBitmap rather than loaded through an
        <img> data: URL, so a page's Content-Security-Policy cannot block it."""
        js = """(async () => {
          const bin = atob(%s), bytes = new Uint8Array(bin.length);
          for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
          const bmp = await createImageBitmap(new Blob([bytes], {type: 'image/png'}),
                                              {colorSpaceConversion: 'none', premultiplyAlpha: 'none'});
          const ctx = new OffscreenCanvas(bmp.width, bmp.height).getContext('2d', {willReadFrequently: true});
          ctx.drawImage(bmp, 0, 0);
          const px = ctx.getImageData(0, 0, bmp.width, bmp.height).data;
          const counts = new Uint32Array(4096);
          for (let i = 0; i < px.length; i += 4)
            counts[((px[i] >> 4) << 8) | (px[i + 1] & 0xf0) | (px[i + 2] >> 4)]++;
          let distinct = 0, top = 0;
          for (const c of counts) { if (c) distinct++; if (c > top) top = c; }
          return {width: bmp.width, height: bmp.height, distinct_colours: distinct,
                  dominant_fraction: top / Math.max(1, bmp.width * bmp.height)};
        })()""" % json.dumps(base64.b64encode(png).decode())
        return self.evaluate(js, await_promise=True)


if __name__ == "__main__":
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as d, Browser(timeout_s=20) as b:
        page = Path(d, "page.html")
        page.write_text("<!doctype html><html><body style='margin:0'>"
                        "<h1 style='color:#c00'>Hello</h1><div style='height:2000px;"
                        "background:linear-gradient(#00f,#0f0)'></div>"
                        "<img src='http://example.invalid/x.png'>"
                        "<script>console.error('boom');"
                        "document.documentElement.dataset.ready='true';</script></body></html>")
        load = b.open(str(page))
        print("console_errors:", load.console_errors)
        print("exceptions:", load.exceptions)
        print("requests:", load.requests)
        print("external:", load.external_requests(load.url))
        assert "boom" in load.console_errors, load.console_errors
        assert load.external_requests(str(page)) == ["http://example.invalid/x.png"]
        png = b.screenshot(os.path.join(d, "shot.png"))
        width, height = int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")
        print(f"screenshot: {len(png)} bytes, {width}x{height}")
        assert width == 1280 and height > 2000, (width, height)
        stats = b.colour_stats(png)
        print("colour_stats:", stats)
        assert (stats["width"], stats["height"]) == (width, height)
        assert stats["distinct_colours"] > 20 and 0 < stats["dominant_fraction"] < 0.5, stats

        white = Path(d, "white.html")
        white.write_text("<!doctype html><body style='background:#fff'>"
                         "<script>document.documentElement.dataset.ready='true'</script>")
        wload = b.open(str(white))
        wstats = b.colour_stats(b.screenshot())
        print("white:", wstats, "errors:", wload.console_errors, "external:",
              wload.external_requests(str(white)))
        assert wstats["dominant_fraction"] > 0.99 and not wload.external_requests(str(white))

        never = Path(d, "never.html")
        never.write_text("<!doctype html><p>never ready</p>")
        b.timeout_s, t1 = 2, time.monotonic()
        try:
            b.open(str(never))
            raise AssertionError("expected TimeoutError")
        except TimeoutError as e:
            took = time.monotonic() - t1
            print(f"TimeoutError after {took:.2f}s: {e}")
            assert took < 3
    print(f"self-test passed in {time.monotonic() - t0:.2f}s")


def page_test_arguments(description: str):
    """The page tests' command line (--xgauge BIN --source DIR --work DIR
    [--chromium BIN]): the work folder made afresh and entered; returns the
    arguments with xgauge and source as absolute paths."""
    import argparse

    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--xgauge", required=True)
    parser.add_argument("--source", required=True)
    parser.add_argument("--work", required=True)
    parser.add_argument("--chromium", default="chromium")
    args = parser.parse_args()
    args.xgauge = os.path.abspath(args.xgauge)
    args.source = os.path.abspath(args.source)
    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    os.chdir(args.work)
    return args
