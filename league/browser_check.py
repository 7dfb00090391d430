"""Open a report in headless Chromium: ``python -m league.browser_check DIR/report/index.html``.

Loads the page, collects console errors, uncaught exceptions and every URL it requests
besides itself (a self-contained page requests none), counts the plotly figures and the
WebGL canvases of the 3D scenes, and saves a screenshot of the first trajectory scene
(``--screenshot``). Exit code 1 when the page shows an error, fetches anything or lacks
a 3D scene (a ``failed:`` line on stderr for each), 2 when no Chromium is installed
(Debian: ``apt-get install chromium``). How Chromium is driven: ``league.reports.page_check``.
"""

from __future__ import annotations

import sys
from pathlib import Path

from league.cli import command_parser
from league.reports.page_check import CHROMIUM_NAMES, check_page, find_chromium


def main(argv: list[str] | None = None) -> int:
    parser = command_parser(prog="python -m league.browser_check", description=__doc__.splitlines()[0])
    parser.add_argument("page", type=Path, help="the report's index.html")
    parser.add_argument("--screenshot", type=Path, help="write a PNG of the first trajectory scene here")
    args = parser.parse_args(argv)
    if not args.page.is_file():
        print(f"error: no page at {args.page}", file=sys.stderr)
        return 2
    chromium = find_chromium()
    if chromium is None:
        print(f"error: no Chromium found (looked for {', '.join(CHROMIUM_NAMES)}); "
              "on Debian: apt-get install chromium", file=sys.stderr)
        return 2
    check = check_page(args.page, chromium)
    if args.screenshot and check.screenshot:
        args.screenshot.write_bytes(check.screenshot)
    print(f"{check.figures} figures, {check.scenes} 3D scenes, {len(check.errors)} console errors, "
          f"{len(check.fetched)} requests besides the page")
    for error in check.errors:
        print(f"console error: {error}")
    for url in check.fetched:
        print(f"requested: {url}")
    problems = check.problems()
    for problem in problems:
        print(f"failed: {problem}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
