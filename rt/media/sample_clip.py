"""A source clip from RGB frames: untagged yuv420p H.264 with a tone, the demo's input.

It writes the planes itself, untagged, on purpose: the reader's colour-metadata guessing and
audio remuxing get exercised, which the product's
:class:`viewcomp.rt.media.video.VideoWriter` (tagged, atomic) never does.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np


def write_clip(
    path: str,
    frames: Iterable[np.ndarray],
    rate: int,
    tone: bool = True,
    audio_codec: str = "aac",
    sample_rate: int = 48000,
    codec: str = "libx264",
    options: dict[str, str] | None = None,
) -> None:
    """Encode RGB frames (H, W, 3) uint8 as an untagged yuv420p clip (BT.601 matrix, limited
    range) at ``rate`` fps, with a mono 440 Hz tone as long as the video if ``tone``.

    A source clip for tests, benchmarks and the demo. It writes the planes itself, untagged,
    on purpose: the reader's colour-metadata guessing and audio remuxing get exercised, which
    the product's :class:`viewcomp.rt.media.video.VideoWriter` (tagged, atomic) never does.
    Odd frame sizes are cropped to even ones.
    """
    import av  # only the video helpers need PyAV

    from viewcomp.rt.media.frames import rgb_to_yuv420p

    n = 0
    with av.open(path, "w") as out:
        vs = out.add_stream(codec, rate=rate)
        vs.pix_fmt = "yuv420p"
        if options:
            vs.options = options
        aus = None
        if tone:
            aus = out.add_stream(audio_codec, rate=sample_rate)
            aus.layout = "mono"
        for rgb in frames:
            h, w = rgb.shape[0] - rgb.shape[0] % 2, rgb.shape[1] - rgb.shape[1] % 2
            if n == 0:
                vs.width, vs.height = w, h
            planes = rgb_to_yuv420p(np.ascontiguousarray(rgb[:h, :w]), "bt601")
            frame = av.VideoFrame(w, h, "yuv420p")
            for plane, arr in zip(frame.planes, (planes.y, planes.u, planes.v), strict=True):
                view = np.frombuffer(plane, np.uint8).reshape(plane.height, plane.line_size)
                view[:, : plane.width] = arr
            frame.pts = n
            n += 1
            for packet in vs.encode(frame):
                out.mux(packet)
        for packet in vs.encode(None):
            out.mux(packet)
        if aus is not None:
            total = round(n / rate * sample_rate)
            chunk = 1024
            for start in range(0, total, chunk):
                k = min(chunk, total - start)
                t = (np.arange(start, start + k) / sample_rate).astype(np.float32)
                samples = (0.3 * np.sin(2 * np.pi * 440.0 * t)).astype(np.float32)[None, :]
                af = av.AudioFrame.from_ndarray(samples, format="fltp", layout="mono")
                af.sample_rate = sample_rate
                af.pts = start
                for packet in aus.encode(af):
                    out.mux(packet)
            for packet in aus.encode(None):
                out.mux(packet)
