"""What `viewcomp play` did and shows: run statistics, the status report (OSC and stdout),
the frame handed to ``on_frame``, the overlay's lines and the log of dropped frames."""

from __future__ import annotations

import logging
import math
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from viewcomp.calib.world.eye import eye_to_polar
from viewcomp.rt.media.audio import AudioStats
from viewcomp.rt.media.frames import Planes
from viewcomp.rt.play.live import STATUS_ADDRESS, SourceCounts

if TYPE_CHECKING:
    from viewcomp.rt.play.embed import LiveRenderer
    from viewcomp.rt.play.frame_record import FrameRecord

log = logging.getLogger(__name__)

DROP_LOG_PERIOD = 5.0  # seconds: dropped frames are logged at most this often


@dataclass
class PlayerStats:
    """What a run did. Times in seconds unless the name says ms."""

    presented: int = 0
    dropped: int = 0
    redrawn: int = 0
    seconds: float = 0.0
    first_present: float | None = None
    last_present: float | None = None
    render_ms: deque[float] = field(default_factory=lambda: deque(maxlen=18000))  # last 10 min
    max_present_gap_ms: float = 0.0
    max_loop_gap_ms: float = 0.0  # between main-loop iterations, after the first frames
    command_latency_ms_last: float | None = None
    command_latency_ms_max: float = 0.0
    inputs: dict[str, SourceCounts] = field(default_factory=dict)
    audio: AudioStats | None = None
    audio_device: str = ""
    files_played: int = 0
    stills: int = 0  # still images shown (not counted in presented)
    unshown: int = 0  # frames that came due while the display was gone (not drawn)
    display_losses: int = 0  # times the fullscreen window's monitor went away

    @property
    def fps(self) -> float:
        """Presented frames per second between the first and the last presentation."""
        if self.first_present is None or self.last_present is None or self.presented < 2:
            return 0.0
        span = self.last_present - self.first_present
        return (self.presented - 1) / span if span > 0 else 0.0

    @property
    def drop_percent(self) -> float:
        """Dropped frames as a percentage of the frames due."""
        due = self.presented + self.dropped
        return 100.0 * self.dropped / due if due else 0.0

    def summary(self) -> str:
        """One line for the terminal."""
        r = np.asarray(self.render_ms) if self.render_ms else np.zeros(1)
        audio = "silent"
        if self.audio is not None:
            audio = (
                f"audio {self.audio_device}: {self.audio.written:.1f} s played, "
                f"{self.audio.dropped:.2f} s dropped late"
            )
        parts = []
        if self.presented or not self.stills:
            rate = "" if self.stills else f", {self.fps:.1f} frames/s"
            parts.append(
                f"{self.presented} video frames presented, {self.dropped} dropped "
                f"({self.drop_percent:.1f} %){rate}"
            )
        if self.stills:
            parts.append(f"{self.stills} still image{'s' if self.stills != 1 else ''} shown")
        if self.display_losses:
            parts.append(
                f"display lost {self.display_losses} time{'s' if self.display_losses > 1 else ''}"
                f" ({self.unshown} frames due meanwhile not shown)"
            )
        inputs = "".join(
            f"; {source}: {c.applied} applied" + (f", {c.rejected} rejected" if c.rejected else "")
            for source, c in sorted(self.inputs.items())
        )
        return (
            f"{', '.join(parts)}, render {float(r.mean()):.1f} ms mean / "
            f"{float(np.percentile(r, 95)):.1f} ms p95, longest gap "
            f"{self.max_present_gap_ms:.0f} ms; {audio}{inputs}"
        )


