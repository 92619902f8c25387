"""Live use: the fullscreen player, live eye input, the embedding API, a private X server.

- ``commands``: Live commands: the eye and show-control commands, their checks, the parsers
  of stdin lines and OSC messages.
- ``embed``: Compensation with a live eye into a host's framebuffer: the embedding API.
- ``embed_present``: Drawing the embedded renderer's frame into the host's target.
- ``embed_texture``: A frame from one of the host's GL textures into the embedded renderer.
- ``frame_record``: What one frame of the embedded renderer used.
- ``glfw_session``: glfw for viewcomp's windows: one initialised session and its monitors.
- ``live``: Live eye input for playback: parsing, validation, smoothing and the listener
  threads.
- ``listeners``: The listener threads of live input (OSC, lines) and the hub they fill.
- ``overlay``: The player's overlay: angle, eye, fps and drops drawn into a texture.
- ``player``: `viewcomp play`: fullscreen playback with a live viewing angle (glfw window, GL
  3.3): the state and the main loop.
- ``player_options``: How `viewcomp play` plays: ``PlayerOptions``.
- ``player_status``: What the player did and shows: statistics, status, the drop log.
- ``playlist``: The playlist and the pump thread: files in order, opened and decoded.
- ``show_control``: Show control and keys: pause, seek, next/previous, blackout, status.
- ``window``: The window and GL life cycle: window, context, renderer, threads, release.
- ``projector``: The projector of `viewcomp capture`: a fullscreen window showing each
  pattern pixel for pixel.
- ``tone_worker``: The tone map (and the paper method's model) on a worker thread.
- ``xvfb``: A private X server (Xvfb) for tests and headless runs of the player and of mpv.
"""
