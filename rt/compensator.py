"""The GL compensator: the formula of docs/RUNTIME.md in a fragment shader, embeddable.

:class:`Compensator` owns every GL object it uses (program, vertex array, textures, an
RGBA8 framebuffer) and releases them all in :meth:`Compensator.release` (or on leaving a
``with`` block). It never scales: frames must be exactly the model's (H, W) grid.

Typical use::

    with Compensator(model) as comp:
        comp.set_angle(60.0, distance=0.5, height=0.035)
        comp.set_tone(alpha, beta)
        out = comp.render(frame)              # (H, W, 3) uint8 -> (H, W, 3) uint8

Threading: call it from the thread whose GL context is current (the thread that made it).
"""

from __future__ import annotations

import math
from typing import Any

import moderngl
import numpy as np

from viewcomp.calib.reference import RuntimeModel, lut_forward
from viewcomp.rt.context import create_context
from viewcomp.rt.frames import Planes, yuv_coefficients
from viewcomp.shaders import build_program

_METHODS = {"identity": 0, "pixel": 1, "paper": 2}
_SAMPLERS = "u_rgb u_y u_uv u_fwd u_inv u_w0 u_w1 u_w2 u_c0 u_c1 u_c2 u_refl u_pos".split()


def eye_from_angle(deg: float, distance: float, height: float) -> np.ndarray:
    """E = (d cos t, h, d sin t) in metres for viewing angle t (degrees); 90 = straight on."""
    t = math.radians(deg)
    return np.array([distance * math.cos(t), height, distance * math.sin(t)], np.float32)


def camera_lobe(refl: np.ndarray, pos: np.ndarray, cam_eye: np.ndarray, gamma: float) -> np.ndarray:
    """max(R . normalize(E_cam - p), 0)^gamma, (H, W) float32, as reference.lobe_change does."""
    vc = cam_eye.astype(np.float32) - pos
    vc /= np.linalg.norm(vc, axis=-1, keepdims=True)
    return (np.maximum(np.sum(refl * vc, axis=-1), 0.0) ** np.float32(gamma)).astype(np.float32)


def _inv_pairs(inv_lut: np.ndarray, n: int) -> np.ndarray:
    """(3, N, 2) float32: [c, i] = (inv_lut[i, c], inv_lut[i + 1, c]) (last pair repeats)."""
    lut = _f32(inv_lut, (n, 3), "inv_lut")
    out = np.empty((3, n, 2), np.float32)
    out[:, :, 0] = lut.T
    out[:, :-1, 1] = lut[1:].T
    out[:, -1, 1] = lut[-1]
    return out


def _f32(a: Any, shape: tuple[int, ...], name: str) -> np.ndarray:
    arr = np.ascontiguousarray(np.asarray(a, dtype=np.float32))
    if arr.shape != shape:
        raise ValueError(f"{name} must be {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} holds NaN or infinite values")
    return arr


