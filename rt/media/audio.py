"""Audio output for playback: ALSA through ctypes, silent when there is no device.

The wall clock leads (:mod:`viewcomp.rt.play.player`): each decoded audio frame is due at
``origin + t`` (the same origin as the video frames of its file). :class:`AudioPlayer`
resamples to 16-bit stereo at 48 kHz, writes a chunk when it is due within ``lead``
seconds, and drops a chunk that would be heard more than ``late`` seconds after its due
time (the device's clock drifting behind, or an underrun): A/V sync is bounded by ``late``
and never drifts. A device that does not pace (ALSA ``null``) is paced by the same rule.

No device (no sound card, no ``default`` PCM, libasound missing): :func:`open_alsa` returns
None with one log line and playback is silent. libasound is the Debian package libasound2
(already a dependency of FFmpeg); with PulseAudio or PipeWire the ``default`` PCM reaches
them through the ALSA plug-ins (libasound2-plugins / pipewire-alsa).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from viewcomp.calib.errors import AudioDeviceError

log = logging.getLogger(__name__)

RATE = 48000
CHANNELS = 2
_SND_PCM_STREAM_PLAYBACK = 0
_SND_PCM_FORMAT_S16_LE = 2
_SND_PCM_ACCESS_RW_INTERLEAVED = 3

_ERROR_HANDLER = ctypes.CFUNCTYPE(
    None, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p
)
_LIB: dict[str, Any] = {}


def _silence(*_args: object) -> None:
    """libasound's error printer, replaced: its messages go to our log instead."""


_SILENCE = _ERROR_HANDLER(_silence)


def _libasound() -> Any | None:
    """libasound.so.2 with prototypes set, or None when it is not installed."""
    if "lib" not in _LIB:
        try:
            lib = ctypes.CDLL(ctypes.util.find_library("asound") or "libasound.so.2")
        except OSError:
            _LIB["lib"] = None
            return None
        lib.snd_strerror.restype = ctypes.c_char_p
        lib.snd_strerror.argtypes = [ctypes.c_int]
        lib.snd_pcm_open.argtypes = [
            ctypes.POINTER(ctypes.c_void_p), ctypes.c_char_p, ctypes.c_int, ctypes.c_int,
        ]  # fmt: skip
        lib.snd_pcm_set_params.argtypes = [
            ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_uint, ctypes.c_uint,
            ctypes.c_int, ctypes.c_uint,
        ]  # fmt: skip
        lib.snd_pcm_writei.restype = ctypes.c_long
        lib.snd_pcm_writei.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_ulong]
        lib.snd_pcm_delay.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_long)]
        lib.snd_pcm_recover.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int]
        lib.snd_pcm_drop.argtypes = [ctypes.c_void_p]
        lib.snd_pcm_close.argtypes = [ctypes.c_void_p]
        lib.snd_lib_error_set_handler.argtypes = [_ERROR_HANDLER]
        lib.snd_lib_error_set_handler(_SILENCE)
        _LIB["lib"] = lib
    return _LIB["lib"]


class AlsaOutput:
    """A blocking ALSA playback PCM, S16_LE interleaved, ``channels`` at ``rate`` Hz.

    Use :func:`open_alsa`. ``latency`` is the device buffer in seconds (ALSA may round it).
    """

    def __init__(self, lib: Any, handle: ctypes.c_void_p, name: str, rate: int, channels: int):
        self._lib = lib
        self._h = handle
        self.name = name
        self.rate = rate
        self.channels = channels

    def write(self, samples: np.ndarray) -> None:
        """Write (n, channels) int16 samples; blocks while the device buffer is full.

        Raises:
            AudioDeviceError: the device failed and could not be recovered.
        """
        data = np.ascontiguousarray(samples, dtype=np.int16)
        frames = data.shape[0]
        done = 0
        while done < frames:
            ptr = data[done:].ctypes.data
            n = int(self._lib.snd_pcm_writei(self._h, ptr, ctypes.c_ulong(frames - done)))
            if n < 0:
                if int(self._lib.snd_pcm_recover(self._h, n, 1)) < 0:
                    raise AudioDeviceError(f"ALSA {self.name}: {self._lib.snd_strerror(n)}")
                continue
            done += n

    def delay(self) -> float:
        """Seconds until a sample written now is heard (0 if the device cannot say)."""
        d = ctypes.c_long(0)
        if int(self._lib.snd_pcm_delay(self._h, ctypes.byref(d))) < 0:
            return 0.0
        return max(int(d.value), 0) / self.rate

    def close(self) -> None:
        """Stop at once (pending samples dropped) and close the device. Idempotent."""
        if self._h:
            self._lib.snd_pcm_drop(self._h)
            self._lib.snd_pcm_close(self._h)
            self._h = ctypes.c_void_p()


