"""viewcomp's runtime: the GL compensator, video in/out and the headless render pipeline.

Modules (import what you need; nothing GL is imported here):

- :mod:`~viewcomp.rt.context`: ``create_context()`` (EGL, GL 3.3), ``GLUnavailable``.
- :mod:`~viewcomp.rt.compensator`: ``Compensator``, the shader for one ``RuntimeModel``.
- :mod:`~viewcomp.rt.frames`: yuv420p planes, the shared yuv -> RGB conversion, fitting.
- :mod:`~viewcomp.rt.video`: ``VideoReader`` (decode thread), ``VideoWriter``, ``VideoError``.
- :mod:`~viewcomp.rt.tracks`: eye tracks (constant angle/eye, CSV of seconds,degrees).
- :mod:`~viewcomp.rt.pipeline`: ``render_file`` for images and videos, both backends.
- :mod:`~viewcomp.rt.testing`: synthetic models, frames and clips for tests and benchmarks.
"""
