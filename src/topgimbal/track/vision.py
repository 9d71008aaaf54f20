"""Finding the target in a picture: one of OpenCV's single-object trackers (opencv-contrib: KCF,
fast; CSRT, sturdier and slower), checked each frame against the target's template so that a
tracker that slid onto the background (an occluded target) is noticed, and a template search
around where the target is expected to re-acquire it after a short occlusion.

Pictures are numpy arrays (height x width x 3, BGR or RGB: only grey levels are used for the
check). Boxes are (x, y, width, height) in pixels, top left origin.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ..errors import TopGimbalError

if TYPE_CHECKING:
    import numpy as np

KINDS = ("kcf", "csrt")
MIN_SCORE = 0.55  # normalised correlation with the template below which the target is not there
SEARCH_RADIUS_BOXES = 3.0  # a re-acquisition search looks this many box sizes around the guess
Box = tuple[float, float, float, float]


class TrackerError(TopGimbalError):
    """A tracking request that cannot be met (no OpenCV, unknown tracker, empty box)."""


def _cv2() -> Any:
    try:
        import cv2
    except ImportError:
        raise TrackerError("the companion tracker needs OpenCV with contrib (opencv-contrib-python-headless)") from None
    return cv2


def _make(kind: str) -> Any:
    cv2 = _cv2()
    name = {"kcf": "TrackerKCF_create", "csrt": "TrackerCSRT_create"}.get(kind)
    if name is None:
        raise TrackerError(f"tracker must be one of {', '.join(KINDS)} (got {kind!r})")
    factory = getattr(cv2, name, None) or getattr(getattr(cv2, "legacy", None), name, None)
    if factory is None:
        raise TrackerError(f"this OpenCV has no {kind.upper()} tracker (install opencv-contrib-python-headless)")
    return factory()


def _grey(image: np.ndarray) -> np.ndarray:
    cv2 = _cv2()
    return image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)


def clamp_box(box: Box, width: int, height: int) -> tuple[int, int, int, int]:
    x, y, w, h = box
    w, h = max(4, round(w)), max(4, round(h))
    x = min(max(0, round(x)), max(0, width - w))
    y = min(max(0, round(y)), max(0, height - h))
    return x, y, min(w, width), min(h, height)


SNAP_MIN_CONTRAST = 20  # grey levels an object must stand out from the box's edge to be snapped to


def snap(grey: np.ndarray, b: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    """The box moved so that the object in it is at its centre: a box drawn by hand (or from a
    late picture) is rarely centred, and the tracker would keep the offset for ever. The object is
    what differs from the box's edge (its median grey level) by more than half the largest
    difference; without such an object the box stays where it is."""
    w, h = b[2], b[3]
    c = centroid(grey, b)
    if c is None:
        return b
    H, W = grey.shape  # noqa: N806
    return clamp_box((c[0] - w / 2, c[1] - h / 2, w, h), W, H)


def centroid(grey: np.ndarray, b: tuple[int, int, int, int]) -> tuple[float, float] | None:
    """Sub-pixel centre of the object in box b (what differs from the box's edge by more than
    half the largest difference, weighted by that difference), or None when nothing stands out.
    Finer than the tracker's whole-pixel box: a pixel is 0.1 degree at 60 degrees over 640."""
    import numpy as np

    x, y, w, h = b
    patch = grey[y : y + h, x : x + w].astype(np.int16)
    if patch.size == 0:
        return None
    edge = np.concatenate([patch[0], patch[-1], patch[:, 0], patch[:, -1]])
    diff = np.abs(patch - int(np.median(edge))).astype(np.float32)
    peak = float(diff.max())
    if peak < SNAP_MIN_CONTRAST:
        return None
    mask = (diff > peak / 2).astype(np.uint8)
    # Only the blob nearest the box's centre: a landmark or a road crossing the box's edge must
    # not pull the measurement off the target.
    n, labels, _, centres = _cv2().connectedComponentsWithStats(mask, connectivity=8)
    if n <= 1:
        return None
    d = [(centres[i][0] - w / 2) ** 2 + (centres[i][1] - h / 2) ** 2 for i in range(1, n)]
    keep = 1 + int(np.argmin(d))
    weight = np.where(labels == keep, diff, 0.0)
    total = float(weight.sum())
    if total <= 0:
        return None
    ys, xs = np.indices(weight.shape)
    return x + 0.5 + float((weight * xs).sum()) / total, y + 0.5 + float((weight * ys).sum()) / total


