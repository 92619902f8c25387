"""Frame sources for the tracker: a camera device, a video file or an image sequence.

``SRC`` (the ``--camera`` of ``viewcomp track`` and ``--track-camera`` of ``viewcomp play``):

- a device index (``0``, ``1``, ...): an OpenCV camera (V4L2 on Linux), frames as they come;
- a video file (anything FFmpeg reads: ``.mp4``, ``.mkv``, ...);
- an image sequence: a folder (its ``.png``, ``.jpg``, ``.jpeg``, ``.bmp``, ``.tif``,
  ``.tiff`` files in name order) or a glob pattern (``walk/frame_*.png``), at ``fps``.

Every :class:`Frame` carries its time ``t`` (seconds: the capture clock for a device, the
media time for a file or a sequence, so a recorded run gives the same result however fast it
is processed) and ``captured``, the ``time.monotonic()`` when the frame was read from the
device or file (where the tracker's latency starts). With ``realtime`` a file or sequence is
paced at its frame rate, as a camera would deliver it.

A device is read by a thread of its own (:class:`NewestFrame`) that keeps only the newest
frame: a tracker slower than the camera gets the latest picture, never one that waited in
the driver's queue (OpenCV asks V4L2 for one buffer, but not every driver honours it; with
four, a busy reader would see every face up to four frames late). The frames skipped are
counted in :attr:`FrameSource.dropped`.
"""

from __future__ import annotations

import glob
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from viewcomp.calib.errors import SourceError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


@dataclass(frozen=True)
class Frame:
    """One camera frame: ``image`` (h, w, 3) uint8 BGR, ``t`` its time in seconds, ``index``
    from 0, ``captured`` the time.monotonic() seconds when it was read."""

    image: np.ndarray
    t: float
    index: int
    captured: float


def _hint() -> str:
    return (
        "give a camera index (0 is the first; see `ls /dev/video*`), a video file, a folder "
        "of images or a glob such as 'frames/*.png'"
    )


class NewestFrame:
    """A thread reading ``capture`` (a ``cv2.VideoCapture`` or anything with ``read()``) as
    fast as it delivers, keeping only the newest frame; :meth:`take` waits for a frame newer
    than the last one taken. ``dropped`` counts frames replaced before they were taken."""

    def __init__(self, capture: object) -> None:
        self.capture = capture
        self.dropped = 0
        self._latest: tuple[np.ndarray, float] | None = None
        self._ended = False
        self._stop = threading.Event()
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._run, name="viewcomp-camera", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            ok, raw = self.capture.read()  # type: ignore[attr-defined]
            now = time.monotonic()
            with self._cond:
                if not ok or raw is None:
                    self._ended = True
                else:
                    self.dropped += self._latest is not None
                    self._latest = (raw, now)
                self._cond.notify_all()
            if self._ended:
                return

    def take(self) -> tuple[np.ndarray, float] | None:
        """The newest frame and the time.monotonic() it was read; None once the device has
        ended (or :meth:`stop` was called)."""
        with self._cond:
            while self._latest is None and not self._ended and not self._stop.is_set():
                self._cond.wait(0.1)
            item, self._latest = self._latest, None
        return item

    def stop(self) -> None:
        """End the thread (it finishes the read in progress: at most a frame period)."""
        self._stop.set()
        with self._cond:
            self._cond.notify_all()
        self._thread.join(timeout=2.0)


