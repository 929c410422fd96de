"""The knob reader's HOG comes from cv2.HOGDescriptor (every OpenCV 4 wheel, the contrib wheels
of OpenCV 5); an OpenCV without it (the main OpenCV 5 wheels) is one clear error."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from perception import knobs
from perception.errors import PerceptionError


def _patches():
    rng = np.random.default_rng(0)
    return rng.integers(0, 255, (2, knobs.PATCH, knobs.PATCH), dtype=np.uint8)


def test_hog_features_come_from_opencv(monkeypatch):
    monkeypatch.setattr(knobs, "_HOGS", {})
    f = knobs.hog_features(_patches(), knobs.DETECTOR_HOG)
    assert f.shape[0] == 2 and f.dtype == np.float32 and np.isfinite(f).all()


def test_an_opencv_without_hog_is_one_clear_error(monkeypatch):
    monkeypatch.setattr(knobs, "_HOGS", {})
    monkeypatch.delattr(cv2, "HOGDescriptor")
    with pytest.raises(PerceptionError) as err:
        knobs.hog_features(_patches(), knobs.DETECTOR_HOG)
    assert "no HOGDescriptor" in str(err.value) and "opencv-contrib-python-headless" in str(err.value)
    assert "\n" not in str(err.value)
