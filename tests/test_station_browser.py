"""The live view in a real browser: ``station replay <demo>/radio.bin --http`` opened in
headless Chromium (Debian's ``chromium`` and ``chromium-driver``, installed by ``make
setup``), driven by selenium. The page must show the replayed run: the map drawn, the last
packet's pose, and as many accepted packets as ``station decode`` counts. A screenshot goes
to ``build/station/live-view.png``."""

import math
import os
import shutil
import time
from pathlib import Path

import pytest

from station.cli import decode_bytes
from station.radio import decode_payload
from tests.test_station_replay import ROOT, WORLD, small_recording
from tests.test_station_web import start_replay, stop, wait_line

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMEDRIVER = shutil.which("chromedriver") or "/usr/bin/chromedriver"
SHOT = Path(ROOT) / "build" / "station" / "live-view.png"


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    return small_recording(tmp_path_factory)


@pytest.fixture
def browser():
    if not (os.path.exists(CHROMIUM) and os.path.exists(CHROMEDRIVER)):
        pytest.fail("headless Chromium is missing: `make setup` installs Debian's chromium "
                    "and chromium-driver")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              "--window-size=1200,900", "--hide-scrollbars"):
        opts.add_argument(a)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
    yield driver
    driver.quit()


def test_the_page_shows_the_replayed_run(recording, browser, tmp_path):
    from selenium.webdriver.support.ui import WebDriverWait
    rec = decode_bytes(recording.read_bytes())
    last = decode_payload(bytes.fromhex(rec["accepted"][-1]["payload"]))
    th = last.theta_u16 * 360.0 / 65536.0
    th = th - 360.0 if th >= 180.0 else th
    proc, url = start_replay(str(recording), "--speed", "0", "--wait-clients", "1", "--out",
                             str(tmp_path / "out"), *WORLD)
    try:
        browser.get(url)                   # the replay starts once the page has connected
        wait_line(proc, "recording ended")
        t0 = time.monotonic()
        WebDriverWait(browser, 5.0, poll_frequency=0.1).until(
            lambda d: d.execute_script("return window.stationView.ended && "
                                       "document.getElementById('accepted').textContent")
            == str(len(rec["accepted"])))
        view = browser.execute_script(
            "const v = window.stationView; return {packets: v.packets, gaps: v.gaps, "
            "drawn: Number(document.getElementById('map').dataset.drawn)};")
        # the map as drawn: free, unknown and occupied cells all on the canvas
        shades = browser.execute_script("""
            const c = document.getElementById('map');
            const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
            let dark = 0, light = 0, grey = 0;
            for (let i = 0; i < d.length; i += 4) {
              if (d[i] === d[i + 1] && d[i] === d[i + 2]) {
                if (d[i] < 40) dark++; else if (d[i] > 200) light++; else grey++;
              }
            }
            return [dark, light, grey];""")
        x = float(browser.find_element("id", "pose-x").text)
        y = float(browser.find_element("id", "pose-y").text)
        theta = float(browser.find_element("id", "pose-th").text)
        within = time.monotonic() - t0
        SHOT.parent.mkdir(parents=True, exist_ok=True)
        browser.save_screenshot(str(SHOT))
    finally:
        assert stop(proc) == 0
    assert within < 5.0
    assert view["packets"] == len(rec["accepted"]) and view["gaps"] == 0
    assert view["drawn"] >= 1 and all(n > 100 for n in shades), shades
    assert x == pytest.approx(last.x_mm / 1000.0, abs=5e-4)
    assert y == pytest.approx(last.y_mm / 1000.0, abs=5e-4)
    assert math.remainder(theta - th, 360.0) == pytest.approx(0.0, abs=0.006)
    assert SHOT.stat().st_size > 10000
