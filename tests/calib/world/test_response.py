"""Camera response curves: round trips, known values, refusals."""

from __future__ import annotations

import numpy as np
import pytest

from viewcomp.calib.world.response import Response, parse_response


@pytest.mark.parametrize("spec", ["linear", "srgb", 2.2, 1.8, "2.4", "SRGB"])
def test_round_trip_encode_decode(spec: str | float) -> None:
    resp = parse_response(spec)
    x = np.linspace(0.0, 1.0, 4097, dtype=np.float32)
    enc = resp.encode(x)
    assert enc.dtype == np.float32
    assert resp.decode(enc) == pytest.approx(x, abs=2e-6)
    dec = resp.decode(x)
    assert dec.dtype == np.float32
    assert resp.encode(dec) == pytest.approx(x, abs=2e-6)


def test_all_8bit_codes_round_trip() -> None:
    codes = np.arange(256, dtype=np.float32) / 255
    for spec in ("srgb", 2.2):
        resp = parse_response(spec)
        back = np.round(resp.encode(resp.decode(codes)) * 255)
        assert np.array_equal(back, np.arange(256))


def test_known_values() -> None:
    srgb = parse_response("srgb")
    # sRGB: encoded 0.5 is linear 0.214041; the linear segment near black has slope 1/12.92
    assert float(srgb.decode(np.float32(0.5))) == pytest.approx(0.2140411, abs=1e-6)
    assert float(srgb.decode(np.float32(0.04))) == pytest.approx(0.04 / 12.92, rel=1e-6)
    g = parse_response(2.0)
    assert float(g.encode(np.float32(0.25))) == pytest.approx(0.5)
    assert parse_response("linear").decode(np.float32(0.3)) == pytest.approx(0.3)


def test_vectorised_shape_and_clipping() -> None:
    resp = parse_response("srgb")
    x = np.full((4, 5, 3), 0.5, np.float32)
    assert resp.decode(x).shape == (4, 5, 3)
    assert np.array_equal(resp.encode(np.array([-0.1, 1.5], np.float32)), [0.0, 1.0])


def test_spec_round_trip() -> None:
    assert parse_response("srgb").spec == "srgb"
    assert parse_response(2.2).spec == 2.2
    assert parse_response(parse_response("linear").spec) == Response(kind="linear")


@pytest.mark.parametrize("bad", ["gamma", "", "sRGB2", -1.0, 0, float("nan"), float("inf"), True])
def test_unknown_specs_are_refused(bad: object) -> None:
    with pytest.raises(ValueError, match=r"linear|positive"):
        parse_response(bad)  # type: ignore[arg-type]


def test_error_names_allowed_values() -> None:
    with pytest.raises(ValueError) as info:
        parse_response("rec709")
    msg = str(info.value)
    assert "rec709" in msg and '"linear"' in msg and '"srgb"' in msg and "number" in msg
