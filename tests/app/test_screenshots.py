"""``pito-app --demo --screenshot FILE --page P``: real, distinct pictures of at least 1280×800."""

import subprocess
import sys

import numpy as np
import pytest

pytestmark = [pytest.mark.needs_display, pytest.mark.slow]


def load_png(path):
    from PySide6.QtGui import QImage

    img = QImage(str(path)).convertToFormat(QImage.Format.Format_RGB888)
    w, h = img.width(), img.height()
    buf = np.frombuffer(img.constBits(), dtype=np.uint8, count=img.bytesPerLine() * h)
    return buf.reshape(h, img.bytesPerLine())[:, : 3 * w].reshape(h, w, 3).copy()


@pytest.fixture(scope="module")
def shots(tmp_path_factory):
    out = {}
    d = tmp_path_factory.mktemp("shots")
    for page in ("mount", "live"):
        path = d / f"{page}.png"
        r = subprocess.run([sys.executable, "-m", "app.main", "--demo", "--screenshot", str(path), "--page", page],
                           capture_output=True, text=True, timeout=240)
        assert r.returncode == 0, r.stderr[-2000:]
        out[page] = path
    return out


def test_screenshots_are_large_real_and_distinct(shots, qapp):
    imgs = {p: load_png(path) for p, path in shots.items()}
    for page, img in imgs.items():
        h, w, _ = img.shape
        assert w >= 1280 and h >= 800, page
        # the 3D view (left part of the page, below the toolbar) is drawn: many colours, not a flat fill
        view = img[150:h - 150, 220:w // 2]
        assert view.std() > 10, page
        assert len(np.unique(view.reshape(-1, 3)[::7], axis=0)) > 100, page
    a, b = imgs["mount"], imgs["live"]
    assert a.shape == b.shape and np.abs(a.astype(int) - b.astype(int)).mean() > 5


def test_screenshot_needs_demo(tmp_path):
    r = subprocess.run([sys.executable, "-m", "app.main", "--screenshot", str(tmp_path / "x.png")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "--demo" in r.stderr
