"""The headless OpenGL 3.3 context (moderngl standalone, EGL), with one clear error if absent."""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
from collections.abc import Callable
from typing import Any

import moderngl

from viewcomp.calib.errors import GLUnavailable

GL_FIX = (
    "install the Debian packages libegl1 libgl1 libgl1-mesa-dri (scripts/setup.sh does it); "
    "Mesa llvmpipe (no GPU) is enough"
)


def create_context(require: int = 330) -> moderngl.Context:
    """A standalone moderngl context through EGL (headless), OpenGL >= ``require``.

    The context is current on the calling thread; use it from that thread only. Its
    ``gc_mode`` is ``"context_gc"``: an object dropped without ``release()`` is queued on
    ``ctx.objects`` (and freed by ``ctx.gc()``), so leaks are visible instead of silent.

    Raises:
        GLUnavailable: EGL or the GL driver is missing, or the version is below ``require``.
    """
    try:
        # moderngl's stub types **settings as dicts; backend is a string (moderngl's docs)
        ctx = moderngl.create_standalone_context(backend="egl", require=require)  # type: ignore[arg-type]
    except Exception as exc:  # moderngl/glcontext raise plain Exception for a missing lib
        raise GLUnavailable(
            f"cannot create an OpenGL {require // 100}.{require % 100 // 10} context through "
            f"EGL ({type(exc).__name__}: {exc}); fix: {GL_FIX}"
        ) from exc
    ctx.gc_mode = "context_gc"
    return ctx


def _gl_void(name: bytes) -> Any:
    """A GL entry point ``void name(void)`` through eglGetProcAddress (ctypes), or None."""
    try:
        return gl_function(name.decode(), (), None)
    except GLUnavailable:
        return None


def core_profile_hints(glfw: Any) -> None:
    """glfw window hints for an OpenGL 3.3 core, forward-compatible context (the project's)."""
    glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 3)
    glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
    glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
    glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)


def finish(ctx: moderngl.Context) -> None:
    """``glFinish`` without holding Python's GIL (moderngl's ``ctx.finish()`` holds it).

    On llvmpipe a draw runs on the driver's threads while the caller waits here; through
    ctypes (which releases the GIL around the call) the decoder and encoder threads keep
    running Python meanwhile. Falls back to ``ctx.finish()`` without an EGL ``glFinish``.
    """
    fn = _gl_void(b"glFinish")
    if fn is not None:
        fn()
    else:
        ctx.finish()


def flush(ctx: moderngl.Context) -> None:
    """``glFlush``: start the queued draws now (llvmpipe renders on its own threads)."""
    fn = _gl_void(b"glFlush")
    if fn is not None:
        fn()


_GL_TEXTURE_BUFFER = 0x8C2A
_GL_TEXTURE0 = 0x84C0
BUFFER_FORMATS = {"r32f": 0x822E, "rg32f": 0x8230, "rgba32f": 0x8814, "rgba32ui": 0x8D70}


ProcAddress = Callable[[str], int]  # a GL function loader: name -> address (0: none)


@functools.cache
def libegl() -> ctypes.CDLL:
    """The system's libEGL, loaded once (raises OSError when it is missing)."""
    return ctypes.CDLL(ctypes.util.find_library("EGL") or "libEGL.so.1")


@functools.cache
def egl_proc_address() -> ProcAddress:
    """EGL's ``eglGetProcAddress`` as a loader (libglvnd also dispatches it to a current GLX
    context). Raises OSError without libEGL."""
    fn = libegl().eglGetProcAddress
    fn.restype = ctypes.c_void_p
    fn.argtypes = [ctypes.c_char_p]
    return lambda name: int(fn(name.encode()) or 0)


def default_proc_address() -> ProcAddress:
    """A GL function loader for the context current on this thread.

    glfw's when a glfw context is current, else EGL's ``eglGetProcAddress``, else GLX's
    ``glXGetProcAddressARB`` (Mesa and libglvnd dispatch either to the current context).

    Raises:
        GLUnavailable: none of them can be loaded.
    """
    try:
        import glfw

        if glfw.get_current_context():
            return lambda name: int(glfw.get_proc_address(name) or 0)
    except Exception:  # glfw missing or not initialised: try the system loaders
        pass
    try:
        return egl_proc_address()
    except (OSError, AttributeError):
        pass
    path = ctypes.util.find_library("GL")
    try:
        fn = ctypes.CDLL(path).glXGetProcAddressARB if path else None
    except (OSError, AttributeError):
        fn = None
    if fn is None:
        raise GLUnavailable(f"no GL function loader (glfw, EGL or GLX) found; fix: {GL_FIX}")
    fn.restype = ctypes.c_void_p
    fn.argtypes = [ctypes.c_char_p]
    return lambda name: int(fn(name.encode()) or 0)


@functools.cache
def gl_function(
    name: str, argtypes: tuple[Any, ...], loader: ProcAddress | None = None, restype: Any = None
) -> Any:
    """``restype name(*argtypes)`` of the current GL context as a ctypes function (which
    releases the GIL around each call), through ``loader`` (default: EGL's eglGetProcAddress).

    Raises:
        GLUnavailable: no libEGL, or the driver lacks ``name``.
    """
    try:
        addr = (loader or egl_proc_address())(name)
    except OSError as exc:  # no libEGL
        raise GLUnavailable(f"cannot load GL functions ({exc}); fix: {GL_FIX}") from exc
    if not addr:
        raise GLUnavailable(f"the GL driver has no {name} (OpenGL 3.3 needed); fix: {GL_FIX}")
    return ctypes.CFUNCTYPE(restype, *argtypes)(addr)


