"""The studio in a real browser: ``studio(*args)`` starts ``genr8 <args>`` (a run with ``--studio``
or ``genr8 studio``), reads the URL it prints, and opens it in headless Chromium through Selenium;
the test's end closes the browser and stops the command. Skips without chromium, chromedriver,
selenium or Pillow (.ci/run installs them)."""

from __future__ import annotations

import contextlib
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

CHROMIUM = shutil.which("chromium")
DRIVER = shutil.which("chromedriver")


def wait(what: str, check: Callable[[], Any], timeout: float) -> Any:
    """``check()``'s first true value, asked every 0.25 s; an ``AssertionError`` naming ``what`` after
    ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = check()
        if value:
            return value
        time.sleep(0.25)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def _browser() -> Any:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1600,1000",
                "--enable-unsafe-swiftshader", "--use-angle=swiftshader", "--disable-background-networking"):
        options.add_argument(arg)
    options.binary_location = CHROMIUM
    return webdriver.Chrome(service=Service(DRIVER), options=options)


class Studio:
    """A running ``genr8`` command with the studio, its output ``lines`` (read as they come) and the
    page open in ``driver``."""

    def __init__(self, args: tuple[str, ...]) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "genr8_dist.cli", *args],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.lines: list[str] = []
        stdout = self.proc.stdout
        assert stdout is not None
        threading.Thread(target=lambda: self.lines.extend(iter(stdout.readline, "")), daemon=True).start()
        self.driver: Any = None
        self.body: Any = None

    def open(self, timeout: float) -> None:
        url = wait("the studio's URL", lambda: next((ln.split()[1] for ln in self.lines
                                                     if ln.startswith("studio: http")), None), timeout)
        self.driver = _browser()
        self.driver.get(url)
        from selenium.webdriver.common.by import By

        self.body = self.driver.find_element(By.TAG_NAME, "body")

    wait = staticmethod(wait)

    def data(self, name: str) -> str | None:
        """The page's ``data-<name>`` attribute of its body (what the page reports it shows)."""
        return self.body.get_attribute(f"data-{name}")

    def colours(self, shot: Path) -> int:
        """Save a screenshot; the number of distinct colours inside the 3D canvas (a blank one has 1-2)."""
        from PIL import Image
        from selenium.common.exceptions import TimeoutException

        for attempt in range(3):   # on a loaded machine the renderer may miss selenium's 10 s answer
            try:
                self.driver.save_screenshot(str(shot))
                break
            except TimeoutException:
                if attempt == 2:
                    raise
                time.sleep(5)
        left, top, right, bottom, ratio = self.driver.execute_script(
            "const r = document.querySelector('#viewport canvas').getBoundingClientRect();"
            "return [r.left, r.top, r.right, r.bottom, window.devicePixelRatio];")
        image = Image.open(shot).convert("RGB")
        box = tuple(int(v * ratio) for v in (left, top, right, bottom))
        return len(image.crop(box).getcolors(maxcolors=1 << 20) or [])

    def stop(self, sig: signal.Signals = signal.SIGTERM, signals: int = 3, patience: float = 30) -> int:
        """Close the browser, then send ``sig`` up to ``signals`` times (``patience`` s apart) while the
        command runs (a run's first SIGTERM stops the run, the next closes its studio), killing it if it
        still runs; its exit status."""
        if self.driver is not None:
            self.driver.quit()
            self.driver = None
        for _ in range(signals):
            if self.proc.poll() is None:
                self.proc.send_signal(sig)
                with contextlib.suppress(subprocess.TimeoutExpired):
                    self.proc.wait(patience)
        if self.proc.poll() is None:
            self.proc.kill()
        return self.proc.wait(60)


@pytest.fixture
def studio() -> Iterator[Callable[..., Studio]]:
    """``studio(*args, timeout=120)``: ``genr8 <args>`` started and its studio open in the browser."""
    if CHROMIUM is None or DRIVER is None:
        pytest.skip("chromium and chromium-driver are not installed (.ci/run installs them)")
    pytest.importorskip("selenium")
    pytest.importorskip("PIL")
    started: list[Studio] = []

    def start(*args: str, timeout: float = 120) -> Studio:
        started.append(Studio(args))
        started[-1].open(timeout)
        return started[-1]

    yield start
    for one in started:
        if one.driver is not None or one.proc.poll() is None:
            one.stop()
