"""The tone worker: the newest request wins, its duty cycle rests, a cut ends the rest and
stops a call in progress."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, cast

import numpy as np

from viewcomp.calib.comp.adaptive import SearchStopped
from viewcomp.calib.comp.compensation import Compensation
from viewcomp.rt.play.tone_worker import ToneWorker

EYE = np.zeros(3)
THUMB = np.zeros((4, 8, 3), np.uint8)


class _Comp:
    """Stands in for Compensation: records each call's time stamp and cut flag; a call can be
    held until released."""

    def __init__(self) -> None:
        self.calls: list[tuple[float, bool | None]] = []
        self.hold = threading.Event()
        self.hold.set()
        self.entered = threading.Event()
        self.stopped: list[float] = []

    def __call__(
        self,
        thumb: np.ndarray,
        eye: Any,
        t: float,
        cut: bool | None = None,
        early: Any = None,
        stop: Any = None,
    ) -> Any:
        if cut and early is not None:
            early(("first stage", t))
        self.entered.set()
        self.hold.wait(10.0)
        if stop is not None and stop():  # as the node search does between nodes
            self.stopped.append(t)
            raise SearchStopped
        self.calls.append((t, cut))
        return ("params", t)


def _wait(cond: Any, limit: float = 5.0) -> bool:
    end = time.monotonic() + limit
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.01)
    return False


@contextmanager
def _running(period: float) -> Iterator[tuple[_Comp, ToneWorker]]:
    """A stand-in Compensation and a worker on it; the worker stopped (a held call released
    first) at the end."""
    comp = _Comp()
    worker = ToneWorker(cast(Compensation, comp), period)
    try:
        yield comp, worker
    finally:
        comp.hold.set()
        worker.stop()


def test_a_cut_ends_the_rest_and_is_computed_as_a_cut() -> None:
    with _running(60.0) as (comp, worker):  # a rest far longer than the test waits
        worker.submit(THUMB, EYE, 1.0, False)
        assert _wait(lambda: len(comp.calls) == 1)
        worker.submit(THUMB, EYE, 2.0, False)  # within the shot: waits for the rest
        time.sleep(0.3)
        assert len(comp.calls) == 1
        worker.submit(THUMB, EYE, 3.0, True)  # a cut: computed now, as a cut
        assert _wait(lambda: len(comp.calls) == 2)
        assert comp.calls[1] == (3.0, True)


def test_a_cut_survives_a_later_request_of_the_same_shot() -> None:
    with _running(60.0) as (comp, worker):
        comp.hold.clear()
        worker.submit(THUMB, EYE, 1.0, False)
        assert comp.entered.wait(5.0)  # the worker is busy with the first request
        worker.submit(THUMB, EYE, 2.0, True)  # the cut's frame
        worker.submit(THUMB, EYE, 3.0, False)  # the next frame replaces it, still a cut
        comp.hold.set()
        # the call in progress was of the old shot: given up for the cut, computed next
        assert _wait(lambda: len(comp.calls) == 1)
        assert comp.stopped == [1.0] and comp.calls == [(3.0, True)]


def test_a_call_within_a_shot_finishes_without_a_cut() -> None:
    with _running(0.01) as (comp, worker):
        comp.hold.clear()
        worker.submit(THUMB, EYE, 1.0, False)
        assert comp.entered.wait(5.0)
        worker.submit(THUMB, EYE, 2.0, False)  # the same shot: the call goes on
        comp.hold.set()
        assert _wait(lambda: len(comp.calls) == 2)
        assert comp.stopped == [] and comp.calls == [(1.0, False), (2.0, False)]
        latest = worker.latest()
        assert latest is not None and latest[0] == ("params", 2.0)


def test_a_cuts_first_stage_is_shown_before_its_call_ends() -> None:
    with _running(60.0) as (comp, worker):
        worker.compute(THUMB, EYE, 0.0, True)
        comp.entered.clear()
        comp.hold.clear()
        worker.submit(THUMB, EYE, 1.0, True)
        assert comp.entered.wait(5.0)  # the call is under way, held
        latest = worker.latest()
        assert latest is not None and latest[0] == ("first stage", 1.0)
        comp.hold.set()
        assert _wait(lambda: (worker.latest() or (None,))[0] == ("params", 1.0))
