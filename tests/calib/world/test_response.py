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


def test_a_table_decodes_between_its_entries_and_round_trips() -> None:
    # entries of x^2 at 5 codes: decode interpolates linearly between them, encode inverts it
    t = parse_response([0.0, 0.0625, 0.25, 0.5625, 1.0])
    assert t.kind == "table" and t.spec == (0.0, 0.0625, 0.25, 0.5625, 1.0)
    assert float(t.decode(np.float32(0.25))) == pytest.approx(0.0625)
    assert float(t.decode(np.float32(0.375))) == pytest.approx((0.0625 + 0.25) / 2)
    x = np.linspace(0.0, 1.0, 1001, dtype=np.float32)
    assert t.encode(t.decode(x)) == pytest.approx(x, abs=1e-6)
    assert parse_response(t.spec) == t
    # a table of an sRGB camera's 256 codes is the sRGB curve at the codes
    srgb = parse_response("srgb")
    codes = np.arange(256) / 255.0
    table = parse_response([float(v) for v in srgb.decode(codes)])
    assert table.decode(codes) == pytest.approx(srgb.decode(codes), abs=1e-6)


@pytest.mark.parametrize(
    ("bad", "said"),
    [
        ([0.0], "2 to 65536 entries"),
        ([0.0, 0.5, 0.4, 1.0], "increase at every entry (entry 2"),
        ([0.1, 0.5, 1.0], "from 0 (black) to 1"),
        ([0.0, 0.5, 0.9], "from 0 (black) to 1"),
        ([0.0, float("nan"), 1.0], "finite"),
        ([0.0, "half", 1.0], "numbers only"),
        ([0.0, True, 1.0], "numbers only"),
    ],
)
def test_bad_tables_are_refused_saying_why(bad: list, said: str) -> None:
    with pytest.raises(ValueError) as info:
        parse_response(bad)
    assert said in str(info.value)
