"""Live eye input without a window: parsers, validation, smoothing, the hub and listeners."""

from __future__ import annotations

import logging
import math
import os
import socket
import struct
import time

import numpy as np
import pytest
from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
from pythonosc.osc_message_builder import OscMessageBuilder

from viewcomp.rt.play.live import (
    ANGLE_ADDRESS,
    EYE_ADDRESS,
    MAX_LINE,
    Blackout,
    EyeState,
    InputError,
    InputHub,
    LineReader,
    Next,
    NudgeAngle,
    OscListener,
    Pause,
    Previous,
    Resume,
    Seek,
    SetAngle,
    SetAngleNorm,
    SetEye,
    Status,
    eye_to_polar,
    parse_host_port,
    parse_line,
    parse_osc_message,
    parse_osc_packet,
    polar_to_eye,
)


def osc(address: str, *args: object, types: str | None = None) -> bytes:
    """An OSC message datagram; ``types`` forces the type tag per argument (f, d, i, s, T)."""
    b = OscMessageBuilder(address)
    for i, a in enumerate(args):
        b.add_arg(a, types[i] if types else None)
    return b.build().dgram


def wait_for(cond, timeout: float = 5.0) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError("timed out")
        time.sleep(0.005)


# ----------------------------------------------------------------------- stdin grammar
@pytest.mark.parametrize(
    ("line", "want"),
    [
        ("angle 60", SetAngle(60.0)),
        ("  ANGLE\t45.5  ", SetAngle(45.5)),
        ("angle 60\r", SetAngle(60.0)),
        ("eye 0.1 0.0 0.5", SetEye((0.1, 0.0, 0.5))),
        ("eye 0.1,0,0.5", SetEye((0.1, 0.0, 0.5))),
        ("", None),
        ("   ", None),
        ("# a comment", None),
    ],
)
def test_parse_line_accepts(line: str, want: object) -> None:
    assert parse_line(line) == want


@pytest.mark.parametrize(
    "line",
    [
        "angle", "angle 60 70", "angle sixty", "angle 0", "angle 180", "angle -5", "angle nan",
        "angle inf", "eye 1 2", "eye 1 2 3 4", "eye 0 0 0", "eye 0 0 -1", "eye 0 0 1e9",
        "eye a b c", "eyes 0 0", "eyes", "eyes 0 0 1 0 0 -1", "turn left", "x" * (MAX_LINE + 1),
        "angle 6O",
    ],
)  # fmt: skip
def test_parse_line_rejects(line: str) -> None:
    with pytest.raises(InputError):
        parse_line(line)


# ----------------------------------------------------------------------- OSC
def test_parse_osc_message() -> None:
    assert parse_osc_message(ANGLE_ADDRESS, [60.0]) == SetAngle(60.0)
    assert parse_osc_message(ANGLE_ADDRESS, [60]) == SetAngle(60.0)
    assert parse_osc_message(EYE_ADDRESS, [0.1, 0, 0.5]) == SetEye((0.1, 0.0, 0.5))
    for address, args in [
        (ANGLE_ADDRESS, []), (ANGLE_ADDRESS, [1.0, 2.0]), (ANGLE_ADDRESS, ["60"]),
        (ANGLE_ADDRESS, [True]), (ANGLE_ADDRESS, [200.0]), (ANGLE_ADDRESS, [math.nan]),
        (EYE_ADDRESS, [0.1, 0.0]), (EYE_ADDRESS, [0.1, 0.0, -0.5]), (EYE_ADDRESS, [b"x", 0, 1]),
        ("/viewcomp/Angle", [60.0]), ("/other", [1.0]),
    ]:  # fmt: skip
        with pytest.raises(InputError):
            parse_osc_message(address, args)


def test_parse_osc_packet_messages_and_bundles() -> None:
    assert parse_osc_packet(osc(ANGLE_ADDRESS, 60.0)) == [SetAngle(60.0)]
    assert parse_osc_packet(osc(ANGLE_ADDRESS, 60.0, types="d")) == [SetAngle(60.0)]
    assert parse_osc_packet(osc(EYE_ADDRESS, 0.1, 0.0, 0.5, types="fff")) == [
        SetEye((pytest.approx(0.1), 0.0, 0.5))  # type: ignore[arg-type]
    ]
    bundle = OscBundleBuilder(IMMEDIATELY)
    bundle.add_content(OscMessageBuilder(ANGLE_ADDRESS).build())  # no argument: rejected
    bm = OscMessageBuilder(ANGLE_ADDRESS)
    bm.add_arg(30.0)
    bundle.add_content(bm.build())
    results = parse_osc_packet(bundle.build().dgram)
    assert isinstance(results[0], InputError)
    assert results[1] == SetAngle(30.0)


