"""Screenshots of a `pedmesh report` page for the docs, taken in headless Chromium.

    pedmesh run geometries/example2.json --model sfm --out runs/example2-sfm -q
    pedmesh report runs/example2-sfm -o runs/example2-sfm/report.html
    python docs/report_screenshot.py runs/example2-sfm/report.html

writes ``docs/images/report.png`` (the top of the page: the summary, the key numbers and
the room plan) and ``docs/images/report_snapshots.png`` (the density over time, with the
slider moved to the middle). Needs the ``browser`` extra and the system Chromium (see
docs/report.md); nothing downloads a browser.
"""

from __future__ import annotations

import argparse
import io
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
WIDTH = 1100


def _crop(png: bytes, top: float, bottom: float, out: Path) -> None:
    from PIL import Image

    im = Image.open(io.BytesIO(png)).convert("RGB")
    im = im.crop((0, int(top), im.width, min(int(bottom), im.height)))
    # a palette of 256 colours: the page is text and flat plots, a quarter of the bytes
    im.quantize(256, method=Image.Quantize.MEDIANCUT).save(out, optimize=True)
    print(f"wrote {out} ({im.width} x {im.height}, {out.stat().st_size / 1e3:.0f} kB)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("report", type=Path, help="a report written by pedmesh report")
    ap.add_argument("--out", type=Path, default=DOCS / "images", help="folder of the PNGs")
    args = ap.parse_args(argv)

    sys.path.insert(0, str(DOCS.parent))
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    from pedmesh._browser import headless_chromium

    driver = headless_chromium(WIDTH, 900)
    try:
        driver.get(args.report.resolve().as_uri())
        height = driver.execute_script("return document.body.scrollHeight")
        driver.set_window_size(WIDTH, height + 200)
        slider = driver.find_element(By.CSS_SELECTOR, ".snapshots input.slider")
        for _ in range(int(slider.get_attribute("max")) // 2):
            slider.send_keys(Keys.ARROW_RIGHT)
        driver.execute_script("window.scrollTo(0, 0)")

        def box(selector: str) -> tuple[float, float]:
            r = driver.execute_script("var r = document.querySelector(arguments[0])"
                                      ".getBoundingClientRect(); return [r.top, r.bottom];",
                                      selector)
            return r[0], r[1]

        png = driver.get_screenshot_as_png()
        args.out.mkdir(parents=True, exist_ok=True)
        _crop(png, 0, box("#plan")[1] + 10, args.out / "report.png")
        top, bottom = box("#snapshots")
        _crop(png, top - 10, bottom + 10, args.out / "report_snapshots.png")
    finally:
        driver.quit()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
