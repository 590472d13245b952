"""Real parts for the browser tests of `fiberfem web` (tests/web/web_test.py): a `fiberfem
serve` or `replay` on the DDS loopback profile, the bridge started through `fiberfem web`,
Debian's headless Chromium driven by Selenium through Debian's chromedriver, and the Python
client as the independent witness of what the service did. Traffic stays on 127.0.0.1."""

import io
import os
import re
import signal
import socket
import subprocess
import tempfile
import time

import numpy as np
from PIL import Image
from selenium import webdriver
from selenium.webdriver.chrome.service import Service

from fiberfem_client import Client

CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"
BACKGROUND = np.array([0x1D, 0x20, 0x26])  # the page's background (clients/web/src/view.js)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Proc:
    """A background process with its output in a file; stopped (SIGTERM, then SIGKILL) at close."""

    def __init__(self, args, log_path, env=None):
        self.log_path = log_path
        self._log = open(log_path, "wb")
        self.p = subprocess.Popen(args, stdout=self._log, stderr=subprocess.STDOUT, env=env)

    def output(self) -> str:
        with open(self.log_path, "rb") as f:
            return f.read().decode(errors="replace")

    def wait_for_output(self, pattern: str, timeout: float = 20) -> re.Match:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = re.search(pattern, self.output())
            if m:
                return m
            if self.p.poll() is not None:
                break
            time.sleep(0.05)
        raise AssertionError(f"no '{pattern}' from {self.p.args[:3]} (exit {self.p.poll()}):\n{self.output()}")

    def close(self):
        if self.p.poll() is None:
            self.p.send_signal(signal.SIGTERM)
            try:
                self.p.wait(10)
            except subprocess.TimeoutExpired:
                self.p.kill()
                self.p.wait()
        self._log.close()


class Rig:
    """One test's service, bridge, browser and witness client; close() stops them all."""

    def __init__(self, fiberfem_bin: str, source_dir: str):
        self.bin, self.source_dir = fiberfem_bin, source_dir
        self.dir = tempfile.mkdtemp(prefix="fiberfem-web-")
        self.env = dict(os.environ, CYCLONEDDS_URI=f"file://{source_dir}/configs/dds/loopback.xml")
        os.environ["CYCLONEDDS_URI"] = self.env["CYCLONEDDS_URI"]
        self.procs, self.driver, self.client = [], None, None
        self.run_id = f"web-test-{os.getpid()}"
        self.port = None

    def start(self, args, name, env=None) -> Proc:
        p = Proc(args, os.path.join(self.dir, name + ".log"), env or self.env)
        self.procs.append(p)
        return p

    def serve(self, *extra) -> str:
        self.start([self.bin, "serve", "--builtin", "heart", "--run-id", self.run_id, "--threads", "1", *extra], "serve")
        self.witness().resolve_run(self.run_id, wait_s=30)
        return self.run_id

    def replay(self, archive: str, *extra) -> str:
        self.start([self.bin, "replay", archive, "--run-id", self.run_id, *extra], "replay")
        self.witness().resolve_run(self.run_id, wait_s=30)
        return self.run_id

    def bridge(self, *extra, env=None) -> Proc:
        self.port = free_port()
        b = self.start([self.bin, "web", "--port", str(self.port), "--run", self.run_id, *extra], "web", env)
        b.wait_for_output(r"fiberfem web: serving http://\S+")
        return b

    def witness(self) -> Client:
        if self.client is None:
            self.client = Client(client_id=f"web-test-witness-{os.getpid()}")
        return self.client

    def browser(self, query: str = "", width: int = 1000, height: int = 640):
        self.driver = open_page(self.port, query, width, height)
        return self.driver

    def js(self, script: str, *args):
        return self.driver.execute_script(script, *args)

    def wait_js(self, predicate: str, timeout: float = 20, what: str = ""):
        """Waits until the JavaScript expression is truthy; returns its value."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            v = self.js(f"return ({predicate});")
            if v:
                return v
            time.sleep(0.05)
        raise AssertionError(f"timed out waiting for {what or predicate}; page messages: {self.messages()}")

    def messages(self) -> list:
        return self.js("return [...document.querySelectorAll('#messages li')].map(li => li.className + ': ' + li.textContent);")

    def frames(self) -> int:
        return self.js("return window.fiberfem ? window.fiberfem.stats.frames : 0;")

    def canvas_image(self) -> np.ndarray:
        """The heart's canvas as an (h, w, 3) uint8 array (a screenshot of the element)."""
        png = self.driver.find_element("id", "view").screenshot_as_png
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(np.int16)

    def close(self):
        if self.driver is not None:
            self.driver.quit()
        for p in reversed(self.procs):
            p.close()


def open_page(port: int, query: str = "", width: int = 1000, height: int = 640) -> webdriver.Chrome:
    """Debian's headless Chromium (WebGL in SwiftShader, no GPU here) on the bridge's page."""
    o = webdriver.ChromeOptions()
    for a in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", f"--window-size={width},{height}",
              "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-proxy-server"):
        o.add_argument(a)
    o.binary_location = CHROMIUM
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=o)
    driver.set_script_timeout(30)
    driver.get(f"http://127.0.0.1:{port}/{query}")
    return driver


def silhouette(img: np.ndarray) -> np.ndarray:
    """Pixels that are not the page background (the heart and its colour bar)."""
    return np.abs(img - BACKGROUND).sum(axis=2) > 24
