"""The page in Debian's headless chromium while the demo walk runs through a real daemon.

Skips, saying why, where chromium or its driver is missing; CI installs both
(``make system-deps``). ``GUIDEBELT_VIEW_PNG=docs/view.png`` keeps the screenshot there.
"""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import pytest

CHROMIUM = shutil.which("chromium")
DRIVER = shutil.which("chromedriver")
pytestmark = pytest.mark.skipif(
    CHROMIUM is None or DRIVER is None,
    reason="needs Debian's chromium and chromium-driver (make system-deps)",
)


def browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1100,900", "--disable-extensions", "--no-first-run"):  # fmt: skip
        options.add_argument(arg)
    # The driver named outright: selenium never looks for (or downloads) one of its own.
    return webdriver.Chrome(options=options, service=Service(executable_path=DRIVER))


CANVAS_COLOURS = """
const c = document.getElementById('map');
const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
const near = (i, r, g, b) =>
  Math.abs(d[i] - r) < 40 && Math.abs(d[i+1] - g) < 40 && Math.abs(d[i+2] - b) < 40;
let wall = 0, path = 0, user = 0, goal = 0;
for (let i = 0; i < d.length; i += 4) {
  if (near(i, 24, 24, 24)) wall++;
  if (near(i, 0x15, 0x65, 0xc0)) path++;
  if (near(i, 0xe6, 0x51, 0x00)) user++;
  if (near(i, 0x2e, 0x7d, 0x32)) goal++;
}
return {wall, path, user, goal};
"""


@pytest.mark.timeout(90)
def test_page_shows_the_walk(daemon, tmp_path: Path) -> None:
    from daemon.service.embedded import free_port
    from protocol.session import ZenohSettings, open_session
    from sim.live import LiveWalks, endpoints
    from viewer.server import ServeSettings, ViewThread

    if True:  # the daemon fixture: a real daemon on loopback
        zport = free_port()
        session = open_session(
            ZenohSettings(listen=endpoints(zport), connect=endpoints(daemon.port))
        )
        driver = None
        try:
            with (
                ViewThread(session, ServeSettings(port=free_port())) as view,
                LiveWalks(daemon.port, ["ann"], observers=[zport], pace_s=0.05) as walks,
            ):
                driver = browser()
                driver.get(view.settings.url())
                poses, motors, states = set(), set(), set()
                deadline = time.monotonic() + 30
                while time.monotonic() < deadline and (len(poses) < 4 or len(motors) < 2):
                    text = {
                        i: driver.find_element("id", i).text for i in ("pose", "motors", "state")
                    }
                    if text["pose"] != "-":
                        poses.add(text["pose"])
                    if text["motors"] != "-":
                        motors.add(text["motors"])
                    states.add(text["state"])
                    time.sleep(0.3)
                colours = driver.execute_script(CANVAS_COLOURS)
                shot = Path(os.environ.get("GUIDEBELT_VIEW_PNG", tmp_path / "view.png"))
                shot.parent.mkdir(parents=True, exist_ok=True)
                assert driver.save_screenshot(str(shot))
                rate = driver.find_element("id", "rate").text
                walks.stop()
        finally:
            if driver is not None:
                driver.quit()
            session.close()
    assert len(poses) >= 4, poses  # the user moved, as the page said it
    assert len(motors) >= 2, motors  # and the belt's motors changed
    assert "guiding" in states, states
    # The map drawn: obstacles, the planned path, the user and the goal, in their colours.
    assert colours["wall"] > 500 and colours["path"] > 50, colours
    assert colours["user"] > 20 and colours["goal"] > 20, colours
    assert rate.endswith("Hz") and float(rate.split()[0]) > 0, rate
    assert shot.stat().st_size > 10_000
