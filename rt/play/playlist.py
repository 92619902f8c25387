"""The playlist and the pump thread of `viewcomp play`: files in order, opened and decoded.

``viewcomp-pump`` walks the playlist, opens each file with
:class:`~viewcomp.rt.media.video.VideoReader` (its own decode thread and bounded queue, frames
fitted to the projector grid) and forwards frames to a bounded queue (read by the main
thread, :class:`~viewcomp.rt.play.player.Player`) and audio to the
:class:`~viewcomp.rt.media.audio.AudioPlayer`. Show control reaches it as a *jump*
(generation, file index, seconds), which reopens that file there.
"""

from __future__ import annotations

import logging
import os
import queue
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from viewcomp.calib.errors import PlayerError
from viewcomp.rt.media.frames import Planes
from viewcomp.rt.media.video import VideoError, VideoReader

if TYPE_CHECKING:
    from viewcomp.rt.media.audio import AudioPlayer
    from viewcomp.rt.play.embed import LiveRenderer
    from viewcomp.rt.play.player_options import PlayerOptions

log = logging.getLogger(__name__)

VIDEO_SUFFIXES = {
    ".mp4", ".mkv", ".mov", ".avi", ".webm", ".m4v", ".mpg", ".mpeg", ".ts", ".m2ts", ".ogv",
    ".wmv", ".flv",
}  # fmt: skip
IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}


def expand_playlist(paths: Sequence[str | os.PathLike[str]]) -> list[Path]:
    """Files as given, folders expanded to their video and image files (by extension, sorted
    by name).

    Raises:
        PlayerError: a path that does not exist, or nothing to play.
    """
    out: list[Path] = []
    for raw in paths:
        p = Path(raw)
        if p.is_dir():
            found = sorted(
                (
                    q
                    for q in p.iterdir()
                    if q.is_file()
                    and not q.name.startswith(".")
                    and q.suffix.lower() in VIDEO_SUFFIXES | IMAGE_SUFFIXES
                ),
                key=lambda q: q.name.lower(),
            )
            if not found:
                raise PlayerError(
                    f"folder {p} has no video or image files "
                    f"({', '.join(sorted(VIDEO_SUFFIXES | IMAGE_SUFFIXES))})"
                )
            out.extend(found)
        elif p.is_file():
            out.append(p)
        else:
            raise PlayerError(f"no such file or folder: {p}")
    if not out:
        raise PlayerError("nothing to play: give a video file, several, or a folder")
    return out


def is_still(path: Path, frames: int | None) -> bool:
    """An image file (by extension), or a video of a single frame."""
    return path.suffix.lower() in IMAGE_SUFFIXES or frames == 1


# ----------------------------------------------------------------------- pump messages
@dataclass(frozen=True)
class _FileStart:
    seq: int
    gen: int
    index: int
    path: Path
    rate: float
    still: bool
    jumped: bool


@dataclass(frozen=True)
class _End:
    gen: int


@dataclass(frozen=True)
class _Failure:
    exc: BaseException


_ENDED = object()


