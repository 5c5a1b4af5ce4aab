"""The demo's Meshcat page as a person sees it: a headless Chromium screenshot of a recorded teleop run shows
the robot and the operator's skeletons (red raw, blue corrected) standing beside it."""

import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")

pytestmark = pytest.mark.skipif(
    CHROMIUM is None, reason="Debian's chromium is not installed (make system-deps installs it as root)"
)


def screenshot(html_path, png_path, timeout_ms: int = 20000) -> None:
    """Render ``html_path`` in headless Chromium (software GL) and save a 1280x800 PNG.

    The page is captured once it has loaded (``--timeout`` is only the longest wait), with a fresh profile folder
    each time. ``--virtual-time-budget`` hung here now and then, whatever the load (2 of 3 runs with the user's
    default profile, 2 of 4 with a fresh one: the process never exits); ``--timeout`` took 2.7-3.8 s in 16 of
    16 runs, the robot and both skeletons drawn every time.
    """
    cmd = [
        CHROMIUM,
        "--headless=new",
        "--no-sandbox",
        "--use-gl=swiftshader",
        "--enable-unsafe-swiftshader",
        "--disable-background-networking",
        "--disable-component-update",
        "--no-first-run",
        "--window-size=1280,800",
        f"--timeout={timeout_ms}",
        f"--screenshot={png_path}",
        f"file://{html_path}",
    ]
    # Should a browser still hang, it is killed and started once more; a page that fails to render fails the test.
    for timeout_s in (120, 240):
        try:
            profile = tempfile.mkdtemp(prefix="chromium-profile-", dir=Path(png_path).parent)
            subprocess.run([cmd[0], f"--user-data-dir={profile}", *cmd[1:]], check=True, capture_output=True,
                           timeout=timeout_s)
            return
        except subprocess.TimeoutExpired:
            continue
    pytest.fail(f"headless Chromium did not finish rendering {html_path} twice (120 s, then 240 s)")


@pytest.fixture(scope="module")
def teleop_png(tmp_path_factory):
    from pydrake.geometry import Meshcat

    from akc_drake.config import PipelineConfig
    from akc_drake.core.skeleton import BodyDimensions
    from akc_drake.diagrams import Measurements
    from akc_drake.fileio import atomic_write_text
    from akc_drake.operator.motions import make_motion
    from akc_drake.teleop import scenario as sc

    out = tmp_path_factory.mktemp("meshcat_view")
    cfg = PipelineConfig().validate()
    motion = sc.truncate_motion(make_motion("II", 1, 0), 25, cfg.camera.rate_hz)
    meas = Measurements.from_session(sc.render_motion(motion, cfg))
    meshcat = Meshcat()
    meshcat.StartRecording(set_visualizations_while_recording=False)
    sc.run_teleop(cfg, BodyDimensions.paper_participant(), corrector="AKC(KF)", replay=meas, motion=motion,
                  meshcat=meshcat)
    meshcat.StopRecording()
    meshcat.PublishRecording()
    html = out / "teleop.html"
    atomic_write_text(html, meshcat.StaticHtml())
    png = out / "teleop.png"
    screenshot(html, png)
    return png


def _rgb(png) -> np.ndarray:
    from matplotlib.image import imread

    img = imread(str(png))
    return (255 * img[..., :3]).astype(int)


def test_screenshot_shows_the_robot_and_the_skeletons_beside_it(teleop_png):
    img = _rgb(teleop_png)
    h, w, _ = img.shape
    assert (h, w) == (800, 1280)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    # The skeletons (SKELETON_HIPS_W: to the robot's left, which the default camera shows on the right).
    red = (r > 160) & (g < 90) & (b < 90)
    blue = (b > 150) & (r < 100) & (g < 150)
    right = np.zeros_like(red)
    right[:, int(0.55 * w) :] = True
    assert np.count_nonzero(red & right) > 150
    assert np.count_nonzero(blue & right) > 100
    # The robot: its dark base, grippers and head band (RGB < 60), in the middle of the view.
    dark = np.max(img, axis=2) < 60
    middle = np.zeros_like(dark)
    middle[int(0.2 * h) : int(0.8 * h), int(0.3 * w) : int(0.65 * w)] = True
    assert np.count_nonzero(dark & middle) > 2000
