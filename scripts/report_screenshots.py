#!/usr/bin/env python3
"""Full-page screenshots of xgauge's HTML reports, as docs/images/ shows them.

Usage: scripts/report_screenshots.py REPORT.html OUT.png [REPORT.html OUT.png ...]

Opens each page in headless Chromium (tests/browser.py, Debian's chromium
from scripts/install-deps.sh) 1280 pixels wide, waits until it has drawn
itself, and fails if it logged an error or asked for anything beyond its
own file. docs/results.md says which runs the pictures in docs/images/ show.
"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))
from browser import Browser  # noqa: E402


def main(argv):
    if len(argv) < 2 or len(argv) % 2:
        sys.exit(__doc__)
    with Browser(width=1280, height=900, timeout_s=120) as browser:
        for page, png in zip(argv[0::2], argv[1::2]):
            path = os.path.abspath(page)
            load = browser.open(path)
            problems = load.console_errors + load.exceptions + load.external_requests(path)
            if problems:
                sys.exit(f"{page}: {problems}")
            browser.screenshot(png)
            print(f"{page} -> {png}: {browser.colour_stats(open(png, 'rb').read())}")


if __name__ == "__main__":
    main(sys.argv[1:])