class VisualTracker:
    def __init__(self, kind: str = "kcf", *, min_score: float = MIN_SCORE) -> None:
        _make(kind)  # fail now for an unknown kind or a missing OpenCV
        self.kind = kind
        self.min_score = min_score
        self._tracker: Any = None
        self._template: np.ndarray | None = None
        self.box: tuple[int, int, int, int] | None = None
        self.centre: tuple[float, float] | None = None  # the object's sub-pixel centre in the last picture
        self.score = 0.0

    @property
    def locked(self) -> bool:
        return self.box is not None

    def start(self, image: np.ndarray, box: Box) -> None:
        h, w = image.shape[:2]
        grey = _grey(image)
        b = clamp_box(box, w, h)
        for _ in range(3):  # an object cut by the box's edge pulls the box a part of the way
            b, moved = snap(grey, b), b
            if b == moved:
                break
        self._template = _grey(image)[b[1] : b[1] + b[3], b[0] : b[0] + b[2]].copy()
        self._init(image, b)

    def _init(self, image: np.ndarray, b: tuple[int, int, int, int]) -> None:
        self._tracker = _make(self.kind)
        self._tracker.init(image, b)
        self.box, self.score = b, 1.0
        self.centre = centroid(_grey(image), b) or (b[0] + b[2] / 2, b[1] + b[3] / 2)

    def _match(self, grey: np.ndarray, b: tuple[int, int, int, int]) -> float:
        cv2 = _cv2()
        t = self._template
        assert t is not None
        patch = grey[b[1] : b[1] + t.shape[0], b[0] : b[0] + t.shape[1]]
        if patch.shape != t.shape:
            return 0.0
        return float(cv2.matchTemplate(patch, t, cv2.TM_CCOEFF_NORMED)[0, 0])

    def update(self, image: np.ndarray) -> tuple[int, int, int, int] | None:
        """The target's box in this picture, or None (and unlocked) when it is not there."""
        if self._tracker is None or self.box is None:
            return None
        ok, found = self._tracker.update(image)
        if not ok:
            self.box = self.centre = None
            return None
        h, w = image.shape[:2]
        assert self._template is not None
        th, tw = self._template.shape
        cx, cy = found[0] + found[2] / 2, found[1] + found[3] / 2
        b = clamp_box((cx - tw / 2, cy - th / 2, tw, th), w, h)
        grey = _grey(image)
        self.score = self._match(grey, b)
        if self.score < self.min_score:
            self.box = self.centre = None
            return None
        self.box = (round(found[0]), round(found[1]), round(found[2]), round(found[3]))
        self.centre = centroid(grey, b) or (cx, cy)
        return self.box

    def reacquire(self, image: np.ndarray, guess_px: tuple[float, float]) -> tuple[int, int, int, int] | None:
        """Look for the template around `guess_px` (where the target is expected); on a match,
        restart the tracker there and return the box."""
        if self._template is None:
            return None
        cv2 = _cv2()
        grey = _grey(image)
        th, tw = self._template.shape
        h, w = grey.shape
        r = SEARCH_RADIUS_BOXES * max(tw, th)
        x0, y0 = max(0, int(guess_px[0] - tw / 2 - r)), max(0, int(guess_px[1] - th / 2 - r))
        x1, y1 = min(w, int(guess_px[0] + tw / 2 + r)), min(h, int(guess_px[1] + th / 2 + r))
        if x1 - x0 < tw or y1 - y0 < th:
            return None
        res = cv2.matchTemplate(grey[y0:y1, x0:x1], self._template, cv2.TM_CCOEFF_NORMED)
        _, score, _, (mx, my) = cv2.minMaxLoc(res)
        if score < self.min_score:
            return None
        b = (x0 + mx, y0 + my, tw, th)
        self._init(image, b)
        self.score = float(score)
        return b