class Compensator:
    """Runs the compensation shader for one :class:`RuntimeModel` on an (H, W) grid.

    Args:
        model: the runtime model (method ``pixel`` or ``paper``; ``identity`` also works and
            needs only the LUTs). Per-pixel arrays are uploaded once here.
        ctx: a moderngl context (>= 3.3) current on this thread; ``None`` creates a
            standalone EGL one, which this object then owns and releases.

    State (uniforms) defaults: eye = ``model.cam_eye``, alpha = 1, beta = 0, compensation on.
    """

    def __init__(self, model: RuntimeModel, ctx: moderngl.Context | None = None) -> None:
        self._own_ctx = ctx is None
        self.ctx: moderngl.Context = create_context() if ctx is None else ctx
        self._objects: list[Any] = []
        self._released = False
        try:
            self._setup(model)
        except BaseException:
            self.release()
            raise

    # ----------------------------------------------------------------- construction
    def _track(self, obj: Any) -> Any:
        self._objects.append(obj)
        return obj

    def _tex(self, size: tuple[int, int], comps: int, dtype: str, data: Any = None) -> Any:
        tex = self._track(self.ctx.texture(size, comps, data, dtype=dtype, alignment=1))
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)  # texelFetch only; integer textures
        tex.repeat_x = tex.repeat_y = False  # need NEAREST to be complete
        return tex

    def _setup(self, model: RuntimeModel) -> None:
        if model.method not in _METHODS:
            raise ValueError(f"model.method must be one of {sorted(_METHODS)}, got {model.method}")
        h, w = model.shape
        self.method: str = model.method
        self.height, self.width = h, w
        max_size = int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])
        n_inv = int(np.asarray(model.inv_lut).shape[0])
        if max(w, h, n_inv) > max_size:
            raise ValueError(
                f"grid {w}x{h} / inverse LUT of {n_inv} entries exceeds GL_MAX_TEXTURE_SIZE "
                f"{max_size}"
            )
        if n_inv < 2:
            raise ValueError(f"inv_lut needs at least 2 entries, got {n_inv}")
        self._n_inv = n_inv

        self._uniforms: dict[str, Any] = {}
        self._programs: dict[tuple[int, int], tuple[Any, Any]] = {}
        self._input = 0
        self._color = self._track(self.ctx.renderbuffer((w, h), 4, dtype="f1"))
        self.fbo = self._track(self.ctx.framebuffer(color_attachments=[self._color]))

        self._rgb = self._tex((w, h), 3, "u1")
        self._y = self._tex((w, h), 1, "u1")
        cw, ch = (w + 1) // 2, (h + 1) // 2
        self._uv = self._tex((cw, ch), 2, "u1")
        self._uv_host = np.empty((ch, cw, 2), np.uint8)
        fwd = _f32(model.fwd_lut, (256, 3), "fwd_lut")
        levels = np.broadcast_to(np.arange(256, dtype=np.float32)[:, None], (256, 3))
        fwd4 = np.zeros((256, 4), np.float32)
        fwd4[:, :3] = lut_forward(fwd, levels)  # exact values at integer levels
        self._fwd = self._tex((256, 1), 4, "f4", fwd4)
        self._inv = self._tex((n_inv, 3), 2, "f4", _inv_pairs(model.inv_lut, n_inv))
        units: dict[str, Any] = {
            "u_rgb": self._rgb, "u_y": self._y, "u_uv": self._uv,
            "u_fwd": self._fwd, "u_inv": self._inv,
        }  # fmt: skip
        if model.method == "pixel":
            units.update(self._upload_pixel_maps(model))
        self._units = [(i, units.get(name)) for i, name in enumerate(_SAMPLERS)]

        self._set("u_size", (w, h))
        self._set("u_origin", (0, 0))
        self._set("u_flip_y", 0)
        self.identity = False
        self._set("u_inv_lo", tuple(_f32(model.inv_lo, (3,), "inv_lo")))
        self._set("u_inv_hi", tuple(_f32(model.inv_hi, (3,), "inv_hi")))
        self._cam_eye = _f32(model.cam_eye, (3,), "cam_eye")
        if model.method == "pixel":
            self._set("u_kappa", tuple(_f32(model.kappa, (3,), "kappa")))
            self._set("u_gamma", float(model.gamma))
        if model.method == "paper":
            self._set("u_Ww", tuple(_f32(model.Ww, (3, 3), "Ww").T.ravel()))  # column-major
            if model.Wc_inv is None:
                raise ValueError("paper method needs model.Wc_inv (3, 3)")
            self._set("u_Wc_inv", tuple(_f32(model.Wc_inv, (3, 3), "Wc_inv").T.ravel()))
        self.set_eye(*self._cam_eye)
        self.set_tone(1.0, 0.0)
        self._yuv_key: tuple[str, str] | None = None
        self._readback = np.empty((h, w, 4), np.uint8)

    def _upload_pixel_maps(self, model: RuntimeModel) -> dict[str, Any]:
        h, w = model.shape
        units: dict[str, Any] = {}
        for key, mat, amb in (("w", model.Ww, model.Aw), ("c", model.Wc, model.Ac)):
            if mat is None or amb is None:
                raise ValueError("pixel method needs Ww, Wc (H, W, 3, 3) and Aw, Ac (H, W, 3)")
            m = _f32(mat, (h, w, 3, 3), f"W{key}")
            a = _f32(amb, (h, w, 3), f"A{key}")
            for row in range(3):
                rgba = np.empty((h, w, 4), np.float32)
                rgba[..., :3] = m[:, :, row, :]
                rgba[..., 3] = a[..., row]
                units[f"u_{key}{row}"] = self._tex((w, h), 4, "f4", rgba)
        refl = _f32(model.refl, (h, w, 3), "refl")
        pos = _f32(model.pos, (h, w, 3), "pos")
        rgba = np.zeros((h, w, 4), np.float32)
        rgba[..., :3] = refl
        units["u_refl"] = self._tex((w, h), 4, "f4", rgba)
        rgba = np.empty((h, w, 4), np.float32)
        rgba[..., :3] = pos
        rgba[..., 3] = camera_lobe(refl, pos, _f32(model.cam_eye, (3,), "cam_eye"), model.gamma)
        units["u_pos"] = self._tex((w, h), 4, "f4", rgba)
        return units

    def _set(self, name: str, value: Any) -> None:
        """Record a uniform; it is written into the variant's program before each draw."""
        self._uniforms[name] = value

    def _program(self) -> tuple[Any, Any]:
        """(program, vertex array) of the current (method, input) variant, compiled once."""
        key = (self._uniforms["u_method"], self._input)
        if key not in self._programs:
            prog = self._track(build_program(self.ctx, defines={"METHOD": key[0], "INPUT": key[1]}))
            vao = self._track(self.ctx.vertex_array(prog, []))
            for i, name in enumerate(_SAMPLERS):  # distinct units: sampler types differ
                if name in prog:
                    prog[name].value = i
            self._programs[key] = (prog, vao)
        return self._programs[key]

    def _draw(self) -> None:
        prog, vao = self._program()
        for name, value in self._uniforms.items():
            if name in prog:  # the GLSL compiler drops what a variant does not use
                prog[name].value = value
        for unit, tex in self._units:
            if tex is not None:
                tex.use(unit)
        vao.render(moderngl.TRIANGLES, vertices=3)

    # ----------------------------------------------------------------- state
    @property
    def identity(self) -> bool:
        """True: pass the frame through (same upload, shader and read-back), no compensation."""
        return self._identity

    @identity.setter
    def identity(self, on: bool) -> None:
        self._identity = bool(on)
        self._set("u_method", 0 if self._identity else _METHODS[self.method])

    def set_eye(self, x: float, y: float, z: float) -> None:
        """Eye position in metres (world frame of MODEL.md)."""
        self.eye = np.array([x, y, z], np.float32)
        self._set("u_eye", (float(x), float(y), float(z)))

    def set_angle(self, deg: float, distance: float, height: float) -> None:
        """Eye from a viewing angle: E = (d cos t, h, d sin t); degrees and metres."""
        self.set_eye(*eye_from_angle(deg, distance, height))

    def set_tone(self, alpha: float, beta: float) -> None:
        """Tone map T = alpha * C_w + beta (Eq. 21), linear camera units."""
        self.alpha, self.beta = float(alpha), float(beta)
        self._set("u_alpha", self.alpha)
        self._set("u_beta", self.beta)

    def update_model(
        self,
        Wc_inv: np.ndarray | None = None,
        inv_lut: np.ndarray | None = None,
        inv_lo: np.ndarray | None = None,
        inv_hi: np.ndarray | None = None,
    ) -> None:
        """Per-eye updates (paper method): (W~_c)^-1 (3, 3) and rho_c^-1 (N, 3) on [lo, hi].

        Small uploads into the existing objects; ``inv_lut`` must keep its N entries.
        """
        if Wc_inv is not None:
            self._set("u_Wc_inv", tuple(_f32(Wc_inv, (3, 3), "Wc_inv").T.ravel()))
        if inv_lut is not None:
            self._inv.write(_inv_pairs(inv_lut, self._n_inv))
        if inv_lo is not None:
            self._set("u_inv_lo", tuple(_f32(inv_lo, (3,), "inv_lo")))
        if inv_hi is not None:
            self._set("u_inv_hi", tuple(_f32(inv_hi, (3,), "inv_hi")))

    # ----------------------------------------------------------------- per frame
    def upload(self, frame: np.ndarray) -> None:
        """Upload an RGB frame (H, W, 3) uint8 (levels 0..255) as the next input."""
        if frame.shape != (self.height, self.width, 3) or frame.dtype != np.uint8:
            raise ValueError(
                f"frame must be uint8 {(self.height, self.width, 3)}, got {frame.dtype} "
                f"{frame.shape} (scale with viewcomp.rt.frames.fit_rgb first)"
            )
        self._rgb.write(np.ascontiguousarray(frame))
        self._input = 0

    def upload_planes(self, planes: Planes) -> None:
        """Upload a yuv420p frame (converted to RGB levels in the shader, see yuv.glsl)."""
        planes.check()
        if planes.shape != (self.height, self.width):
            raise ValueError(
                f"planes must be {(self.height, self.width)}, got {planes.shape} "
                "(the video reader fits frames to the grid)"
            )
        self._y.write(np.ascontiguousarray(planes.y))
        self._uv_host[..., 0] = planes.u  # interleave: one chroma texture, half the fetches
        self._uv_host[..., 1] = planes.v
        self._uv.write(self._uv_host)
        key = (planes.colorspace, planes.color_range)
        if key != self._yuv_key:
            k = yuv_coefficients(*key)
            self._set("u_yuv_k", (k.cy, k.cr_r, k.cb_b, k.y_off))
            self._set("u_yuv_kg", (k.cb_g, k.cr_g))
            self._yuv_key = key
        self._input = 1

    def draw(self) -> None:
        """Run the shader on the last upload into the own framebuffer."""
        self.fbo.use()
        self.ctx.viewport = (0, 0, self.width, self.height)
        self._set("u_origin", (0, 0))
        self._set("u_flip_y", 0)
        self._draw()

    def read(self, out: np.ndarray | None = None) -> np.ndarray:
        """Read back the last draw as (H, W, 3) uint8 (into ``out`` if given)."""
        self.fbo.read_into(self._readback, components=4, alignment=1)
        if out is None:
            return self._readback[..., :3].copy()
        np.copyto(out, self._readback[..., :3])
        return out

    def render(self, frame: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Compensate one RGB frame (H, W, 3) uint8 -> (H, W, 3) uint8 for the projector."""
        self.upload(frame)
        self.draw()
        return self.read(out)

    def render_planes(
        self,
        y: np.ndarray | Planes,
        u: np.ndarray | None = None,
        v: np.ndarray | None = None,
        colorspace: str = "bt709",
        color_range: str = "limited",
        out: np.ndarray | None = None,
    ) -> np.ndarray:
        """Compensate one yuv420p frame (planes, or a :class:`Planes`) -> (H, W, 3) uint8."""
        planes = y if isinstance(y, Planes) else Planes(y, u, v, colorspace, color_range)  # type: ignore[arg-type]
        self.upload_planes(planes)
        self.draw()
        return self.read(out)

    def render_to(
        self,
        framebuffer: moderngl.Framebuffer,
        origin: tuple[int, int] = (0, 0),
        flip_y: bool = True,
    ) -> None:
        """Draw the last upload into a host-owned framebuffer of the same context.

        Args:
            framebuffer: e.g. ``ctx.screen`` of a window (8-bit unorm colour).
            origin: window pixel (x, y) from the bottom-left where the grid's corner goes.
            flip_y: True for a window (y = 0 at the bottom), so array row 0 shows at the top.
        """
        framebuffer.use()
        self.ctx.viewport = (origin[0], origin[1], self.width, self.height)
        self._set("u_origin", origin)
        self._set("u_flip_y", 1 if flip_y else 0)
        self._draw()

    # ----------------------------------------------------------------- lifetime
    def live_objects(self) -> int:
        """How many of the GL objects this compensator made are still alive (0 after release)."""
        return sum(1 for o in self._objects if not isinstance(o.mglo, moderngl.InvalidObject))

    def release(self) -> None:
        """Release every GL object (and the context if this object created it). Idempotent."""
        for obj in reversed(self._objects):  # each release() is idempotent
            obj.release()
        if self._own_ctx and not self._released:
            self.ctx.release()
        self._released = True

    def __enter__(self) -> Compensator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()
