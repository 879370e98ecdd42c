#!/usr/bin/env python3
"""Screenshot of a Yamcs web page with headless Chromium, driven over the DevTools
protocol (websocket-client, a yamcs-client dependency): the page is given real time to
connect its websocket and receive live values before the capture, which Chromium's
one-shot --screenshot does not wait for.

    python3 yamcs/tools/screenshot.py URL OUT.png [--wait-s 12] [--size 1500x1000] [--user observer]

With --user the browser is logged in as that user of yamcs/etc/users.yaml (Yamcs'
security is on): the tokens of a password login are set as the cookies the web UI
keeps them in (access_token, refresh_token).
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
    w, h = (int(x) for x in a.size.split("x"))
    profile = tempfile.mkdtemp(prefix="m2-chromium-")
    chrome = subprocess.Popen(
        ["chromium", *FLAGS, f"--user-data-dir={profile}", f"--window-size={w},{h}",
         f"--remote-debugging-port={a.port}", "about:blank"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    try:
        targets = None
        for _ in range(100):
            try:
                targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{a.port}/json", timeout=1))
                if any(t.get("type") == "page" for t in targets):
                    break
            except OSError:
                pass
            time.sleep(0.1)
        page = next(t for t in targets or [] if t.get("type") == "page")
        ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=30)
        n = 0

        def call(method, **params):
            nonlocal n
            n += 1
            ws.send(json.dumps({"id": n, "method": method, "params": params}))
            while True:
                m = json.loads(ws.recv())
                if m.get("id") == n:
                    return m.get("result", {})

        call("Emulation.setDeviceMetricsOverride", width=w, height=h, deviceScaleFactor=1, mobile=False)
        call("Page.enable")
        if a.user:
            origin = "/".join(a.url.split("/")[:3])
            token = access_token(a.user, origin.split("//", 1)[1])
            for name in ("access_token", "refresh_token"):
                if token.get(name):
                    call("Network.setCookie", name=name, value=token[name], url=origin + "/", path="/")
        call("Page.navigate", url=a.url)
        time.sleep(a.wait_s)
        shot = call("Page.captureScreenshot", format="png")
        with open(a.out, "wb") as f:
            f.write(base64.b64decode(shot["data"]))
        text = call("Runtime.evaluate", expression="document.body.innerText", returnByValue=True)
        body = text.get("result", {}).get("value", "")
        print(f"screenshot: {a.out} ({len(body)} characters of text on the page)")
        ws.close()
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
    finally:
        chrome.terminate()
        try:
            chrome.wait(timeout=10)
        except subprocess.TimeoutExpired:
            chrome.kill()
        shutil.rmtree(profile, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
