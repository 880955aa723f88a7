"""Headless Chromium driven through the DevTools protocol over a pipe (standard library only).

Chromium started with --remote-debugging-pipe reads commands on its file descriptor 3 and
writes answers and events on 4, each a JSON message ended by a NUL byte.

    with Browser(width=1000, height=700) as b:
        b.open("file:///.../run.html")
        b.wait_for("window.mbdaeReady === true")
        png = b.screenshot()                    # PNG bytes
        value = b.evaluate("window.mbdae.time()")
"""
import base64
import json
import os
import shutil
import subprocess
import tempfile
import time


def find_chromium():
    """The Chromium program (Debian's chromium), or None."""
    for name in ("chromium", "chromium-browser", "chromium-headless-shell"):
        path = shutil.which(name)
        if path:
            return path
    return None


class BrowserError(RuntimeError):
    pass


class Browser:
    def __init__(self, width=1000, height=700, program=None, timeout=60):
        self.width, self.height, self.timeout = width, height, timeout
        self.program = program or find_chromium()
        if not self.program:
            raise BrowserError("chromium not found (Debian: apt-get install chromium)")
        self._next_id = 0
        self._buffer = b""
        self.session = None
        self.console = []

    def __enter__(self):
        self.profile = tempfile.mkdtemp(prefix="mbdae-chromium-")
        to_browser_r, to_browser_w = os.pipe()
        from_browser_r, from_browser_w = os.pipe()

        def child_fds():  # the browser's fds 3 (commands) and 4 (answers)
            r, w = os.dup(to_browser_r), os.dup(from_browser_w)  # above 4: no clash with 3, 4
            os.dup2(r, 3)
            os.dup2(w, 4)
            os.set_inheritable(3, True)
            os.set_inheritable(4, True)

        args = [self.program, "--headless=new", "--remote-debugging-pipe", "--no-sandbox",
                "--no-first-run", "--no-default-browser-check", "--disable-extensions",
                "--disable-background-networking", "--disable-dev-shm-usage",
                "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
                "--hide-scrollbars", "--mute-audio", "--force-device-scale-factor=1",
                f"--window-size={self.width},{self.height}",
                f"--user-data-dir={self.profile}", "about:blank"]
        # The browser is not ours: it runs without the sanitizer runtime that
        # scripts/sanitize.sh preloads into the Python tests (under it Chromium does not
        # answer within the time limit).
        env = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "ASAN_OPTIONS",
                                                                 "LSAN_OPTIONS", "UBSAN_OPTIONS")}
        self.proc = subprocess.Popen(args, preexec_fn=child_fds, pass_fds=(3, 4), env=env,
                                     stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL)
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._out = os.fdopen(to_browser_w, "wb", buffering=0)
        self._in = from_browser_r
        return self

    def __exit__(self, *exc):
        try:
            self.call("Browser.close", session=False)
        except Exception:
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self._out.close()
        os.close(self._in)
        shutil.rmtree(self.profile, ignore_errors=True)

    # ---- the protocol ------------------------------------------------------------------
    def _read_message(self, deadline):
        import select
        while b"\0" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0:
                raise BrowserError("no answer from chromium within the time limit")
            ready, _, _ = select.select([self._in], [], [], left)
            if not ready:
                continue
            chunk = os.read(self._in, 1 << 20)
            if not chunk:
                raise BrowserError("chromium closed the pipe (exit code %s)" % self.proc.poll())
            self._buffer += chunk
        message, self._buffer = self._buffer.split(b"\0", 1)
        return json.loads(message)

    def call(self, method, params=None, session=True):
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params or {}}
        if session and self.session:
            message["sessionId"] = self.session
        self._out.write(json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + self.timeout
        while True:
            answer = self._read_message(deadline)
            if answer.get("method") == "Runtime.consoleAPICalled":
                self.console.append(" ".join(str(a.get("value", a.get("description", "")))
                                             for a in answer["params"].get("args", [])))
            if answer.get("method") == "Runtime.exceptionThrown":
                details = answer["params"]["exceptionDetails"]
                self.console.append("exception: " + details.get("exception", {}).get("description", details.get("text", "")))
            if answer.get("id") == self._next_id:
                if "error" in answer:
                    raise BrowserError(f"{method}: {answer['error']}")
                return answer.get("result", {})

    def open(self, url):
        """A new page at url, its session attached; the viewport width x height, scale 1."""
        target = self.call("Target.createTarget", {"url": "about:blank"}, session=False)["targetId"]
        self.session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True},
                                 session=False)["sessionId"]
        self.call("Runtime.enable")
        self.call("Page.enable")
        self.call("Emulation.setDeviceMetricsOverride",
                  {"width": self.width, "height": self.height, "deviceScaleFactor": 1, "mobile": False})
        self.call("Page.navigate", {"url": url})

    def evaluate(self, expression):
        result = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                                "awaitPromise": True})
        if "exceptionDetails" in result:
            raise BrowserError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def wait_for(self, expression, timeout=60):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                if self.evaluate(expression):
                    return
            except BrowserError:
                pass
            time.sleep(0.1)
        raise BrowserError(f"'{expression}' not true after {timeout} s; console: {self.console}")

    def screenshot(self):
        data = self.call("Page.captureScreenshot", {"format": "png", "captureBeyondViewport": False})["data"]
        return base64.b64decode(data)