class PlaylistPump:
    """The pump thread's side of :class:`~viewcomp.rt.play.player.Player` (a mixin): it
    reads the playlist and the pending jump and fills the frame queue ``_vq``."""

    options: PlayerOptions
    playlist: list[Path]
    renderer: LiveRenderer | None
    _sources: list[str | os.PathLike[str]]
    _stop: threading.Event
    _vq: queue.Queue[Any]
    _audio: AudioPlayer | None
    _jump: tuple[int, int, float] | None
    _jump_lock: threading.Lock
    _pump_thread: threading.Thread | None
    _gen: int

    def _init_pump(self) -> None:
        self._vq = queue.Queue(maxsize=max(2, self.options.queue_size))
        self._pump_thread = None
        self._gen = 0  # jumps requested (main thread)
        self._jump = None  # (gen, index, seconds) for the pump
        self._jump_lock = threading.Lock()

    def _put(self, item: Any) -> bool:
        """Queue an item for the main thread; False when stopping or a jump is pending."""
        while not self._stop.is_set():
            if self._jump is not None:
                return False
            try:
                self._vq.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _take_jump(self) -> tuple[int, int, float] | None:
        with self._jump_lock:
            jump, self._jump = self._jump, None
        return jump

    def _refresh_playlist(self) -> None:
        """Re-read the folders of the playlist: files added since are played too, files removed
        are left out (each change said once, when it is seen)."""
        if not any(Path(p).is_dir() for p in self._sources):
            return
        try:
            new = expand_playlist(self._sources)
        except PlayerError:  # a folder emptied or gone: play on with what was there
            return
        added = [p.name for p in new if p not in self.playlist]
        gone = [p.name for p in self.playlist if p not in new]
        for names, form in ((added, "%d new file%s: %s"), (gone, "%d file%s gone: %s")):
            if names:
                listed = ", ".join(names[:5]) + (" ..." if len(names) > 5 else "")
                log.info("playlist: " + form, len(names), "s" if len(names) > 1 else "", listed)
        self.playlist = new

    def _pump(self) -> None:
        assert self.renderer is not None
        grid = self.renderer.grid
        seq, gen, index, start, jumped = 0, 0, 0, 0.0, False
        bad = 0  # unreadable files in a row
        unreadable: set[Path] = set()  # said once each, until readable again
        audio_mode = "frames" if self._audio is not None else "none"
        try:
            while not self._stop.is_set():
                playlist = self.playlist
                if index < 0:
                    index = len(playlist) - 1 if self.options.loop else 0
                if index >= len(playlist):
                    if self.options.loop:
                        index = 0
                    else:  # the end: wait for a jump back (previous, seek) or the stop
                        self._put(_End(gen))
                        jump = None
                        while jump is None and not self._stop.wait(0.02):
                            jump = self._take_jump()
                        if jump is None:
                            return
                        gen, index, start = jump
                        jumped = True
                        continue
                path = playlist[index]
                try:
                    reader = VideoReader(
                        path,
                        fit=grid,
                        audio=audio_mode,  # type: ignore[arg-type]
                        queue_size=self.options.queue_size,
                        start_at=start,
                    )
                except VideoError as exc:
                    if path not in unreadable:  # a looping kiosk would say it every loop
                        log.error("skipping: %s (said once, until it can be read again)", exc)
                        unreadable.add(path)
                    bad += 1
                    if bad >= len(playlist):
                        self._put(
                            _Failure(
                                VideoError(
                                    "none of the files in the playlist "
                                    "could be played (see the errors "
                                    "above)"
                                )
                            )
                        )
                        return
                    index, start = index + 1, 0.0
                    continue
                bad = 0
                if path in unreadable:
                    unreadable.discard(path)
                    log.info("playlist: %s can be read again", path.name)
                jump = None
                if not self._forward(reader, path, seq, gen, index, jumped):
                    return
                if self._stop.is_set():
                    return
                seq += 1
                jump = self._take_jump()
                if jump is not None:
                    if self._audio is not None:
                        self._audio.cancel(seq - 1)
                    gen, index, start = jump
                    jumped = True
                    continue
                self._refresh_playlist()
                if path in self.playlist:
                    index = self.playlist.index(path)
                index, start, jumped = index + 1, 0.0, False
        except BaseException as exc:  # handed to the main thread, which re-raises it
            while not self._stop.is_set():
                self._take_jump()
                if self._put(_Failure(exc)):
                    return

    def _forward(
        self, reader: VideoReader, path: Path, seq: int, gen: int, index: int, jumped: bool
    ) -> bool:
        """Queue the file's start, then its frames and audio until it ends, a jump is pending
        or the pump stops; False when the pump must return (stopping, or audio gone)."""
        with reader:
            start0 = reader.info.start
            still = is_still(path, reader.info.frames)
            if self._put(_FileStart(seq, gen, index, path, float(reader.info.rate), still, jumped)):
                try:
                    for item in reader:
                        if self._stop.is_set():
                            return False
                        if self._jump is not None:
                            break
                        if isinstance(item, Planes):
                            if not self._put(item):
                                break
                        elif self._audio is not None and item.frame is not None:
                            t = (
                                float(item.frame.time) - start0
                                if item.frame.time is not None
                                else 0.0
                            )
                            if not self._audio.feed(seq, t, item.frame):
                                return False
                except VideoError as exc:
                    log.error("stopped playing %s: %s", path, exc)
        return True
