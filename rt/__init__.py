"""viewcomp's runtime: moderngl, glfw and PyAV; reads the runtime model, never fits.

Sub-packages, in the order a frame flows through them (nothing GL is imported here):

- ``media``: yuv420p frames, video decode (a worker thread) and encode, audio output; no GL.
- ``gl``: the headless OpenGL context, the one GL function loader, and the ``Compensator``
  that runs the shader for one ``RuntimeModel``.
- ``render``: ``viewcomp render``: images and videos through either backend, and eye tracks.
- ``play``: ``viewcomp play``: the fullscreen player, live eye input, the embedding API
  (``LiveRenderer``), the capture window and a private X server for headless runs.
- ``export``: ``viewcomp export-mpv``: the compensation as an mpv user shader.
- ``track``: ``viewcomp track``: faces in a camera's frames -> viewers' eye positions, live
  (OpenCV, no GL).
"""
