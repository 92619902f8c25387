"""viewcomp's runtime: the GL compensator, video in/out and the headless render pipeline.

Modules (import what you need; nothing GL is imported here):

- :mod:`~viewcomp.rt.gl.context`: ``create_context()`` (EGL, GL 3.3), ``GLUnavailable``.
- :mod:`~viewcomp.rt.gl.compensator`: ``Compensator``, the shader for one ``RuntimeModel``.
- :mod:`~viewcomp.rt.media.frames`: yuv420p planes, the shared yuv -> RGB conversion, fitting.
- :mod:`~viewcomp.rt.media.video`: ``VideoReader`` (decode thread), ``VideoWriter``, ``VideoError``.
- :mod:`~viewcomp.rt.render.tracks`: eye tracks (constant angle/eye, CSV of seconds,degrees).
- :mod:`~viewcomp.rt.render.pipeline`: ``render_file`` for images and videos, both backends.
- :mod:`~viewcomp.rt.testing`: synthetic models, frames and clips for tests and benchmarks.
"""