@dataclass(frozen=True)
class PlayerStatus:
    """What the player shows now (``/viewcomp/status``, stdin ``status``).

    ``file`` the path of the file on screen, ``position`` the time of the frame on screen
    (seconds from the file's first frame), ``angle`` degrees and ``eye`` metres of the eye
    the frame on screen was drawn for, ``fps`` presented frames per second (smoothed),
    ``dropped`` late frames dropped so far, ``blackout`` whether the screen is black.
    """

    file: str
    position: float
    paused: bool
    angle: float
    eye: tuple[float, float, float]
    fps: float
    dropped: int
    blackout: bool

    def osc(self) -> bytes:
        """``/viewcomp/status s f i f f f f f i i`` (the fields in order)."""
        from pythonosc.osc_message_builder import OscMessageBuilder

        b = OscMessageBuilder(STATUS_ADDRESS)
        b.add_arg(self.file, "s")
        b.add_arg(float(self.position), "f")
        b.add_arg(int(self.paused), "i")
        b.add_arg(float(self.angle), "f")
        for v in self.eye:
            b.add_arg(float(v), "f")
        b.add_arg(float(self.fps), "f")
        b.add_arg(int(self.dropped), "i")
        b.add_arg(int(self.blackout), "i")
        return b.build().dgram

    def line(self) -> str:
        """One line for stdout: ``status file=... position=12.345 paused=0 ...``."""
        x, y, z = self.eye
        return (
            f"status file={self.file} position={self.position:.3f} paused={int(self.paused)} "
            f"angle={self.angle:.2f} eye={x:.4f},{y:.4f},{z:.4f} fps={self.fps:.1f} "
            f"dropped={self.dropped} blackout={int(self.blackout)}"
        )


@dataclass(frozen=True)
class PresentedFrame:
    """Handed to ``on_frame`` after a frame is drawn and before it is presented."""

    index: int
    file_index: int
    path: Path
    time: float
    due: float
    record: FrameRecord
    planes: Planes


@dataclass(frozen=True)
class _Shown:
    """The frame on screen: file index and path, its time, whether a still, when shown."""

    index: int
    path: Path
    time: float
    still: bool
    at: float
    eye: tuple[float, float, float]
    blackout: bool


class StatusReport:
    """The status, the overlay's lines and the drop log of
    :class:`~viewcomp.rt.play.player.Player` (a mixin; main thread)."""

    stats: PlayerStats
    renderer: LiveRenderer | None
    playlist: list[Path]
    _shown: _Shown | None
    _file: tuple[int, Path]
    _paused: bool
    _blackout: bool
    _fps_now: float
    _origin: float | None
    _drops_unlogged: int
    _drop_logged_at: float

    def _init_status(self) -> None:
        self.stats = PlayerStats()
        self._drops_unlogged = 0
        self._drop_logged_at = -math.inf
        self._fps_now = 0.0

    def status(self) -> PlayerStatus:
        """What is on screen now (main thread; see :class:`PlayerStatus`)."""
        shown = self._shown
        if shown is None:
            eye = tuple(float(v) for v in self.renderer.eye) if self.renderer else (0.0,) * 3
            file, position = str(self._file[1]), 0.0
        else:
            eye, file, position = shown.eye, str(shown.path), shown.time
        return PlayerStatus(
            file=file,
            position=position,
            paused=self._paused,
            angle=eye_to_polar(np.asarray(eye))[0],
            eye=eye,  # type: ignore[arg-type]
            fps=self._fps_now,
            dropped=self.stats.dropped,
            blackout=self._blackout if shown is None else shown.blackout,
        )

    def _dropped(self, now: float, due: float) -> None:
        self.stats.dropped += 1
        self._drops_unlogged += 1
        if now - self._drop_logged_at >= DROP_LOG_PERIOD:
            log.warning(
                "dropped %d late frame%s (%s at %.2f s; %d in all)",
                self._drops_unlogged,
                "s" if self._drops_unlogged > 1 else "",
                self._file[1].name,
                due - (self._origin or 0.0),
                self.stats.dropped,
            )
            self._drops_unlogged = 0
            self._drop_logged_at = now

    def _overlay_lines(self) -> tuple[str, ...]:
        assert self.renderer is not None
        eye = self.renderer.eye
        angle, _d, _h = eye_to_polar(eye)
        s = self.stats
        idx, path = self._file
        state = " PAUSED" if self._paused else ""
        aud = self.renderer.audience
        who = f"  ({len(aud)} viewers: their mean)" if aud is not None else ""
        return (
            f"angle {angle:6.1f} deg  eye ({eye[0]:+.3f}, {eye[1]:+.3f}, {eye[2]:+.3f}) m{who}",
            f"{self._fps_now:5.1f} fps  dropped {s.dropped} ({s.drop_percent:.1f} %)"
            + ("  COMPENSATION OFF" if self.renderer.identity else ""),
            f"file {idx + 1}/{len(self.playlist)}: {path.name[:40]}{state}",
        )
