"""How `viewcomp play` plays: :class:`PlayerOptions`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from viewcomp.calib.comp.tonemap import DEFAULT_LAMBDA
from viewcomp.calib.world.audience import Audience
from viewcomp.rt.play.live import NORM_RANGE


@dataclass
class PlayerOptions:
    """How to play. Angles in degrees, eye in metres, times in seconds.

    ``stdin_fd`` is the descriptor command lines are read from (None: no line input);
    ``osc`` (host, port) to listen on (None: no OSC; port 0: any free port, see
    :attr:`Player.osc_address`); ``max_seconds`` stops playback after that long (None:
    until the playlist ends, or forever with ``loop``). ``still_seconds``: how long an image
    file stays up; ``norm_range``: the angles (degrees) ``/viewcomp/angle/norm`` 0 and 1 mean;
    ``osc_feedback`` (host, port): where the status is pushed every ``feedback_every`` s.
    """

    method: str = "pixel"
    lam: float = DEFAULT_LAMBDA
    tone: str | None = None  # paper, global or adaptive (Compensation's tone); None: the method's
    tone_tau: float = 0.5
    eye_tau: float = 0.25
    angle: float = 90.0
    eye: tuple[float, float, float] | None = None
    angle_step: float = 2.0
    monitor: int = 0
    windowed: bool = False
    size: tuple[int, int] | None = None
    vsync: bool = True
    loop: bool = False
    osc: tuple[str, int] | None = None
    stdin_fd: int | None = None
    audio: bool = True
    audio_device: str = "default"
    overlay: bool = False
    queue_size: int = 8
    tone_side: int = 32
    tone_hz: float = 5.0
    scale: str = "auto"
    max_seconds: float | None = None
    title: str = "viewcomp"
    still_seconds: float = 10.0
    norm_range: tuple[float, float] = NORM_RANGE
    osc_feedback: tuple[str, int] | None = None
    feedback_every: float = 1.0
    inputs: tuple[Any, ...] = ()  # more eye sources: start(hub) -> an object with stop()
    audience: Audience | None = None  # several viewers at once from the start (pixel method)
