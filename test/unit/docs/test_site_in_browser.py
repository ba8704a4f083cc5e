"""The built documentation site as a reader sees it: its home page and a tutorial opened in
headless Chromium (Debian's chromium and chromium-driver, as the web viewer's test uses) over
HTTP on 127.0.0.1 render their headings, navigation and every picture."""

from __future__ import annotations

import functools
import http.server
import os
import shutil
import subprocess
import sys
import threading
import time

import pytest
from conftest import REPO

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """The site built with --strict into a temporary folder, served on 127.0.0.1."""
    out = tmp_path_factory.mktemp("site")
    # not --quiet: it hides the warnings (a broken link) that --strict counts
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict",
                           "--site-dir", str(out)], cwd=REPO, capture_output=True, text=True,
                          timeout=300, env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert proc.returncode == 0, proc.stderr[-3000:]
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(out))
    handler.log_message = lambda *_: None
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    thread.join(5)


@pytest.fixture(scope="module")
def browser():
    if not (shutil.which("chromium") and shutil.which("chromedriver")):
        pytest.skip("chromium and chromedriver are needed (scripts/bootstrap.sh installs them)")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium")
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1280,900"):
        options.add_argument(arg)
    driver = webdriver.Chrome(options=options, service=Service(shutil.which("chromedriver")))
    yield driver
    driver.quit()


def page_state(driver, url: str) -> dict:
    """Open ``url`` and wait for its pictures; what the page shows."""
    driver.get(url)
    deadline = time.monotonic() + 120  # [s] a loaded machine's browser is slow
    script = "return Array.from(document.images).every(i => i.complete)"
    while not driver.execute_script(script):
        assert time.monotonic() < deadline, f"{url}: pictures not loaded within 120 s"
        time.sleep(0.2)
    return driver.execute_script("""
        const imgs = Array.from(document.querySelectorAll('article img'));
        return {title: document.title,
                h1: (document.querySelector('article h1') || {}).textContent || '',
                nav: document.querySelectorAll('nav.md-nav a.md-nav__link').length,
                images: imgs.map(i => ({src: i.getAttribute('src'), w: i.naturalWidth,
                                        h: i.naturalHeight,
                                        shown: i.getBoundingClientRect().width})),
                tables: document.querySelectorAll('article table').length};""")


def test_the_home_page_renders_with_its_picture(site, browser):
    state = page_state(browser, f"{site}/")
    assert state["title"].startswith("coverage_ros")
    assert state["h1"].strip().startswith("coverage_ros")
    assert state["nav"] >= 20  # the navigation lists the tutorials, concepts, reference
    assert state["images"], "the home page shows a picture"
    assert [i for i in state["images"] if i["w"] < 100 or i["h"] < 100 or i["shown"] < 100] == []


def test_a_tutorial_renders_with_its_pictures(site, browser):
    state = page_state(browser, f"{site}/tutorials/explore/")
    assert "Explore an unknown building" in state["h1"]
    assert len(state["images"]) >= 3, state["images"]
    assert [i for i in state["images"] if i["w"] < 100 or i["h"] < 100 or i["shown"] < 50] == []


def test_a_reference_page_shows_its_generated_tables(site, browser):
    state = page_state(browser, f"{site}/reference/robot_node/")
    assert state["tables"] >= 2
    assert "update_load" in browser.find_element("tag name", "article").text


def test_the_strategy_chooser_shows_every_strategys_picture(site, browser):
    state = page_state(browser, f"{site}/concepts/strategies/")
    shown = [i["src"] for i in state["images"] if i["w"] >= 100 and i["shown"] >= 50]
    assert len(shown) == 5, state["images"]
