"""The tone worker: ``Compensation`` calls (the tone map, and the paper method's model) on a
worker thread, the newest request winning, so that frames never wait for them."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np

from viewcomp.calib.comp.adaptive import SearchStopped
from viewcomp.calib.comp.compensation import Compensation, FrameParams
from viewcomp.calib.model.reference import View
from viewcomp.calib.world.audience import Audience


def copy_view(eye: View) -> View:
    """An eye as a float64 copy; an audience (immutable) as it is."""
    return eye if isinstance(eye, Audience) else np.array(eye, np.float64)


class ToneWorker:
    """``Compensation`` calls on a worker thread; the newest request wins.

    ``compute`` runs one call synchronously (under the same lock); ``submit`` hands a request
    to the thread; ``latest`` returns the newest result with the eye it was computed for.
    The thread keeps its duty cycle at or below one half: after a call of cost c it rests
    until max(period, 2 c) has passed since the call began, unless a cut is asked for: a
    request that starts a new shot (``cut=True``, detected by the caller on every frame) ends
    the rest at once and stays a cut when a later request of the same shot replaces it, so
    the new shot's own tone map comes after one call, not after a rest and a guess. A call
    in progress gives its adaptive field's node search up when a cut is asked for
    (``Compensation``'s ``stop``): the old shot's field is of no more use. At a cut the
    adaptive field's first stage (``Compensation``'s ``early``) becomes the latest result as
    soon as it is known, so frames leave the old shot's field before the search ends.
    """

    def __init__(self, comp: Compensation, period: float = 0.1) -> None:
        self.comp = comp
        self.period = float(period)
        self.calls = 0
        self.busy_seconds = 0.0
        self._lock = threading.Lock()
        self._cond = threading.Condition()
        self._request: tuple[np.ndarray, View, float, bool | None] | None = None
        self._result: tuple[FrameParams, View] | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="viewcomp-tone", daemon=True)
        self._thread.start()

    def compute(
        self,
        thumb: np.ndarray,
        eye: View,
        t: float,
        cut: bool | None = None,
        stop: Callable[[], bool] | None = None,
    ) -> FrameParams:
        """One synchronous call (``cut`` and ``stop`` as ``Compensation``'s); also becomes
        the latest result."""
        start = time.perf_counter()
        seen = copy_view(eye)

        def first(q: FrameParams) -> None:  # a cut's first stage, shown until the call ends
            self._result = (q, seen)

        with self._lock:
            try:
                p = self.comp(thumb, eye, t, cut, first, stop)
            finally:
                self.busy_seconds += time.perf_counter() - start
            self._result = (p, copy_view(eye))
            self.calls += 1
        return p

    def submit(self, thumb: np.ndarray, eye: View, t: float, cut: bool | None = None) -> None:
        """Ask for a call with these inputs (replaces a request not yet started; a cut in
        the one replaced carries over). ``cut``: a new shot began since the last request."""
        with self._cond:
            if cut is not None and self._request is not None and self._request[3]:
                cut = True
            self._request = (thumb, copy_view(eye), t, cut)
            self._cond.notify()

    def _cut_waiting(self) -> bool:
        return self._request is not None and bool(self._request[3])

    def latest(self) -> tuple[FrameParams, View] | None:
        """The newest (FrameParams, eye) or None before the first call."""
        return self._result

    def _run(self) -> None:
        while not self._stop.is_set():
            with self._cond:
                while self._request is None and not self._stop.is_set():
                    self._cond.wait(0.1)
                req, self._request = self._request, None
            if req is None:
                continue
            start = time.perf_counter()
            try:
                self.compute(*req, stop=self._cut_waiting)
            except SearchStopped:  # a cut came: it is the next request, no rest
                continue
            except Exception:  # keep the last good parameters; the frame goes on
                import logging

                logging.getLogger(__name__).exception("tone map computation failed")
            cost = time.perf_counter() - start
            with self._cond:  # the rest; a cut ends it
                self._cond.wait_for(
                    lambda: self._stop.is_set() or self._cut_waiting(),
                    max(self.period - cost, cost),
                )
            if self._stop.is_set():
                return

    def stop(self) -> None:
        """Stop the thread (a call in progress finishes first)."""
        self._stop.set()
        with self._cond:
            self._cond.notify_all()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)
