"""Widening the view by stitching the images taken while turning (seed 004, §V).

Seed 004 gives "an array of input images" to OpenCV's stitcher (SURF features) and, as its
modification, "compares only two images at a time": "the images that have to be combined are
forwarded separately in pairs". Both are here on OpenCV's ``Stitcher`` (feature finding,
matching, homographies, warping and blending are all OpenCV's); SURF is not free, so the
features are ORB (``Stitcher``'s default when xfeatures2d is absent).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import cv2
import numpy as np


@dataclass
class Stitched:
    image: np.ndarray | None
    """The panorama, or None when the stitcher could not join the images."""
    status: str
    seconds: float


def _stitcher():
    return cv2.Stitcher.create(cv2.Stitcher_PANORAMA)


def stitch_all(images: list[np.ndarray]) -> Stitched:
    """All images to the stitcher at once (seed 004 without its modification)."""
    t0 = time.perf_counter()
    status, pano = _stitcher().stitch(images)
    ok = status == cv2.Stitcher_OK
    return Stitched(pano if ok else None, _status(status), time.perf_counter() - t0)


def stitch_pairwise(images: list[np.ndarray]) -> Stitched:
    """Seed 004's modification: two images at a time, the panorama so far with the next.

    A pair that fails leaves the panorama as it was and the walk goes on with the next image
    (the view is then narrower, but not lost); only a first pair that fails is a failure."""
    t0 = time.perf_counter()
    pano, status = images[0], "ok"
    joined = 1
    for img in images[1:]:
        st, out = _stitcher().stitch([pano, img])
        if st == cv2.Stitcher_OK:
            pano, joined = out, joined + 1
        else:
            status = _status(st)
    ok = joined == len(images)
    return Stitched(pano if joined > 1 else None, "ok" if ok else status,
                    time.perf_counter() - t0)  # fmt: skip


def _status(code: int) -> str:
    names = {
        cv2.Stitcher_OK: "ok",
        cv2.Stitcher_ERR_NEED_MORE_IMGS: "need more images",
        cv2.Stitcher_ERR_HOMOGRAPHY_EST_FAIL: "homography estimation failed",
        cv2.Stitcher_ERR_CAMERA_PARAMS_ADJUST_FAIL: "camera parameters adjustment failed",
    }
    return names.get(code, f"status {code}")
