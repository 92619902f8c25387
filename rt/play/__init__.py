"""Live use: the fullscreen player, live eye input, the embedding API, a private X server.

- ``embed``: Compensation with a live eye into a host's framebuffer: the embedding API.
- ``glfw_session``: glfw for viewcomp's windows: one initialised session and its monitors.
- ``live``: Live eye input for playback: parsing, validation, smoothing and the listener
  threads.
- ``player``: `viewcomp play`: fullscreen playback with a live viewing angle (glfw window, GL
  3.3).
- ``projector``: The projector of `viewcomp capture`: a fullscreen window showing each
  pattern pixel for pixel.
- ``xvfb``: A private X server (Xvfb) for tests and headless runs of the player and of mpv.
"""