@pytest.mark.parametrize(
    "data",
    [b"", b"\x00" * 16, b"hello", b"/viewcomp/angle", b"#bundle\x00" + b"\xff" * 5,
     osc(ANGLE_ADDRESS, 60.0)[:-3], os.urandom(64), b"/viewcomp/angle\x00,f\x00\x00"],
)  # fmt: skip
def test_parse_osc_packet_rejects_junk(data: bytes) -> None:
    try:
        results = parse_osc_packet(data)
    except InputError:
        return
    assert all(isinstance(r, InputError) for r in results)


def test_parse_host_port() -> None:
    assert parse_host_port("127.0.0.1:9000") == ("127.0.0.1", 9000)
    assert parse_host_port(":9001") == ("127.0.0.1", 9001)
    assert parse_host_port("9002") == ("127.0.0.1", 9002)
    assert parse_host_port("[::1]:9003") == ("::1", 9003)
    for bad in ("host:port", "1.2.3.4:70000", "localhost:"):
        with pytest.raises(InputError):
            parse_host_port(bad)


# ----------------------------------------------------------------------- state
def test_polar_round_trip() -> None:
    e = polar_to_eye(60.0, 0.5, 0.035)
    assert e == pytest.approx([0.25, 0.035, 0.5 * math.sin(math.radians(60))])
    a, d, h = eye_to_polar(e)
    assert (a, d, h) == pytest.approx((60.0, 0.5, 0.035))


def test_eye_state_smooths_and_never_jumps() -> None:
    s = EyeState(0.5, 0.035, polar_to_eye(90.0, 0.5, 0.035), tau=0.2)
    s.update(0.0)
    s.apply(SetAngle(30.0))
    target = polar_to_eye(30.0, 0.5, 0.035)
    prev = s.current.copy()
    steps = []
    for i in range(1, 121):  # 2 s at 60 Hz
        cur = s.update(i / 60.0)
        steps.append(float(np.linalg.norm(cur - prev)))
        prev = cur.copy()
    total = float(np.linalg.norm(target - polar_to_eye(90.0, 0.5, 0.035)))
    assert max(steps) < 0.1 * total  # no frame moves more than 10 % of the way
    assert np.allclose(s.current, target, atol=1e-3)  # 10 tau later: there
    s.update(10.0)
    assert s.settled


def test_eye_state_instant_and_nudge() -> None:
    s = EyeState(0.5, 0.035, polar_to_eye(90.0, 0.5, 0.035), tau=0.0)
    s.apply(SetEye((0.1, 0.2, 0.3)))
    assert s.update(1.0).tolist() == [0.1, 0.2, 0.3]
    s.apply(NudgeAngle(10.0))  # keeps distance and height of the target
    a, d, h = eye_to_polar(s.update(2.0))
    a0, d0, h0 = eye_to_polar(np.array([0.1, 0.2, 0.3]))
    assert (a, d, h) == pytest.approx((a0 + 10.0, d0, h0))
    s.apply(NudgeAngle(1000.0))
    assert eye_to_polar(s.update(3.0))[0] == pytest.approx(179.0)


# ----------------------------------------------------------------------- hub, listeners
def test_hub_counts_and_rate_limited_log(caplog: pytest.LogCaptureFixture) -> None:
    hub = InputHub()
    with caplog.at_level(logging.WARNING, logger="viewcomp.rt.play.live"):
        for i in range(100):
            hub.reject("osc", f"bad {i}")
    hub.put("osc", SetAngle(10.0))
    items = hub.drain()
    for it in items:
        hub.applied(it)
    c = hub.snapshot()["osc"]
    assert (c.received, c.applied, c.rejected) == (1, 1, 100)
    assert len([r for r in caplog.records if "dropped" in r.getMessage()]) <= 12


def test_osc_listener_applies_valid_rejects_rest() -> None:
    hub = InputHub()
    with OscListener(hub, "127.0.0.1", 0) as listener:
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        packets = [
            osc(ANGLE_ADDRESS, 45.0), b"junk", osc(EYE_ADDRESS, 0.0, 0.0, 1.0),
            osc(ANGLE_ADDRESS, 999.0), osc("/nope", 1.0), struct.pack(">f", 1.0),
        ]  # fmt: skip
        for p in packets:
            tx.sendto(p, listener.address)
        tx.close()
        wait_for(lambda: listener.packets == len(packets))
    got = [r.command for r in hub.drain()]
    assert got == [SetAngle(45.0), SetEye((0.0, 0.0, 1.0))]
    assert hub.snapshot()["osc"].rejected == 4


