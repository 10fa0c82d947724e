"""The run's and the evaluation's pages in a real browser: Debian's Chromium (``make test``
installs it), driven by Playwright. No console error, every image loads, the page draws
something, and each video's first frame decodes."""

from __future__ import annotations

import shutil
from pathlib import Path

import imageio.v3 as iio
import pytest

from imitate.evaluation import Suite, evaluate

CHROMIUM = shutil.which("chromium")
# Headless, as root, on a machine without network: no sandbox, no background connections.
ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]
# Each <video>'s source, its decoded width [px] and its error code, once its first frame is in
# (readyState 2) or it failed.
VIDEOS = """() => Promise.all([...document.querySelectorAll('video')].map(v => new Promise(done => {
    const seen = () => done([v.getAttribute('src'), v.videoWidth, v.error && v.error.code]);
    if (v.readyState >= 2) return seen();
    v.addEventListener('loadeddata', seen);
    v.addEventListener('error', seen);
    v.preload = 'auto';
    v.load();
})))"""

pytestmark = pytest.mark.skipif(
    CHROMIUM is None,
    reason="no chromium: `make test` installs it (scripts/ci/install_system_deps.sh --test)",
)


def opened(page_path: Path) -> dict:
    """What Chromium makes of ``page_path``: its console errors, each image's source and whether
    it loaded, each video's (source, width, error) and a screenshot ``(h, w, 3)``."""
    from playwright.sync_api import sync_playwright

    errors: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        try:
            page = browser.new_page()
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(page_path.resolve().as_uri(), wait_until="load")
            images = page.evaluate(
                "[...document.images].map(i => [i.getAttribute('src'),"
                " i.complete && i.naturalWidth > 0])"
            )
            videos = page.evaluate(VIDEOS)
            shot = iio.imread(page.screenshot(full_page=True), extension=".png")
        finally:
            browser.close()
    return {"errors": errors, "images": images, "videos": videos, "shot": shot[..., :3]}


def _check(seen: dict, images: int, videos: int) -> None:
    """No console error, at least ``images`` images and ``videos`` videos, every one shown."""
    assert seen["errors"] == []
    assert len(seen["images"]) >= images and all(ok for _, ok in seen["images"]), seen["images"]
    assert len(seen["videos"]) >= videos
    for src, width, error in seen["videos"]:
        assert width > 0 and error is None, f"{src}: width {width}, error {error}"
    assert seen["shot"].std() > 10  # text, tables and figures, not a blank page


def test_the_run_page_shows_its_figures_and_plays_its_video(quick_run):
    _check(opened(quick_run / "report.html"), images=7, videos=1)


def test_a_missing_figure_is_seen_as_missing(run_dir):
    """The check can fail: a figure deleted from the run is an image that does not load."""
    (run_dir / "figures" / "gmr.png").unlink()
    seen = opened(run_dir / "report.html")
    assert ["figures/gmr.png", False] in seen["images"]


def test_the_evaluation_page_shows_its_outcomes_and_failures(run_dir):
    """Without the collision cost the quick run's plans go into the chest: two failures, each
    with its video on the page."""
    suite = Suite.from_dict({"variations": 2, "replays": 1, "collision_weight": 0.0})
    evaluate(run_dir, suite, n=2, workers=1, videos=2)
    out = run_dir / "eval" / "default-w0-variance"
    seen = opened(out / "report.html")
    _check(seen, images=1, videos=2)
    assert len(seen["videos"]) == len(list(out.glob("failures/**/*.mp4")))
    assert any(src == "outcomes.png" for src, _ in seen["images"])
