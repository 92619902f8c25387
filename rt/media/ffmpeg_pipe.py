"""Encoding through the system's ``ffmpeg`` program, for codecs PyAV's build lacks (HAP).

:class:`FfmpegPipeWriter` starts ``ffmpeg -f rawvideo -pix_fmt rgb24 -s WxH -framerate R -i
pipe:0 [-i INPUT] -c:v hap ...`` writing to a temporary file next to the output, pipes each
RGB frame to it and renames the file into place when ffmpeg exits cleanly. It has
:class:`~viewcomp.rt.media.video.VideoWriter`'s interface, so
:class:`~viewcomp.rt.media.video.EncodeThread` runs it.

Audio does not pass through Python: ffmpeg reads it from the input file itself (the first
audio stream), shifted so that the input video's first frame is at 0 as VideoWriter shifts
it (ffmpeg already moves the file's earliest timestamp to 0; ``-itsoffset`` adds the rest),
copied when the container takes its codec, else re-encoded (AAC in .mov). The
reader is therefore told ``audio_mode = "none"``. ffmpeg's messages go to a temporary file
(a full pipe would stall it) and its last lines make the error message when it fails.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from fractions import Fraction
from typing import Any

import numpy as np

from viewcomp.calib.errors import describe_os_error
from viewcomp.calib.io.atomic import AtomicFile
from viewcomp.rt.media.formats import OutputPlan
from viewcomp.rt.media.video import AudioMode, VideoError

_LOG_LINES = 3  # lines of ffmpeg's own messages quoted when it fails


class FfmpegPipeWriter:
    """Encode RGB frames with the ``ffmpeg`` program (HAP in .mov); atomic on success.

    Args:
        plan: a checked :class:`OutputPlan` whose codec is encoded by ffmpeg.
        width, height: frame size in pixels.
        rate: frames per second.
        audio_source: the input file to take the audio from (its first audio stream), or
            None for no audio.
        audio_codec: the input audio's codec name (copied or re-encoded as the plan says).
        audio_shift: seconds to move the audio earlier after ffmpeg's own shift (which puts
            the input file's earliest timestamp at 0): the video stream's start time minus
            the file's, >= 0.
    """

    audio_mode: AudioMode = "none"  # ffmpeg reads the audio from the input itself

    def __init__(
        self,
        plan: OutputPlan,
        width: int,
        height: int,
        rate: Fraction,
        audio_source: str | os.PathLike[str] | None = None,
        audio_codec: str | None = None,
        audio_shift: float = 0.0,
    ) -> None:
        assert plan.codec is not None and plan.profile is not None
        self.path = plan.path
        self.shape = (height, width, 3)
        self._index = 0
        self._closed = False
        exe = shutil.which("ffmpeg")
        if exe is None:
            raise VideoError(f"cannot write video {self.path}: no ffmpeg program on PATH")
        try:
            self._target = AtomicFile(self.path)
        except OSError as exc:
            raise VideoError(f"cannot write video {describe_os_error(exc, self.path)}") from exc
        self.tmp = self._target.tmp
        rate = Fraction(rate)
        cmd = [
            exe,
            "-hide_banner",
            "-loglevel",
            "error",
            "-y",
            "-f",
            "rawvideo",
            "-pix_fmt",
            "rgb24",
            "-s",
            f"{width}x{height}",
            "-framerate",
            f"{rate.numerator}/{rate.denominator}",
            "-i",
            "pipe:0",
        ]
        how = plan.audio_plan(audio_codec) if audio_source is not None else None
        if how is not None:
            if audio_shift:
                cmd += ["-itsoffset", f"{-audio_shift:.6f}"]
            cmd += ["-i", str(audio_source), "-map", "0:v:0", "-map", "1:a:0"]
            cmd += ["-c:a", "copy" if how[0] == "copy" else how[1]]
        else:
            cmd += ["-map", "0:v:0"]
        fmt = plan.codec.profiles[plan.profile][0] or plan.codec.encoder
        cmd += ["-c:v", plan.codec.encoder, "-format", fmt]
        cmd += ["-f", plan.container.muxer if plan.container else "mov", str(self.tmp)]
        self.command = cmd
        self._log = tempfile.TemporaryFile()
        try:
            self.proc = subprocess.Popen(
                cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=self._log
            )
        except OSError as exc:
            self._log.close()
            self._target.discard(exc)
            raise VideoError(f"cannot start ffmpeg for {self.path}: {exc}") from exc

    @property
    def frames_written(self) -> int:
        """Frames handed to ffmpeg so far."""
        return self._index

    def _failure(self, what: str) -> VideoError:
        self._log.seek(0)
        lines = self._log.read().decode("utf-8", "replace").strip().splitlines()
        said = " / ".join(lines[-_LOG_LINES:]) or "no message"
        return VideoError(
            f"cannot write video {self.path}: ffmpeg {what} ({said}); fix: check the disk and "
            "the input's audio, or use --codec prores_ks"
        )

    def write(self, rgb: np.ndarray) -> None:
        """Pipe one (H, W, 3) uint8 RGB frame to ffmpeg."""
        if rgb.shape != self.shape or rgb.dtype != np.uint8:
            raise ValueError(f"expected a {self.shape} uint8 frame, got {rgb.dtype} {rgb.shape}")
        assert self.proc.stdin is not None
        try:
            self.proc.stdin.write(np.ascontiguousarray(rgb).data)
        except BrokenPipeError as exc:
            self.proc.wait()
            raise self._failure(f"stopped (exit status {self.proc.returncode})") from exc
        self._index += 1

    def write_audio(self, item: Any) -> None:
        """The audio comes from the input file through ffmpeg: nothing to do."""

    def close(self) -> None:
        """Let ffmpeg finish, then move the file into place (or raise with its message)."""
        if self._closed:
            return
        try:
            assert self.proc.stdin is not None
            try:
                self.proc.stdin.close()
            except BrokenPipeError:
                pass  # ffmpeg has exited: its status says why
            rc = self.proc.wait()
            if rc != 0:
                raise self._failure(f"failed (exit status {rc})")
        except BaseException as exc:  # undo on any failure, Ctrl-C included; then re-raise
            self._abort(exc)
            raise
        self._closed = True
        self._log.close()
        try:
            self._target.commit()
        except OSError as exc:
            raise VideoError(f"cannot write video {describe_os_error(exc, self.path)}") from exc

    def abort(self) -> None:
        """Stop ffmpeg and delete the temporary file; no output is left."""
        self._abort(None)

    def _abort(self, cause: BaseException | None) -> None:
        if self._closed:
            return
        self._closed = True
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        if self.proc.stdin is not None:
            try:
                self.proc.stdin.close()
            except BrokenPipeError:
                pass
        self._log.close()
        self._target.discard(cause)
