"""Headless Chromium driven by Selenium: the browser checks of ``pedmesh report``'s pages
(``tests/test_report.py``) and the screenshot in the docs (``docs/report_screenshot.py``).

It needs the ``browser`` extra (``pip install 'pedmesh[browser]'``: Selenium) and a
system Chromium with its driver (Debian: ``apt-get install chromium chromium-driver``).
Only the system's browser is used: the driver's path is always given to Selenium, so
Selenium Manager never runs and nothing downloads a browser of its own.
``PEDMESH_CHROMIUM`` and ``PEDMESH_CHROMEDRIVER`` name other binaries.
"""

from __future__ import annotations

import os
import shutil

__all__ = ["BrowserUnavailable", "find_chromium", "headless_chromium"]

_CHROMIUM = ("chromium", "chromium-browser")
_DRIVER = ("chromedriver",)


class BrowserUnavailable(RuntimeError):
    """No headless browser here; the message says what is missing."""


def _which(env: str, names: tuple[str, ...], extra: tuple[str, ...]) -> str | None:
    given = os.environ.get(env)
    if given:
        return given if os.path.isfile(given) else None
    for n in names:
        found = shutil.which(n)
        if found:
            return found
    return next((p for p in extra if os.path.isfile(p)), None)


def find_chromium() -> tuple[str, str]:
    """(Chromium binary, chromedriver binary); :class:`BrowserUnavailable` if either is
    missing."""
    browser = _which("PEDMESH_CHROMIUM", _CHROMIUM, ("/usr/bin/chromium",))
    driver = _which("PEDMESH_CHROMEDRIVER", _DRIVER,
                    ("/usr/bin/chromedriver", "/usr/lib/chromium/chromedriver"))
    if browser is None:
        raise BrowserUnavailable("no Chromium found (Debian: apt-get install chromium "
                                 "chromium-driver; or set PEDMESH_CHROMIUM)")
    if driver is None:
        raise BrowserUnavailable("no chromedriver found (Debian: apt-get install "
                                 "chromium-driver; or set PEDMESH_CHROMEDRIVER)")
    return browser, driver


def headless_chromium(width: int = 1200, height: int = 900):
    """A Selenium WebDriver of the system Chromium, headless, with the browser console
    logged (``driver.get_log("browser")``). Quit it when done."""
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        raise BrowserUnavailable("selenium is not installed (pip install "
                                 "'pedmesh[browser]')") from None
    browser, driver = find_chromium()
    opts = webdriver.ChromeOptions()
    opts.binary_location = browser
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--hide-scrollbars", "--force-device-scale-factor=1",
                f"--window-size={int(width)},{int(height)}"):
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    try:
        return webdriver.Chrome(options=opts, service=Service(executable_path=driver))
    except Exception as exc:  # a driver that does not match the browser, no display libs
        raise BrowserUnavailable(f"Chromium did not start: {type(exc).__name__}: "
                                 f"{str(exc).splitlines()[0] if str(exc) else ''}") from None