def open_alsa(
    device: str = "default", rate: int = RATE, channels: int = CHANNELS, latency: float = 0.1
) -> AlsaOutput | None:
    """Open an ALSA PCM for playback, or None (logged once) when there is none."""
    lib = _libasound()
    if lib is None:
        log.info("audio: libasound.so.2 not found (Debian: libasound2); playing silently")
        return None
    h = ctypes.c_void_p()
    err = int(lib.snd_pcm_open(ctypes.byref(h), device.encode(), _SND_PCM_STREAM_PLAYBACK, 0))
    if err < 0:
        log.info(
            "audio: no ALSA device %r (%s); playing silently",
            device,
            lib.snd_strerror(err).decode(errors="replace"),
        )
        return None
    err = int(
        lib.snd_pcm_set_params(
            h,
            _SND_PCM_FORMAT_S16_LE,
            _SND_PCM_ACCESS_RW_INTERLEAVED,
            channels,
            rate,
            1,
            int(latency * 1e6),
        )
    )
    if err < 0:
        log.info(
            "audio: ALSA device %r refuses %d Hz stereo (%s); playing silently",
            device,
            rate,
            lib.snd_strerror(err).decode(errors="replace"),
        )
        lib.snd_pcm_close(h)
        return None
    return AlsaOutput(lib, h, device, rate, channels)


@dataclass
class AudioStats:
    """Seconds of audio written to the device and dropped as late; chunks of each."""

    written: float = 0.0
    dropped: float = 0.0
    chunks: int = 0
    dropped_chunks: int = 0
    failed: str = ""


@dataclass
class _Chunk:
    seq: int
    t: float
    frame: Any


class AudioPlayer:
    """Plays decoded audio frames on the wall clock, on its own thread.

    Args:
        output: an opened device (:func:`open_alsa`), or any object with ``rate``,
            ``channels``, ``write(int16 (n, ch))``, ``delay() -> s`` and ``close()``.
        clock: the wall clock (seconds); the player's.
        lead: write a chunk when it is due within this many seconds.
        late: drop a chunk that would be heard later than this after its due time.

    ``feed(seq, t, frame)`` from the decoding side (``seq`` numbers the played file, ``t``
    seconds from its start); ``set_origin(seq, wall)`` from the playback side when the
    file's first video frame is scheduled. Chunks of a file wait for its origin.
    """

    def __init__(
        self,
        output: Any,
        clock: Callable[[], float] = time.monotonic,
        lead: float = 0.12,
        late: float = 0.08,
        max_queue: int = 512,
    ) -> None:
        import av

        self.output = output
        self.clock = clock
        self.lead, self.late = lead, late
        self.stats = AudioStats()
        self._queue: queue.Queue[_Chunk] = queue.Queue(maxsize=max_queue)
        self._origins: dict[int, float] = {}
        self._cancelled = -1  # files numbered up to this one are not to be heard
        self._cond = threading.Condition()
        self._stop = threading.Event()
        layout = "stereo" if output.channels == 2 else "mono"
        self._resampler = av.AudioResampler(format="s16", layout=layout, rate=output.rate)
        self._thread = threading.Thread(target=self._run, name="viewcomp-audio", daemon=True)
        self._thread.start()

    def feed(self, seq: int, t: float, frame: Any) -> bool:
        """Queue a decoded audio frame; blocks while the queue is full. False once stopped."""
        item = _Chunk(seq, t, frame)
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def set_origin(self, seq: int, wall: float) -> None:
        """File ``seq`` starts (t = 0) at wall-clock time ``wall``."""
        with self._cond:
            self._origins[seq] = wall
            for old in [k for k in self._origins if k < seq - 4]:
                del self._origins[old]
            self._cond.notify_all()

    def cancel(self, seq: int) -> None:
        """Drop the audio of file ``seq`` and earlier (a pause, seek, next or previous)."""
        with self._cond:
            self._cancelled = max(self._cancelled, seq)
            self._cond.notify_all()

    def _origin(self, seq: int) -> float | None:
        with self._cond:
            while seq not in self._origins and not self._stop.is_set():
                if seq <= self._cancelled or any(k > seq for k in self._origins):
                    return None  # that file was skipped or cancelled: its audio is stale
                self._cond.wait(0.1)
            if seq <= self._cancelled:
                return None
            return self._origins.get(seq)

    def _samples(self, frame: Any) -> np.ndarray:
        parts = [
            f.to_ndarray().reshape(-1, self.output.channels)
            for f in self._resampler.resample(frame)
        ]
        if not parts:
            return np.zeros((0, self.output.channels), np.int16)
        return np.concatenate(parts).astype(np.int16, copy=False)

    def _run(self) -> None:
        rate = float(self.output.rate)
        while not self._stop.is_set():
            try:
                chunk = self._queue.get(timeout=0.1)
            except queue.Empty:
                continue
            origin = self._origin(chunk.seq)
            if origin is None:
                continue
            try:
                samples = self._samples(chunk.frame)
            except Exception as exc:  # a broken audio frame is dropped, the rest plays on
                log.warning("audio: cannot convert a frame at %.2f s: %s", chunk.t, exc)
                continue
            seconds = samples.shape[0] / rate
            due = origin + chunk.t
            wait = due - self.lead - self.clock()
            if wait > 0 and self._stop.wait(wait):
                return
            heard = self.clock() + self.output.delay()
            if heard > due + self.late:
                self.stats.dropped += seconds
                self.stats.dropped_chunks += 1
                continue
            try:
                self.output.write(samples)
            except AudioDeviceError as exc:
                log.warning("audio: %s; playing on silently", exc)
                self.stats.failed = str(exc)
                return
            self.stats.written += seconds
            self.stats.chunks += 1

    def stop(self) -> None:
        """Stop the thread and close the device. Idempotent."""
        self._stop.set()
        with self._cond:
            self._cond.notify_all()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        self.output.close()
