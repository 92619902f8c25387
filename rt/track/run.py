"""The tracking loop: frames -> faces -> eyes -> filter -> publishers, and its thread.

:func:`build` turns a ``SRC`` and a rig into a ready :class:`Pipeline` (opening the source
and checking the camera first, so that a bad ``SRC`` fails before anything runs);
:meth:`Pipeline.run` processes frames until the source ends or a stop is asked;
:class:`TrackerThread` runs it on a thread of its own for ``viewcomp play --track-camera``
(it feeds the player's input queue; no GL is touched off the player's thread).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from viewcomp.calib.world.rig import Device, Rig, tracking_camera
from viewcomp.rt.track.anatomy import IPD, NOSE_DEPTH, HeadPose, head_pose
from viewcomp.rt.track.boxes import SAME_FACE, iou
from viewcomp.rt.track.faces import DetectorConfig, FaceDetector, size_range
from viewcomp.rt.track.live_faces import LiveFaces
from viewcomp.rt.track.pose import EYE_ROW, FACE_WIDTH, camera_for_frames, eyes_from_boxes
from viewcomp.rt.track.publish import Publisher
from viewcomp.rt.track.scale import FaceTemplate, ScaleConfig
from viewcomp.rt.track.source import ArraySource, Frame, FrameSource, SourceError
from viewcomp.rt.track.tracker import EyeTracker, TrackerConfig
from viewcomp.rt.track.yunet import YuNetConfig, YuNetDetector

log = logging.getLogger(__name__)

EYE_LIMIT = 50.0  # metres: estimates farther than this (or behind the screen) are not viewers


@dataclass
class TrackOptions:
    """Everything ``viewcomp track`` can set. Metres, seconds, Hz.

    ``detector``: ``"yunet"`` (the default: faces and landmarks, the distance from the eyes'
    separation, :mod:`viewcomp.rt.track.anatomy`, with ``ipd`` the viewers' interpupillary
    distance and ``nose_depth`` the nose point's depth in IPDs, ``anatomy.NOSE_DEPTH``) or
    ``"cascade"`` (the fallback: the LBP cascade's box taken as ``face_width`` metres wide,
    biased by how the cascade draws boxes; the options below up to ``background_search`` are
    the cascade's).
    ``near``/``far``: the distances (along the camera's axis) at which faces are searched;
    ``fps``: the frame rate of an image sequence; ``realtime``: pace files at their rate;
    ``templates``: size tracked faces by their own near view (:mod:`viewcomp.rt.track.scale`)
    rather than by the cascade's box alone; ``background_search``: run the periodic
    full-frame search on a worker thread (None: for a live camera and ``realtime``; a file
    processed as fast as possible stays on one thread, so its output is reproducible); with
    YuNet, a live search instead looks at each frame at half resolution and at one tile of
    it (or the region where it changed) at full resolution, and follows the faces it found
    in crops (:mod:`viewcomp.rt.track.live_faces`).
    """

    detector_kind: str = "yunet"
    ipd: float = IPD
    nose_depth: float = NOSE_DEPTH
    yunet: YuNetConfig = field(default_factory=YuNetConfig)
    face_width: float = FACE_WIDTH
    eye_row: float = EYE_ROW
    near: float = 0.5
    far: float = 4.0
    fps: float = 30.0
    realtime: bool = False
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    detector: DetectorConfig | None = None
    templates: bool = True
    scale: ScaleConfig = field(default_factory=ScaleConfig)
    background_search: bool | None = None


@dataclass
class FrameResult:
    """What one frame gave: the raw eyes (N, 3), the published eyes (K, 3), and times:
    ``captured`` (monotonic s, the frame handed over) and ``done`` (published)."""

    index: int
    t: float
    raw: np.ndarray
    eyes: np.ndarray
    sent: bool
    captured: float
    done: float


@dataclass
class Stats:
    """Totals of a run: frames, frames with a face, lines/messages sent, mean ms per frame."""

    frames: int = 0
    with_face: int = 0
    sent: int = 0
    seconds: float = 0.0

    def summary(self) -> str:
        ms = 1000.0 * self.seconds / max(self.frames, 1)
        return (
            f"{self.frames} frames, a face in {self.with_face}, {self.sent} updates "
            f"sent, {ms:.1f} ms per frame"
        )


class Pipeline:
    """One source, one camera model, one detector, one tracker, any publishers."""

    def __init__(
        self,
        source: FrameSource | ArraySource,
        device: Device,
        options: TrackOptions,
        publishers: Sequence[Publisher] = (),
    ) -> None:
        self.source = source
        self.options = options
        try:
            self.device = camera_for_frames(device, source.size)
        except ValueError as exc:
            raise SourceError(f"{source.src}: {exc}") from None
        self.tracker = EyeTracker(options.tracker)
        self.publishers = list(publishers)
        self.stats = Stats()
        self._pool: ThreadPoolExecutor | None = None
        self._pending: Future[np.ndarray] | None = None
        self.yunet: YuNetDetector | LiveFaces | None = None
        # Live: no frame waits for a whole-frame search at full resolution (the cascade's runs
        # on a worker thread, YuNet's is spread over the frames in tiles); a file processed as
        # fast as possible is searched whole, frame by frame (reproducible).
        background = options.background_search
        if background is None:
            background = bool(getattr(source, "live", False)) or options.realtime
        if options.detector_kind == "yunet":
            if not options.ipd > 0:
                raise ValueError(f"the interpupillary distance must be > 0 m, got {options.ipd}")
            self.yunet = (
                LiveFaces(options.yunet, device=self.device)
                if background
                else YuNetDetector(options.yunet, device=self.device)
            )
            log.info("face detector: YuNet (%s), distance from the eyes at IPD %.1f mm",
                     self.yunet.path.name, 1000 * options.ipd)  # fmt: skip
            return
        if options.detector_kind != "cascade":
            raise ValueError(f'detector is "yunet" or "cascade", got {options.detector_kind!r}')
        log.warning("face detector: the LBP cascade FALLBACK; its distance comes from the "
                    "box size (%.3f m per box) and is biased, use YuNet for measurement",
                    options.face_width)  # fmt: skip
        lo, hi = size_range(self.device.focal(), options.face_width, options.near, options.far)
        config = replace(options.detector or DetectorConfig(), min_px=lo, max_px=hi)
        self.detector = FaceDetector(config)
        self._since_full = 0  # frames since the last background search started
        if background:
            self._background = FaceDetector(replace(config))
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="viewcomp-faces")

    def _sized(self, gray: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """``boxes`` with each tracked face's size and place from its template, where it has
        one and the template finds it (:mod:`viewcomp.rt.track.scale`)."""
        out = boxes.copy()
        for tr in self.tracker.tracks:
            if tr.template is None or len(boxes) == 0:
                continue
            overlap = iou(tr.box, boxes)
            i = int(np.argmax(overlap))
            if overlap[i] < SAME_FACE:
                continue
            found = tr.template.measure(gray, boxes[i], self.options.scale)
            if found is not None:
                out[i] = found[0]
        return out

    def _keep_templates(self, gray: np.ndarray, boxes: np.ndarray, t: float) -> None:
        """Take a face's template when it is seen large enough, and larger than before."""
        anchor = self.options.scale.anchor_px
        for tr in self.tracker.tracks:
            if tr.seen != t or not 0 <= tr.index < len(boxes):
                continue
            b = boxes[tr.index]
            if (
                b[2] >= anchor
                and FaceTemplate.fits(gray, b)
                and (tr.template is None or b[2] > 1.05 * tr.template.width)
            ):
                tr.template = FaceTemplate(gray, b)

    def _hints(self, frame: Frame) -> tuple[np.ndarray, bool]:
        """Where to look in ``frame``: the tracked faces, plus what the background search
        found since the last frame; and whether the detector does its periodic full search
        itself (no background search)."""
        hints = self.tracker.hints()
        if self._pool is None:
            return hints, True
        if self._pending is not None and self._pending.done():
            hints = np.concatenate([hints, self._pending.result()])
            self._pending = None
        self._since_full += 1
        due = self._since_full >= self.detector.config.full_every
        if self._pending is None and len(self.tracker.tracks) and due:
            self._pending = self._pool.submit(self._background.candidates, frame.image)
            self._since_full = 0
        return hints, False

    def _landmark_eyes(self, frame: Frame) -> tuple[HeadPose, np.ndarray, np.ndarray]:
        """YuNet: the landmarks' reading (eyes (N, 3) metres, :class:`HeadPose`), the boxes
        (N, 4) pixels and which readings are coarse ((N,) bool, ``Faces.coarse``) of the
        faces between ``near`` / 1.5 and 1.5 ``far`` from the camera."""
        assert self.yunet is not None
        # the tracked faces are followed in crops where the frame's search misses them
        faces = self.yunet.detect(frame.image, follow=self.tracker.hints())
        o = self.options
        pose = head_pose(self.device, faces.landmarks, o.ipd, o.nose_depth)
        ok = (pose.range >= o.near / 1.5) & (pose.range <= o.far * 1.5)
        return pose.take(ok), faces.boxes[ok], faces.coarse[ok]

    def _box_eyes(self, frame: Frame) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The cascade fallback: eyes (N, 3) from the boxes' size, the boxes as found and as
        sized by the templates, and the grey frame."""
        gray = cv2.cvtColor(frame.image, cv2.COLOR_BGR2GRAY)
        hints, periodic = self._hints(frame)
        boxes = self.detector.detect(frame.image, hints, gray=gray, periodic=periodic)
        sized = self._sized(gray, boxes) if self.options.templates else boxes
        raw = eyes_from_boxes(self.device, sized, self.options.face_width, self.options.eye_row)
        return raw, boxes, sized, gray

    def step(self, frame: Frame) -> FrameResult:
        """Detect, range, filter and publish one frame."""
        pose: HeadPose | None = None
        if self.yunet is not None:
            pose, sized, coarse = self._landmark_eyes(frame)
            raw, boxes, gray = pose.eyes, sized, None
        else:
            raw, boxes, sized, gray = self._box_eyes(frame)
            coarse = np.zeros(len(raw), bool)
        ok = (raw[:, 2] > 0.0) & np.all(np.abs(raw) <= EYE_LIMIT, axis=1)
        raw, boxes, sized, coarse = raw[ok], boxes[ok], sized[ok], coarse[ok]
        pose = pose.take(ok) if pose is not None else None
        eyes = self.tracker.update(raw, sized, frame.t, pose, coarse)
        if self.options.templates and gray is not None:
            self._keep_templates(gray, boxes, frame.t)
        sent = False
        for p in self.publishers:
            sent = p.publish(eyes) or sent
        done = time.monotonic()
        self.stats.frames += 1
        self.stats.with_face += int(len(raw) > 0)
        self.stats.sent += int(sent)
        self.stats.seconds += done - frame.captured
        return FrameResult(frame.index, frame.t, raw, eyes, sent, frame.captured, done)

    def run(
        self,
        stop: threading.Event | None = None,
        max_seconds: float | None = None,
    ) -> Stats:
        """Process frames until the source ends, ``stop`` is set or ``max_seconds`` (of
        frame time) have passed."""
        for frame in self.source:
            if stop is not None and stop.is_set():
                break
            if max_seconds is not None and frame.t > max_seconds:
                break
            self.step(frame)
        return self.stats

    def close(self) -> None:
        """Release the source, the search thread and the publishers."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
        self.source.close()
        for p in self.publishers:
            p.close()


def build(
    src: str,
    rig: Rig,
    options: TrackOptions,
    publishers: Sequence[Publisher] = (),
) -> Pipeline:
    """A pipeline for camera ``src`` whose pose and intrinsics are the rig's tracking camera
    (:func:`viewcomp.calib.world.rig.tracking_camera`).

    Raises:
        RigError: the rig's tracking camera faces the screen.
        SourceError: ``src`` cannot be read, or its frames do not fit the camera's aspect.
    """
    device = tracking_camera(rig)
    source = FrameSource(src, fps=options.fps, realtime=options.realtime, size=device.resolution)
    try:
        return Pipeline(source, device, options, publishers)
    except BaseException:  # undo on any failure, Ctrl-C included; then re-raise
        source.close()
        raise


class TrackerThread:
    """A pipeline on its own thread, publishing into a player's input hub.

    ``start(hub)`` adds a :class:`viewcomp.rt.track.publish.HubPublisher` and starts the
    thread; ``stop()`` ends it and releases the source. A source that ends (a file) ends the
    thread; the player goes on with the last eye.
    """

    def __init__(self, pipeline: Pipeline, all_faces: bool = False) -> None:
        self.pipeline = pipeline
        self.all_faces = all_faces  # publish every face (an audience), not only the nearest
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="viewcomp-track", daemon=True)
        self.error: BaseException | None = None

    def start(self, hub: object) -> TrackerThread:
        """Publish into ``hub`` (an InputHub) and start."""
        from viewcomp.rt.track.publish import HubPublisher

        self.pipeline.publishers.append(HubPublisher(hub, self.all_faces))
        self._thread.start()
        return self

    def _run(self) -> None:
        try:
            self.pipeline.run(self._stop)
        except Exception as exc:  # a camera unplugged, a corrupt file: playback goes on
            self.error = exc
            log.warning("face tracker stopped: %s; the eye stays where it was", exc)

    def stop(self) -> None:
        """Stop the thread and release the camera."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        self.pipeline.close()


def load_tracking_rig(path: str) -> Rig:
    """The rig of a ``rig.toml``, of a capture set (a folder with one) or of a calibration
    bundle (the rig it was calibrated with).

    Raises:
        RigError, BundleError: the file cannot be read; the message says why.
    """
    import tomllib
    from pathlib import Path

    from viewcomp.calib.world.rig import load_rig, rig_from_dict

    p = Path(path)
    if p.is_dir():
        return load_rig(p / "rig.toml")
    if p.suffix.lower() == ".toml" or not p.exists():
        return load_rig(p)
    from viewcomp.calib.io.bundle import BundleError, load_bundle

    _, meta = load_bundle(p)
    try:
        return rig_from_dict(tomllib.loads(meta["rig"]), source=f"{p} (rig)")
    except (KeyError, TypeError, tomllib.TOMLDecodeError) as exc:
        raise BundleError(f"{p}: the bundle holds no readable rig ({exc}); recalibrate") from None


def default_options(rig: Rig) -> TrackOptions:
    """``viewcomp track``'s defaults for ``rig``: the default eye is its [viewer] at 90
    degrees, the interpupillary distance its ``[tracker] ipd`` (0.063 m without)."""
    eye = rig.viewer.eye(90.0)
    tracker = TrackerConfig(default_eye=(float(eye[0]), float(eye[1]), float(eye[2])))
    return TrackOptions(tracker=tracker, ipd=rig.tracker_ipd or IPD)
