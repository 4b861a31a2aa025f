"""Check a report in a real browser: headless Chromium driven over the DevTools protocol.

Chromium is started with `--remote-debugging-pipe`: the protocol's JSON messages go through
two pipes (file descriptors 3 and 4 of the browser, each message ended by a NUL byte), so the
driver needs only the standard library (no websocket client, no browser-automation package).
Every request that is not a `file:` or `data:` URL is recorded, and a dead proxy makes it fail
anyway, so a report that needed the network would show it. JavaScript exceptions, console
errors and browser log errors are collected; `check_report` fails on any of them.

    python -m sportsngen.report check outputs/.../report.html --out docs/figures/report
"""

from __future__ import annotations

import base64
import json
import os
import queue
import shutil
import subprocess
import tempfile
import threading
import time
from pathlib import Path

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "chrome")


class BrowserError(RuntimeError):
    """The browser could not be started or did not answer in time."""


def find_chromium() -> str | None:
    """Path of a Chromium-family browser on the PATH, or None."""
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    return None


class Chromium:
    """One headless Chromium with one page, driven over the DevTools protocol (a context
    manager). `events` keeps every protocol event received."""

    def __init__(self, binary: str | None = None, width: int = 1280, height: int = 900,
                 timeout_s: float = 20.0):
        binary = binary or find_chromium()
        if binary is None:
            raise BrowserError(f"no Chromium on the PATH (looked for {', '.join(BROWSERS)})")
        self.timeout_s = timeout_s
        self.events: list[dict] = []
        self._profile = tempfile.TemporaryDirectory(prefix="sportsngen-chromium-")
        to_browser_r, self._to_browser = os.pipe()
        self._from_browser, from_browser_w = os.pipe()

        def child_fds() -> None:
            # The browser reads fd 3 and writes fd 4. dup2 onto them makes them inheritable
            # (Python's own fds are not, so close_fds=False passes only these two); going
            # through fresh copies first, because dup2 of an fd onto itself changes nothing.
            r, w = os.dup(to_browser_r), os.dup(from_browser_w)
            os.dup2(r, 3)
            os.dup2(w, 4)

        args = [binary, "--headless", "--remote-debugging-pipe", "--no-sandbox",
                "--disable-gpu", "--no-first-run", "--no-default-browser-check",
                "--disable-extensions", "--mute-audio", "--hide-scrollbars",
                f"--user-data-dir={self._profile.name}",
                "--proxy-server=127.0.0.1:9", "--proxy-bypass-list=<-loopback>",
                f"--window-size={width},{height}", "about:blank"]
        self.proc = subprocess.Popen(args, close_fds=False, preexec_fn=child_fds,
                                     stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL)
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._inbox: queue.Queue = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()
        self._next_id = 0
        self.session = None
        try:
            target = next(t for t in self.send("Target.getTargets")["targetInfos"]
                          if t["type"] == "page")
            self.session = self.send("Target.attachToTarget", targetId=target["targetId"],
                                     flatten=True, session=None)["sessionId"]
            for domain in ("Page", "Runtime", "Log", "Network"):
                self.send(f"{domain}.enable")
            self.send("Emulation.setDeviceMetricsOverride", width=width, height=height,
                      deviceScaleFactor=1, mobile=False)
        except BaseException:
            self.close()      # never leave a browser behind
            raise

    def _read(self) -> None:
        buf = b""
        with os.fdopen(self._from_browser, "rb", buffering=0) as pipe:
            while True:
                chunk = pipe.read(65536)
                if not chunk:
                    self._inbox.put(None)
                    return
                buf += chunk
                while b"\0" in buf:
                    msg, buf = buf.split(b"\0", 1)
                    self._inbox.put(json.loads(msg))

    def _take(self, deadline: float) -> dict:
        try:
            msg = self._inbox.get(timeout=max(0.01, deadline - time.monotonic()))
        except queue.Empty:
            raise BrowserError(f"Chromium did not answer within {self.timeout_s} s") from None
        if msg is None:
            raise BrowserError("Chromium closed the DevTools pipe (did it crash?)")
        return msg

    def send(self, method: str, session: str | None | bool = True, **params) -> dict:
        """Call a protocol method (on the page's session unless `session` is None) and return
        its result; events that arrive meanwhile go to `events`."""
        self._next_id += 1
        msg = {"id": self._next_id, "method": method, "params": params}
        sid = self.session if session is True else session
        if sid:
            msg["sessionId"] = sid
        os.write(self._to_browser, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + self.timeout_s
        while True:
            reply = self._take(deadline)
            if reply.get("id") == self._next_id:
                if "error" in reply:
                    raise BrowserError(f"{method}: {reply['error'].get('message')}")
                return reply.get("result", {})
            if "method" in reply:
                self.events.append(reply)

    def wait_event(self, method: str, timeout_s: float | None = None) -> dict:
        """The first event `method` already received or arriving within the timeout."""
        for ev in self.events:
            if ev["method"] == method:
                return ev
        deadline = time.monotonic() + (timeout_s or self.timeout_s)
        while True:
            msg = self._take(deadline)
            if "method" in msg:
                self.events.append(msg)
                if msg["method"] == method:
                    return msg

    def pump(self, seconds: float) -> None:
        """Let the page run for `seconds`, collecting events."""
        wait = f"new Promise(r => setTimeout(r, {seconds * 1000:.0f}))"
        self.send("Runtime.evaluate", expression=wait, awaitPromise=True)

    def evaluate(self, expression: str):
        res = self.send("Runtime.evaluate", expression=expression, returnByValue=True,
                        awaitPromise=True)
        if "exceptionDetails" in res:
            raise BrowserError(f"evaluating {expression[:60]!r}: "
                               f"{res['exceptionDetails'].get('text')}")
        return res["result"].get("value")

    def open(self, path: str | Path) -> None:
        url = Path(path).resolve().as_uri()
        self.events = [e for e in self.events if e["method"] != "Page.loadEventFired"]
        self.send("Page.navigate", url=url)
        self.wait_event("Page.loadEventFired")

    def click(self, selector: str) -> None:
        """A real left click (mouse pressed and released) at the centre of `selector`."""
        xy = self.evaluate(
            f"(() => {{ const e = document.querySelector({json.dumps(selector)});"
            " if (!e) return null; e.scrollIntoView({block: 'center'});"
            " const r = e.getBoundingClientRect();"
            " return [r.x + r.width / 2, r.y + r.height / 2]; })()")
        if xy is None:
            raise BrowserError(f"nothing matches {selector!r} on the page")
        for kind in ("mouseMoved", "mousePressed", "mouseReleased"):
            self.send("Input.dispatchMouseEvent", type=kind, x=xy[0], y=xy[1], button="left",
                      clickCount=1)

    def screenshot(self, path: str | Path, selector: str | None = None) -> Path:
        """PNG of the element `selector` (the whole page when None)."""
        if selector is None:
            size = self.evaluate("[document.documentElement.scrollWidth,"
                                 " document.documentElement.scrollHeight]")
            clip = {"x": 0, "y": 0, "width": size[0], "height": size[1], "scale": 1}
        else:
            clip = self.evaluate(
                f"(() => {{ const e = document.querySelector({json.dumps(selector)});"
                " if (!e) return null; const r = e.getBoundingClientRect();"
                " return {x: r.x + window.scrollX, y: r.y + window.scrollY,"
                " width: r.width, height: r.height, scale: 1}; })()")
            if clip is None:
                raise BrowserError(f"nothing matches {selector!r} on the page")
        shot = self.send("Page.captureScreenshot", format="png", clip=clip,
                         captureBeyondViewport=True)
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(base64.b64decode(shot["data"]))
        return path

    def problems(self) -> dict[str, list[str]]:
        """JavaScript errors (exceptions, console errors, log errors) and requests that left
        the file, from the events so far."""
        errors, external = [], []
        for ev in self.events:
            m, p = ev["method"], ev.get("params", {})
            if m == "Runtime.exceptionThrown":
                d = p.get("exceptionDetails", {})
                what = d.get("exception", {}).get("description") or d.get("text")
                errors.append(f"exception: {what}")
            elif m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
                errors.append("console: " + " ".join(str(a.get("value", a.get("description")))
                                                     for a in p.get("args", [])))
            elif m == "Log.entryAdded" and p.get("entry", {}).get("level") == "error":
                errors.append(f"log: {p['entry'].get('text')} ({p['entry'].get('url', '')})")
            elif m == "Network.requestWillBeSent":
                url = p.get("request", {}).get("url", "")
                if not url.startswith(("file:", "data:", "about:")):
                    external.append(url)
        return {"errors": errors, "external_requests": external}

    def close(self) -> None:
        try:
            self.send("Browser.close", session=None)
        except BrowserError:
            pass
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._to_browser)
        self._profile.cleanup()

    def __enter__(self) -> Chromium:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def check_report(html: str | Path, out_dir: str | Path | None = None,
                 binary: str | None = None, rally_play_s: float = 0.0,
                 whatif_index: int = 0) -> dict:
    """Open a report, take its screenshots into `out_dir` (the timeline; the rally of the first
    key moment that has one, after a click on the timeline, `rally_play_s` after the check that
    its animation runs; what-if shot number `whatif_index`; the whole page) and return what
    was seen: errors, external requests, screenshot paths, whether the rally animation
    advanced, timings. Raises nothing for a bad page: the caller decides (`assert_clean`)."""
    out_dir = Path(out_dir) if out_dir is not None else None
    seen: dict = {"screenshots": [], "animated": None, "has_rallies": False,
                  "has_whatif": False}
    t0 = time.monotonic()
    with Chromium(binary) as browser:
        def snap(name: str, selector: str | None = None) -> None:
            if out_dir is not None:
                seen["screenshots"].append(str(browser.screenshot(out_dir / name, selector)))

        browser.open(html)
        browser.pump(0.3)
        seen["timeline_rects"] = browser.evaluate(
            "document.querySelectorAll('#timeline svg rect').length")
        snap("timeline.png", "#timeline-section")
        # The first key moment whose point has a rally (else the first key moment).
        target = browser.evaluate(
            "(() => { const d = JSON.parse(document.getElementById('match-data').textContent);"
            " const ms = Array.from(document.querySelectorAll('#timeline .moment'));"
            " const ok = ms.filter(m => d.rallies"
            "   && (d.points.rallies[+m.dataset.i] || []).length);"
            " const m = ok[0] || ms[0]; return m ? ms.indexOf(m) : -1; })()")
        if target is not None and target >= 0:
            browser.click(f"#timeline .moment:nth-of-type({target + 1}) circle")
            browser.pump(0.1)
            seen["selected_point"] = browser.evaluate("window.sportsngenReport.ui.sel")
            seen["has_rallies"] = bool(browser.evaluate("!!window.sportsngenReport.ui.rally"))
            if seen["has_rallies"]:  # the rally plays by itself once its point is clicked
                f1 = browser.evaluate("window.sportsngenReport.ui.frame")
                browser.pump(0.3)
                f2 = browser.evaluate("window.sportsngenReport.ui.frame")
                seen["animated"] = f2 > f1
                seen["frames_seen"] = [f1, f2]
                browser.pump(rally_play_s)
            snap("rally.png", "#point-section")
        n_whatif = browser.evaluate("document.querySelectorAll('.wi-list button').length")
        seen["has_whatif"] = bool(n_whatif)
        if seen["has_whatif"]:
            browser.click(f".wi-list button:nth-of-type({min(whatif_index, n_whatif - 1) + 1})")
            browser.pump(0.4)
            seen["whatif_bars"] = browser.evaluate(
                "document.querySelectorAll('#whatif-chart svg rect').length")
            snap("whatif.png", ".row")
        snap("page.png")
        browser.pump(0.1)
        seen.update(browser.problems())
    seen["seconds"] = round(time.monotonic() - t0, 2)
    return seen


def assert_clean(seen: dict) -> None:
    """AssertionError listing what `check_report` found wrong."""
    bad = [f"JavaScript error: {e}" for e in seen["errors"]]
    bad += [f"network request: {u}" for u in seen["external_requests"]]
    if seen["has_rallies"] and not seen["animated"]:
        bad.append(f"the rally animation did not advance (frames {seen.get('frames_seen')})")
    if bad:
        raise AssertionError("report check failed:\n  " + "\n  ".join(bad))
