"""Encoding on its own thread: a :class:`~viewcomp.rt.media.video.VideoWriter` fed frames and
audio in order, from a small pool of read-back buffers, so rendering never waits on x264."""

from __future__ import annotations

import queue
import threading
from typing import Any, Protocol

import numpy as np

from viewcomp.rt.media.video import _QUEUE_POLL, AudioItem, AudioMode


class FrameWriter(Protocol):
    """What the encode thread drives: :class:`~viewcomp.rt.media.video.VideoWriter`, the image
    sequence writer and the system-ffmpeg pipe (HAP) alike."""

    audio_mode: AudioMode

    def write(self, rgb: np.ndarray) -> None: ...

    def write_audio(self, item: AudioItem) -> None: ...

    @property
    def frames_written(self) -> int: ...

    def close(self) -> None: ...

    def abort(self) -> None: ...


_END = object()  # the last item of the queue: flush and close


class EncodeThread:
    """Runs a :class:`VideoWriter` on its own thread: frames and audio in, in order.

    Read-back buffers come from a small pool (:meth:`buffer`) and go back to it once encoded,
    so the steady state allocates nothing per frame. At most ``depth`` items wait in the
    queue; :meth:`buffer` and :meth:`put_frame` block while the encoder is behind. An error on
    the encoder thread is raised in the caller's thread by the next call.

    Use :meth:`close` (flush, rename into place) or :meth:`abort` (no output left); as a
    context manager, an exception aborts.
    """

    def __init__(self, writer: FrameWriter, shape: tuple[int, int, int], depth: int = 3) -> None:
        self.writer = writer
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=depth)
        self._free: queue.Queue[np.ndarray] = queue.Queue()
        for _ in range(depth + 3):  # queued, being encoded, in flight, being filled
            self._free.put(np.empty(shape, np.uint8))
        self._error: BaseException | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="viewcomp-encode", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item is _END or self._stop.is_set():
                return
            try:
                if isinstance(item, AudioItem):
                    self.writer.write_audio(item)
                else:
                    self.writer.write(item)
                    self._free.put(item)
            except BaseException as exc:  # re-raised in the caller's thread
                self._error = exc
                self._stop.set()
                return

    def _check(self) -> None:
        if self._error is not None:
            raise self._error

    def _put(self, item: Any) -> None:
        while True:
            self._check()
            try:
                self._queue.put(item, timeout=_QUEUE_POLL)
                return
            except queue.Full:
                continue

    def buffer(self) -> np.ndarray:
        """A free (H, W, 3) uint8 array to render the next frame into."""
        while True:
            self._check()
            try:
                return self._free.get(timeout=_QUEUE_POLL)
            except queue.Empty:
                continue

    def put_frame(self, rgb: np.ndarray) -> None:
        """Queue a frame (a :meth:`buffer` array) for encoding; it returns to the pool."""
        self._put(rgb)

    def put_audio(self, item: AudioItem) -> None:
        """Queue an audio item (written in order with the frames)."""
        self._put(item)

    @property
    def frames_written(self) -> int:
        """Frames encoded so far (all of them after :meth:`close`)."""
        return self.writer.frames_written

    def close(self) -> None:
        """Encode what is queued, flush and move the file into place."""
        self._put(_END)
        self._thread.join()
        self._check()
        self.writer.close()

    def abort(self) -> None:
        """Stop without finishing; the temporary file is deleted."""
        self._stop.set()
        while self._thread.is_alive():
            try:  # unblock a put waiting on a full queue; the thread then sees the flag
                self._queue.get_nowait()
            except queue.Empty:
                try:
                    self._queue.put_nowait(_END)
                except queue.Full:
                    pass
            self._thread.join(timeout=_QUEUE_POLL)
        self.writer.abort()

    def __enter__(self) -> EncodeThread:
        return self

    def __exit__(self, exc_type: object, *exc: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