class FrameSource:
    """Frames from ``src`` (see the module's description); iterate, then :meth:`close`.

    Opening checks that a first frame can be read. ``size`` is (w, h) pixels; ``live`` is
    True for a device.

    Raises:
        SourceError: nothing readable at ``src``.
    """

    def __init__(
        self,
        src: str,
        fps: float = 30.0,
        realtime: bool = False,
        size: tuple[int, int] | None = None,
    ) -> None:
        self.src = str(src)
        self.fps = float(fps)
        self.realtime = realtime
        self._cap: cv2.VideoCapture | None = None
        self._files: list[Path] = []
        self._first: np.ndarray | None = None
        self._reader: NewestFrame | None = None
        text = self.src.strip()
        self.live = text.isdigit()
        if self.live:
            self._open_capture(int(text), size)
        elif any(ch in text for ch in "*?["):
            self._files = sorted(Path(p) for p in glob.glob(text) if Path(p).is_file())
            if not self._files:
                raise SourceError(f"no files match {text!r}; {_hint()}")
        else:
            path = Path(text)
            if path.is_dir():
                self._files = sorted(
                    p for p in path.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES
                )
                if not self._files:
                    kinds = ", ".join(IMAGE_SUFFIXES)
                    raise SourceError(f"{path}: a folder without images ({kinds}); {_hint()}")
            elif path.is_file():
                if path.suffix.lower() in IMAGE_SUFFIXES:
                    self._files = [path]
                else:
                    self._open_capture(str(path), None)
            else:
                raise SourceError(f"{text}: no such camera, file or folder; {_hint()}")
        if self._files:
            self._first = self._read_image(self._files[0])
        if self._first is None:  # pragma: no cover - both branches above set it or raise
            raise SourceError(f"{text}: no frame could be read; {_hint()}")
        h, w = self._first.shape[:2]
        self.size = (int(w), int(h))

    def _open_capture(self, what: int | str, size: tuple[int, int] | None) -> None:
        level = cv2.utils.logging.getLogLevel()
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)  # the message below
        try:
            cap = cv2.VideoCapture(what)
        finally:
            cv2.utils.logging.setLogLevel(level)
        if not cap.isOpened():
            cap.release()
            kind = (
                "no camera with this index can be opened"
                if isinstance(what, int)
                else ("not a video OpenCV can open")
            )
            raise SourceError(f"{what}: {kind}; {_hint()}")
        if isinstance(what, int):
            # one buffered frame: a reader that is busy gets the newest frame, not a queue
            # of old ones (latency over completeness); not every driver honours it
            cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)
            if size is not None:
                cap.set(cv2.CAP_PROP_FRAME_WIDTH, size[0])
                cap.set(cv2.CAP_PROP_FRAME_HEIGHT, size[1])
        ok, image = cap.read()
        if not ok or image is None:
            cap.release()
            raise SourceError(f"{what}: no frame could be read; {_hint()}")
        if not isinstance(what, int):
            rate = cap.get(cv2.CAP_PROP_FPS)
            if rate and np.isfinite(rate) and rate > 0:
                self.fps = float(rate)
        self._cap = cap
        self._first = _as_bgr(image)

    def _read_image(self, path: Path) -> np.ndarray:
        image = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if image is None:
            raise SourceError(f"{path}: not an image OpenCV can read; {_hint()}")
        return _as_bgr(image)

    def _live(self) -> Iterator[Frame]:
        """A device's frames, the newest each time (:class:`NewestFrame`)."""
        assert self._cap is not None
        self._reader = NewestFrame(self._cap)
        start = time.monotonic()
        index = 0
        while (item := self._reader.take()) is not None:
            image, read_at = item
            yield Frame(_as_bgr(image), read_at - start, index, read_at)
            index += 1

    @property
    def dropped(self) -> int:
        """Frames of a device skipped because a newer one came before they were taken."""
        return self._reader.dropped if self._reader is not None else 0

    def __iter__(self) -> Iterator[Frame]:
        if self.live:
            yield from self._live()
            return
        start = time.monotonic()
        index = 0
        pending = self._first
        while True:
            if pending is not None:
                image, pending = pending, None
            elif self._cap is not None:
                ok, raw = self._cap.read()
                if not ok or raw is None:
                    return
                image = _as_bgr(raw)
            elif index < len(self._files):
                image = self._read_image(self._files[index])
                if image.shape[:2] != (self.size[1], self.size[0]):
                    raise SourceError(
                        f"{self._files[index]}: {image.shape[1]}x{image.shape[0]}, but the "
                        f"sequence started at {self.size[0]}x{self.size[1]}; one size for all"
                    )
            else:
                return
            t_media = index / self.fps
            if self.realtime:
                delay = start + t_media - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            yield Frame(image, t_media, index, time.monotonic())
            index += 1

    def close(self) -> None:
        """Stop reading and release the camera or file."""
        if self._reader is not None:
            self._reader.stop()
        if self._cap is not None:
            self._cap.release()
            self._cap = None

    def __enter__(self) -> FrameSource:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _as_bgr(image: np.ndarray) -> np.ndarray:
    """(h, w, 3) uint8 BGR from what OpenCV returns (gray, BGRA, 16-bit)."""
    if image.dtype != np.uint8:
        scale = 1.0 / 257.0 if image.dtype == np.uint16 else 1.0
        image = np.clip(image * scale + 0.5, 0, 255).astype(np.uint8)
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    return image


class ArraySource:
    """Frames held in memory (tests, benchmarks, the simulated walk): the same interface as
    :class:`FrameSource`. ``images`` are (h, w, 3) uint8 BGR of one size, at ``fps``."""

    live = False

    def __init__(self, images: list[np.ndarray], fps: float = 30.0, src: str = "<memory>"):
        if not images:
            raise SourceError(f"{src}: no frames")
        self.images = images
        self.fps = float(fps)
        self.src = src
        h, w = images[0].shape[:2]
        self.size = (int(w), int(h))

    def __iter__(self) -> Iterator[Frame]:
        for i, image in enumerate(self.images):
            yield Frame(image, i / self.fps, i, time.monotonic())

    def close(self) -> None:
        """Nothing to release."""
