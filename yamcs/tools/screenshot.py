#!/usr/bin/env python3
"""Screenshot of a Yamcs web page with headless Chromium, driven over the DevTools
protocol (websocket-client, a yamcs-client dependency): the page is given real time to
connect its websocket and receive live values before the capture, which Chromium's
one-shot --screenshot does not wait for.

    python3 yamcs/tools/screenshot.py URL OUT.png [--wait-s 12] [--size 1500x1000] [--user observer]

With --user the browser is logged in as that user of yamcs/etc/users.yaml (Yamcs'
security is on): the tokens of a password login are set as the cookies the web UI
keeps them in (access_token, refresh_token).

From Python (yamcs/tools/e2e.py): `with Browser(size) as b: b.login(...); b.open(url)`,
then `b.text()`, `b.drawn()` (the texts drawn on canvases: Yamcs web draws OPI displays
on a canvas), `b.click(selector)`, `b.shot(path)`.
"""

from __future__ import annotations

import argparse
import base64
import json
import shutil
import subprocess
import sys
import tempfile
import time
import urllib.request

import websocket

from users import access_token

FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
]

# Installed in every page before its own scripts: records every text drawn on a canvas
# (CanvasRenderingContext2D.fillText), so that a test can read what a display shows.
RECORD_CANVAS_TEXT = """
(() => {
  window.__m2drawn = new Set();
  const fill = CanvasRenderingContext2D.prototype.fillText;
  CanvasRenderingContext2D.prototype.fillText = function (text, ...rest) {
    window.__m2drawn.add(String(text));
    return fill.call(this, text, ...rest);
  };
})();
"""


class Browser:
    """Headless Chromium driven over the DevTools protocol (one page)."""

    def __init__(self, size: str = "1500x1000", port: int = 9333):
        self.w, self.h = (int(x) for x in size.split("x"))
        self.port = port
        self.profile = tempfile.mkdtemp(prefix="m2-chromium-")
        self.chrome = None
        self.ws = None
        self.n = 0
        self.errors: list[str] = []

    def __enter__(self) -> "Browser":
        self.chrome = subprocess.Popen(
            ["chromium", *FLAGS, f"--user-data-dir={self.profile}", f"--window-size={self.w},{self.h}",
             f"--remote-debugging-port={self.port}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )
        targets = None
        for _ in range(100):
            try:
                targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{self.port}/json", timeout=1))
                if any(t.get("type") == "page" for t in targets):
                    break
            except OSError:
                pass
            time.sleep(0.1)
        page = next(t for t in targets or [] if t.get("type") == "page")
        self.ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=30)
        self.call("Emulation.setDeviceMetricsOverride", width=self.w, height=self.h,
                  deviceScaleFactor=1, mobile=False)
        self.call("Page.enable")
        self.call("Runtime.enable")
        self.call("Page.addScriptToEvaluateOnNewDocument", source=RECORD_CANVAS_TEXT)
        return self

    def __exit__(self, *exc):
        if self.ws:
            self.ws.close()
        if self.chrome:
            self.chrome.terminate()
            try:
                self.chrome.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.chrome.kill()
        shutil.rmtree(self.profile, ignore_errors=True)

    def call(self, method: str, **params):
        self.n += 1
        self.ws.send(json.dumps({"id": self.n, "method": method, "params": params}))
        while True:
            m = json.loads(self.ws.recv())
            if m.get("id") == self.n:
                return m.get("result", {})
            # Uncaught exceptions and console errors of the page, for the caller.
            if m.get("method") == "Runtime.exceptionThrown":
                d = m["params"]["exceptionDetails"]
                self.errors.append(d.get("exception", {}).get("description") or d.get("text", ""))
            elif m.get("method") == "Runtime.consoleAPICalled" and m["params"].get("type") in ("error", "warning"):
                self.errors.append(" ".join(str(a.get("value", a.get("description", "")))
                                            for a in m["params"].get("args", [])))

    def login(self, user: str, origin: str):
        """Logs the browser in as `user` of yamcs/etc/users.yaml on Yamcs at `origin`."""
        token = access_token(user, origin.split("//", 1)[1])
        for name in ("access_token", "refresh_token"):
            if token.get(name):
                self.call("Network.setCookie", name=name, value=token[name], url=origin + "/", path="/")

    def open(self, url: str):
        self.call("Page.navigate", url=url)

    def eval(self, expression: str):
        r = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        return r.get("result", {}).get("value")

    def text(self) -> str:
        """The page's visible text."""
        return self.eval("document.body ? document.body.innerText : ''") or ""

    def drawn(self, reset: bool = False) -> list[str]:
        """Texts drawn on the page's canvases since it loaded (or the last reset)."""
        out = self.eval("Array.from(window.__m2drawn || [])") or []
        if reset:
            self.eval("window.__m2drawn && window.__m2drawn.clear()")
        return out

    def click(self, selector: str) -> bool:
        """Clicks the first element matching the CSS selector; False if there is none."""
        return bool(self.eval(
            f"(() => {{ const e = document.querySelector({json.dumps(selector)}); "
            "if (!e) return false; e.click(); return true; })()"))

    def wait_for(self, expression: str, timeout_s: float, poll_s: float = 0.5):
        """Evaluates `expression` until it is truthy (returned), at most `timeout_s`
        (then None); the wall clock only bounds the wait."""
        t0 = time.time()
        while True:
            v = self.eval(expression)
            if v:
                return v
            if time.time() - t0 > timeout_s:
                return None
            time.sleep(poll_s)

    def dismiss_banners(self) -> int:
        """Closes Yamcs web's message banners (e.g. "A gap was detected in one of the data
        feeds", shown when values arrive faster than the page redraws); returns how many."""
        return self.eval(
            "(() => { const b = Array.from(document.querySelectorAll('button'))"
            ".filter(e => e.innerText.trim() === 'close' && e.closest('.message-bar, ya-message-bar, app-message-bar'));"
            " b.forEach(e => e.click()); return b.length; })()") or 0

    def shot(self, path: str):
        shot = self.call("Page.captureScreenshot", format="png")
        with open(path, "wb") as f:
            f.write(base64.b64decode(shot["data"]))


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("url")
    ap.add_argument("out")
    ap.add_argument("--wait-s", type=float, default=12.0)
    ap.add_argument("--size", default="1500x1000")
    ap.add_argument("--port", type=int, default=9333)
    ap.add_argument("--user", help="log in as this user of yamcs/etc/users.yaml")
    ap.add_argument("--expect", action="append", default=[],
                    help="text the page must show (else exit 1)")
    ap.add_argument("--forbid", action="append", default=[],
                    help="text the page must not show (else exit 1)")
    a = ap.parse_args()
    with Browser(a.size, a.port) as b:
        if a.user:
            b.login(a.user, "/".join(a.url.split("/")[:3]))
        b.open(a.url)
        time.sleep(a.wait_s)
        b.shot(a.out)
        body = b.text()
        print(f"screenshot: {a.out} ({len(body)} characters of text on the page)")
    ok = bool(body.strip())
    for t in a.expect:
        found = t in body
        print(f"  {'ok  ' if found else 'FAIL'} the page shows {t!r}")
        ok &= found
    for t in a.forbid:
        found = t in body
        print(f"  {'FAIL' if found else 'ok  '} the page does not show {t!r}")
        ok &= not found
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
