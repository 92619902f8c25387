"""Media I/O without GL: yuv420p frames, video decode/encode (PyAV), audio output.

- ``audio``: Audio output for playback: ALSA through ctypes, silent when there is no device.
- ``encode_thread``: Encoding on its own thread: a VideoWriter fed frames and audio in order.
- ``frames``: CPU-side frames: yuv420p planes, their conversion to RGB, thumbnails and fitting.
- ``sample_clip``: A source clip from RGB frames (untagged yuv420p with a tone): the demo's
  input.
- ``video``: Video in and out with PyAV: a threaded decoder yielding yuv420p planes, and an
  encoder.
"""