def test_osc_listener_port_in_use_is_a_clear_error() -> None:
    hub = InputHub()
    with OscListener(hub, "127.0.0.1", 0) as first:
        with pytest.raises(InputError, match="cannot listen"):
            OscListener(hub, "127.0.0.1", first.address[1])


def test_line_reader_from_a_pipe() -> None:
    hub = InputHub()
    r, w = os.pipe()
    reader = LineReader(hub, r).start()
    try:
        os.write(w, b"angle 60\nnonsense\n\n# note\neye 0 0 0.7\n")
        os.write(w, b"x" * (3 * MAX_LINE) + b"\nangle 1")  # an over-long line, a last one
        os.write(w, b"20\n\xff\xfe\n")  # not UTF-8
        os.close(w)
        wait_for(lambda: reader.eof)
    finally:
        reader.stop()
        os.close(r)
    assert [x.command for x in hub.drain()] == [
        SetAngle(60.0), SetEye((0.0, 0.0, 0.7)), SetAngle(120.0),
    ]  # fmt: skip
    assert hub.snapshot()["stdin"].rejected == 3


# ----------------------------------------------------------------------- show control
@pytest.mark.parametrize(
    ("line", "want"),
    [
        ("pause", Pause()), ("RESUME", Resume()), ("seek 12.5", Seek(12.5)), ("next", Next()),
        ("previous", Previous()), ("blackout 1", Blackout(True)), ("blackout 0", Blackout(False)),
        ("norm 0.25", SetAngleNorm(0.25)), ("status", Status()),
        # a console's button: 1 when pressed (act), 0 when released (nothing)
        ("pause 1", Pause()), ("pause 0", None), ("next 1", Next()), ("previous 0", None),
    ],
)  # fmt: skip
def test_parse_line_show_control(line: str, want: object) -> None:
    assert parse_line(line) == want


@pytest.mark.parametrize(
    "line", ["pause 2", "pause 0.5", "pause 1 1", "seek", "seek -1", "seek x", "blackout",
             "blackout 2", "norm 1.5", "norm", "status now", "next 2"],
)  # fmt: skip
def test_parse_line_show_control_rejects(line: str) -> None:
    with pytest.raises(InputError):
        parse_line(line)


def test_osc_show_control_and_status_reply_address() -> None:
    sender = ("127.0.0.1", 5555)
    assert parse_osc_message("/viewcomp/seek", [3], sender) == Seek(3.0)
    assert parse_osc_message("/viewcomp/blackout", [1], sender) == Blackout(True)
    assert parse_osc_message("/viewcomp/angle/norm", [0.5], sender) == SetAngleNorm(0.5)
    assert parse_osc_message("/viewcomp/status", [], sender) == Status(sender)
    assert parse_osc_message("/viewcomp/pause", [1], sender) == Pause()  # a button pressed
    assert parse_osc_message("/viewcomp/pause", [0], sender) is None  # released
    assert parse_osc_message("/viewcomp/next", [1.0], sender) == Next()
    bad = [("/viewcomp/pause", [2]), ("/viewcomp/pause", ["1"]), ("/viewcomp/resume", [1, 0]),
           ("/viewcomp/seek", []), ("/viewcomp/blackout", [0.5]),
           ("/viewcomp/angle/norm", [-0.1])]  # fmt: skip
    for address, args in bad:
        with pytest.raises(InputError):
            parse_osc_message(address, args, sender)


def test_norm_maps_onto_the_range_and_show_commands_are_not_eye_commands() -> None:
    state = EyeState(0.5, 0.0, polar_to_eye(90.0, 0.5, 0.0), tau=0.0)
    state.norm_range = (40.0, 140.0)
    state.apply(SetAngleNorm(0.2))
    assert eye_to_polar(state.target)[0] == pytest.approx(60.0)
    with pytest.raises(TypeError):
        state.apply(Pause())  # type: ignore[arg-type]


def test_a_button_release_in_a_packet_is_no_command() -> None:
    """A console sends /viewcomp/next 1 on press and 0 on release, often in one bundle: one
    Next, and no error for the release."""
    from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
    from pythonosc.osc_message_builder import OscMessageBuilder

    bundle = OscBundleBuilder(IMMEDIATELY)
    for value in (1, 0):
        msg = OscMessageBuilder("/viewcomp/next")
        msg.add_arg(value)
        bundle.add_content(msg.build())
    assert parse_osc_packet(bundle.build().dgram) == [Next()]
