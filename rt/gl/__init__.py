"""OpenGL: the headless context and the Compensator that runs the shader.

- ``compensator``: The GL compensator: the formula of docs/RUNTIME.md in a fragment shader,
  embeddable.
- ``context``: The headless OpenGL 3.3 context (moderngl standalone, EGL), with one clear error
  if absent, and the one GL function loader (``gl_function``, ``default_proc_address``).
- ``frame_io``: Frames in and out of the GL compensator: uploads and read-back.
- ``egl_suspend``: Releasing the EGL context current on this thread while a window's GLX
  context is used.
- ``shader_passes``: The compensator's programs (one per variant) and per-frame values.
- ``state_guard``: Saving and restoring a host's GL state around viewcomp's drawing, and the
  raw GL calls moderngl lacks.
- ``view_cache``: The compensator's view cache: a held eye's per-pixel solve, done once.
"""
