"""What does the exported WebGL walkthrough weigh and cost in a browser?

Usage:
    python benchmarks/bench_web.py [--fit fit.npz] [--repeats 5] [--frames 30]

For the demo scene (cornell-teapot, draft solve, the default fit with 8 point lights
per glossy object, coefficients per light; or ``--fit FILE``):
  1. sizes: scene.glb against fit.npz (and the page with its vendored three.js);
  2. page load time in headless chromium (software WebGL2: SwiftShader), from
     navigation to the first complete frame (``document.title == "rendered"``), median
     of ``--repeats`` fresh pages, served by ``display.serve`` on 127.0.0.1;
  3. frame time at 1280 x 720, median of ``--frames`` frames drawn back to back (each
     waited for with a one-pixel read-back, as the page's own frame counter does), at 1
     and 4 samples per pixel (4x MSAA, the default), fitted and diffuse-only;
  4. the same camera rendered by ``vlights render --shading pixel`` (llvmpipe), mean
     absolute difference of the 8-bit images: the page's agreement on the real scene.

Results: JSON lines in benchmarks/results/web.jsonl.
"""

from __future__ import annotations

import argparse
import io
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import Recorder

FLAGS = ["--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--disable-gpu-sandbox", "--force-color-profile=srgb", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run"]
SIZE = (1280, 720)


def demo_fit(directory):
    """solve + fit of the demo scene at draft (the demo's defaults); the fit's path."""
    for argv in (["solve", "cornell-teapot", "--quality", "draft", "-o", str(directory / "solution.npz")],
                 ["fit", str(directory / "solution.npz"), "-o", str(directory / "fit.npz")]):
        subprocess.run([sys.executable, "-m", "display", *argv], check=True, stdout=subprocess.DEVNULL)
    return directory / "fit.npz"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--fit", type=Path, help="fit.npz (default: solve and fit the demo scene at draft)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--frames", type=int, default=30)
    args = parser.parse_args(argv)

    from PIL import Image
    from playwright.sync_api import sync_playwright

    from display.export import FILE, PAGE, page_files
    from display.serve import start

    record = Recorder(benchmark="web", size=list(SIZE))
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        fit = args.fit or demo_fit(tmp)
        web = tmp / "web"
        subprocess.run([sys.executable, "-m", "display", "export", str(fit), "-o", str(web)], check=True,
                       stdout=subprocess.DEVNULL)
        page_bytes = sum((web / p).stat().st_size for p in page_files())
        record({"what": "size", "fit_npz_bytes": fit.stat().st_size, "scene_glb_bytes": (web / FILE).stat().st_size,
                "glb_over_npz": (web / FILE).stat().st_size / fit.stat().st_size, "page_bytes": page_bytes})

        reference = tmp / "render.png"
        subprocess.run([sys.executable, "-m", "display", "render", str(fit), "--shading", "pixel", "--size",
                        f"{SIZE[0]}x{SIZE[1]}", "-o", str(reference)], check=True, stdout=subprocess.DEVNULL)
        want = np.asarray(Image.open(reference).convert("RGB"), np.float64)

        with start(web) as server, sync_playwright() as p:
            browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=FLAGS)
            loads = []
            for _ in range(args.repeats):
                page = browser.new_page(viewport={"width": SIZE[0], "height": SIZE[1]}, device_scale_factor=1)
                t = time.perf_counter()
                page.goto(f"{server.url}{PAGE}?overlay=0")
                page.wait_for_function("document.title === 'rendered' || document.title === 'error'", timeout=300_000)
                loads.append(time.perf_counter() - t)
                assert page.title() == "rendered", page.evaluate("window.vlights.error")
                got = np.asarray(Image.open(io.BytesIO(page.locator("#view").screenshot())).convert("RGB"), np.float64)
                page.close()
            record({"what": "load", "seconds_median": statistics.median(loads), "seconds": loads,
                    "mean_abs_diff_to_render": float(np.abs(got - want).mean()),
                    "pixels_off_by_more_than_16": float(np.mean(np.abs(got - want).max(axis=2) > 16))})
            for samples in (1, 4):
                for mode in ("fitted", "diffuse"):
                    page = browser.new_page(viewport={"width": SIZE[0], "height": SIZE[1]}, device_scale_factor=1)
                    page.goto(f"{server.url}{PAGE}?overlay=0&samples={samples}&mode={mode}")
                    page.wait_for_function("document.title === 'rendered'", timeout=300_000)
                    times = page.evaluate(f"window.vlights.benchmark({args.frames})")
                    page.close()
                    record({"what": "frame", "mode": mode, "samples": samples, "ms_median": statistics.median(times),
                            "ms_min": min(times), "frames": len(times)})
            browser.close()
    record.save("web.jsonl")


if __name__ == "__main__":
    main()
