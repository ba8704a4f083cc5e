"""A headless Chromium (Debian's ``chromium`` and ``chromium-driver``, driven by selenium) that
opens the rerun web viewer and hands back what the viewer holds, for tests."""

from __future__ import annotations

import base64
import contextlib
import shutil
import threading
import time
from pathlib import Path

# The viewer's page keeps its WebHandle in window._handle once the app has started;
# save_recording() encodes the recording it shows as .rrd bytes.
SAVE_RECORDING = """
const done = arguments[arguments.length - 1];
try {
  const bytes = window._handle.save_recording();
  let text = '';
  for (let i = 0; i < bytes.length; i += 0x8000) {
    text += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
  }
  done(btoa(text));
} catch (e) {
  done('error: ' + e);
}
"""


#: [s] the browser gets this long to quit; then it and its driver are killed
QUIT_WAIT = 30.0


def chromium_paths() -> tuple[str, str]:
    browser, driver = shutil.which("chromium"), shutil.which("chromedriver")
    if not (browser and driver):
        raise RuntimeError("chromium and chromedriver are needed (Debian: apt install chromium "
                           "chromium-driver; scripts/bootstrap.sh installs them when root)")
    return browser, driver


class HeadlessViewer:
    """``with HeadlessViewer(url) as viewer: viewer.recording(...)`` - Chromium without a GPU
    (the viewer falls back to WebGL on SwiftShader, its "software rasterizer")."""

    def __init__(self, url: str, size: tuple[int, int] = (1280, 800)) -> None:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service

        browser, driver = chromium_paths()
        options = webdriver.ChromeOptions()
        options.binary_location = browser
        for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
                    "--enable-unsafe-swiftshader", f"--window-size={size[0]},{size[1]}"):
            options.add_argument(arg)
        self.driver = webdriver.Chrome(options=options, service=Service(driver))
        self.driver.set_script_timeout(60)
        self.driver.get(url)

    def __enter__(self) -> HeadlessViewer:
        return self

    def __exit__(self, *exc) -> None:
        """Quit the browser; one that has not quit within :data:`QUIT_WAIT` (on a loaded
        machine chromedriver once did not answer for ten minutes) is killed by PID with its
        driver, which this viewer started, and every process the driver started."""
        import psutil

        tree: list[psutil.Process] = []
        with contextlib.suppress(psutil.Error, AttributeError):
            root = psutil.Process(self.driver.service.process.pid)
            tree = [root, *root.children(recursive=True)]
        quitter = threading.Thread(target=self.driver.quit, daemon=True)
        quitter.start()
        quitter.join(QUIT_WAIT)
        if quitter.is_alive():
            for proc in tree:
                with contextlib.suppress(psutil.Error):
                    proc.kill()
            quitter.join(QUIT_WAIT)

    def wait_started(self, timeout: float = 240.0) -> None:
        """Until the wasm app runs (its handle exists), or raise with the page's last words.
        While the page compiles the viewer's wasm its thread may not answer a script for a
        minute on a busy machine, nor chromedriver the poll for two: such a poll times out
        (selenium's script timeout, or the driver connection's read timeout) and the wait goes
        on to the deadline."""
        from selenium.common.exceptions import TimeoutException
        from urllib3.exceptions import ReadTimeoutError

        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                if self.driver.execute_script("return typeof window._handle !== 'undefined'"):
                    return
            except (TimeoutException, ReadTimeoutError):
                continue
            time.sleep(0.5)
        raise AssertionError(f"the web viewer did not start within {timeout:g} s: "
                             f"{self.driver.find_element('id', 'center_text').text!r}")

    def panic(self) -> str | None:
        return self.driver.execute_script(
            "return window._handle.has_panicked() ? (window._handle.panic_message() || '?') "
            ": null")

    def save_recording(self, path: Path) -> Path:
        """The recording the viewer holds right now, written to ``path`` (.rrd)."""
        text = self.driver.execute_async_script(SAVE_RECORDING)
        if text.startswith("error: "):
            raise AssertionError(f"the viewer could not save its recording: {text}")
        path.write_bytes(base64.b64decode(text))
        return path

    def screenshot(self, path: Path) -> Path:
        self.driver.save_screenshot(str(path))
        return path
