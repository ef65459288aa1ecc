#!/usr/bin/env python3
"""Take the README's screenshot of the live view: Table 1's first turns through a live graph, in ``fsreg-ctl view``.

    scripts/screenshot_view.py [OUT.png]      (default docs/img/live-view.png; needs Debian's chromium)

Starts the Guess-Who graph (one process per node, sim time, decay delta = 10 s), serves
its view on a free port of 127.0.0.1, plays three turns (two human descriptions and a
robot description), and has headless Chromium photograph the page.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from venv_python import prepare  # noqa: E402

REPO = prepare("screenshot_view.py")  # .venv, import path

from fsreg_ros.ros.network import ros_environment  # noqa: E402 - after the path

os.environ.update(ros_environment(allow_network=False))


def main() -> int:
    from fsreg_ros.testing import LiveGraph

    out = Path(sys.argv[1]) if len(sys.argv) > 1 else REPO / "docs" / "img" / "live-view.png"
    browser = shutil.which("chromium")
    if browser is None:
        print("screenshot_view: needs Debian's chromium (apt-get install chromium)", file=sys.stderr)
        return 2
    scenario = REPO / "scenarios" / "guess_who_table1.yaml"
    with LiveGraph(scenario, processes=True, policy="decay", decay_period=10.0) as robot:
        view = subprocess.Popen([sys.executable, "-m", "fsreg_ros.tools.ctl", "view", "--namespace", robot.namespace,
                                 "--port", "0"], stdout=subprocess.PIPE, text=True, env=dict(os.environ))
        try:
            url = re.search(r"(http://127\.0\.0\.1:\d+/)", view.stdout.readline()).group(1)
            robot.set_clock(1.0)
            robot.say("male, lab-coat, light-hair, glasses")
            robot.set_clock(4.0)
            robot.say("female, glasses")
            robot.set_clock(12.0)
            robot.describe("face1")
            time.sleep(1.5)  # the view's status poll (next decay tick) has come round
            with tempfile.TemporaryDirectory() as profile:
                subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                                f"--user-data-dir={profile}", "--hide-scrollbars", "--window-size=1200,700",
                                "--timeout=3000", f"--screenshot={out}", url],
                               check=True, capture_output=True, timeout=60)
        finally:
            view.terminate()
            view.wait(timeout=10)
    print(f"screenshot_view: wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
