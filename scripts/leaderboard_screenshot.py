"""Screenshot the leaderboard page in headless Chromium, for the README.

    python scripts/leaderboard_screenshot.py [--page leaderboards/index.html]
        [--out docs/images/leaderboard.png]

Needs Debian's chromium and chromium-driver, and selenium (the test extras).
"""

from __future__ import annotations

import argparse
import io
import shutil
from pathlib import Path

from PIL import Image
from selenium import webdriver
from selenium.webdriver.chrome.service import Service


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--page", default="leaderboards/index.html")
    parser.add_argument("--out", default="docs/images/leaderboard.png")
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=900)
    args = parser.parse_args()
    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium")
    for argument in ("--headless=new", "--no-sandbox", "--hide-scrollbars"):
        options.add_argument(argument)
    options.add_argument(f"--window-size={args.width},{args.height}")
    driver = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)
    try:
        driver.get(Path(args.page).resolve().as_uri())
        png = driver.get_screenshot_as_png()
    finally:
        driver.quit()
    image = Image.open(io.BytesIO(png)).convert("P", palette=Image.Palette.ADAPTIVE, colors=128)
    image.save(args.out, optimize=True)
    print(f"wrote {args.out}: {Path(args.out).stat().st_size // 1024} kB")


if __name__ == "__main__":
    main()