def set_sampler_units(
    program: moderngl.Program, units: dict[str, int], loader: ProcAddress | None = None
) -> None:
    """Point sampler uniforms at texture units with ``glUniform1i``, any sampler type.

    moderngl's ``program[name].value = unit`` does not take buffer samplers
    (``samplerBuffer``); this works for every kind. Leaves no program bound. ``loader``: the
    GL function loader of the host's windowing library (default: EGL's).
    """
    use = gl_function("glUseProgram", (ctypes.c_uint,), loader)
    uniform1i = gl_function("glUniform1i", (ctypes.c_int, ctypes.c_int), loader)
    use(program.glo)
    for name, unit in units.items():
        member = program[name]
        assert isinstance(member, moderngl.Uniform), f"{name} is not a uniform"
        uniform1i(member.location, unit)
    use(0)


class BufferTexture:
    """A buffer texture (GLSL ``samplerBuffer``/``usamplerBuffer``): ``texelFetch(t, i)``.

    moderngl has no buffer textures; this one pairs a moderngl :class:`~moderngl.Buffer`
    (the data, written with :meth:`write` or filled by ``Framebuffer.read_into``) with a GL
    texture name made and deleted through ctypes. On llvmpipe a ``texelFetch`` from it costs
    ~0.7x a NEAREST ``textureLod`` from a 2D texture (an index: no coordinate arithmetic).
    Use it on the thread where its context is current; :meth:`release` frees both objects.
    ``loader``: the GL function loader of the host's windowing library (default: EGL's).
    """

    def __init__(
        self,
        ctx: moderngl.Context,
        data: Any,
        fmt: str,
        reserve: int = 0,
        loader: ProcAddress | None = None,
    ) -> None:
        uint, pname = ctypes.c_uint, ctypes.POINTER(ctypes.c_uint)
        self._gl = {  # resolved before anything is made: a failure leaves nothing behind
            "gen": gl_function("glGenTextures", (ctypes.c_int, pname), loader),
            "delete": gl_function("glDeleteTextures", (ctypes.c_int, pname), loader),
            "bind": gl_function("glBindTexture", (uint, uint), loader),
            "active": gl_function("glActiveTexture", (uint,), loader),
            "tex_buffer": gl_function("glTexBuffer", (uint, uint, uint), loader),
        }
        internal_format = BUFFER_FORMATS[fmt]
        self.buffer = ctx.buffer(data, reserve=reserve)
        name = ctypes.c_uint(0)
        self._gl["gen"](1, ctypes.byref(name))
        self.name = name.value
        self._gl["bind"](_GL_TEXTURE_BUFFER, self.name)
        self._gl["tex_buffer"](_GL_TEXTURE_BUFFER, internal_format, self.buffer.glo)
        self._gl["bind"](_GL_TEXTURE_BUFFER, 0)

    @property
    def mglo(self) -> Any:
        """The buffer's moderngl handle: ``moderngl.InvalidObject`` once released."""
        return self.buffer.mglo

    def write(self, data: Any, offset: int = 0) -> None:
        """Overwrite the texels from byte ``offset`` on."""
        self.buffer.write(data, offset=offset)

    def use(self, unit: int) -> None:
        """Bind to texture unit ``unit`` (its GL_TEXTURE_BUFFER target)."""
        self._gl["active"](_GL_TEXTURE0 + unit)
        self._gl["bind"](_GL_TEXTURE_BUFFER, self.name)

    def release(self) -> None:
        """Delete the texture name and release the buffer. Idempotent."""
        if self.name:
            name = ctypes.c_uint(self.name)
            self._gl["delete"](1, ctypes.byref(name))
            self.name = 0
        self.buffer.release()


_IS_FUNCS = {
    "textures": "glIsTexture",
    "buffers": "glIsBuffer",
    "framebuffers": "glIsFramebuffer",
    "renderbuffers": "glIsRenderbuffer",
    "vertex_arrays": "glIsVertexArray",
    "programs": "glIsProgram",
    "shaders": "glIsShader",
}


def live_gl_objects(ctx: moderngl.Context, upto: int = 16384) -> dict[str, int]:
    """Count the GL objects alive in the current context, per kind, by GL name 1..upto.

    Asks the driver (``glIsTexture`` etc. through ``eglGetProcAddress``), so it sees what
    moderngl's bookkeeping cannot. Mesa never reuses names, hence the scan. For the soak test
    and the benchmark; needs the EGL context of :func:`create_context` to be current.
    """
    ctx.finish()
    # A deleted program stays alive while it is the current one: unbind it first.
    gl_function("glUseProgram", (ctypes.c_uint,))(0)
    counts = {}
    for kind, name in _IS_FUNCS.items():
        fn = gl_function(name, (ctypes.c_uint,), None, ctypes.c_ubyte)
        counts[kind] = sum(1 for i in range(1, upto + 1) if fn(i))
    return counts
