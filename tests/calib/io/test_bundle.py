"""The calibration bundle: round trip and every refusal."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from viewcomp.calib.io.bundle import SCHEMA_VERSION, BundleError, load_bundle, save_bundle


def _arrays() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    return {
        "Ww": rng.standard_normal((8, 16, 3, 3)).astype(np.float32),
        "fwd_lut": np.linspace(0, 1, 256 * 3, dtype=np.float32).reshape(256, 3),
        "gamma": np.array(12.5),
        "mask": rng.integers(0, 2, (8, 16)).astype(bool),
        "levels": np.arange(10, dtype=np.uint16),
    }


META: dict[str, Any] = {"method": "pixel", "rig": "[projector]\n", "alpha": 0.9, "n": [1, 2, 3]}


def _save(path: Path) -> Path:
    save_bundle(path, _arrays(), META)
    return path


def _rewrite(src: Path, dst: Path, change: dict[str, bytes | None]) -> None:
    """Copy a bundle zip, replacing (bytes) or dropping (None) members."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for info in zin.infolist():
            if info.filename in change:
                data = change[info.filename]
                if data is not None:
                    zout.writestr(info.filename, data)
            else:
                zout.writestr(info, zin.read(info))


def _meta_doc(path: Path) -> dict[str, Any]:
    with zipfile.ZipFile(path) as zf:
        return json.loads(zf.read("meta.json"))


def test_round_trip(tmp_path: Path) -> None:
    path = _save(tmp_path / "calib")  # exactly this name, no extension added
    assert sorted(p.name for p in tmp_path.iterdir()) == ["calib"]
    arrays, meta = load_bundle(path)
    assert meta == META
    assert set(arrays) == set(_arrays())
    for name, a in _arrays().items():
        assert arrays[name].dtype == a.dtype and arrays[name].shape == a.shape
        assert np.array_equal(arrays[name], a)
    doc = _meta_doc(path)
    assert doc["format"] == "viewcomp-bundle" and doc["schema"] == SCHEMA_VERSION == 3


def test_overwrite_is_atomic_and_leaves_no_temp(tmp_path: Path) -> None:
    path = _save(tmp_path / "sub" / "calib.vcb")
    save_bundle(path, {"x": np.zeros(3)}, {"v": 2})
    arrays, meta = load_bundle(path)
    assert meta == {"v": 2} and list(arrays) == ["x"]
    assert [p.name for p in path.parent.iterdir()] == ["calib.vcb"]


def test_failed_save_leaves_old_bundle_and_no_temp(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = _save(tmp_path / "calib")
    calls = {"n": 0}
    real = np.lib.format.write_array

    def flaky(*args: Any, **kwargs: Any) -> None:
        calls["n"] += 1
        if calls["n"] == 2:
            raise OSError("disk full")
        real(*args, **kwargs)

    monkeypatch.setattr(np.lib.format, "write_array", flaky)
    with pytest.raises(OSError, match="disk full"):
        save_bundle(path, {"a": np.ones(4), "b": np.ones(4)}, {"new": True})
    monkeypatch.undo()
    assert [p.name for p in tmp_path.iterdir()] == ["calib"]
    assert load_bundle(path)[1] == META


def test_arrays_made_one_at_a_time(tmp_path: Path) -> None:
    """(name, array) pairs are written as they come (a 4K calibration's maps are encoded
    one at a time): the same bundle as from a dict; a repeated name or a failure while
    making them leaves the path as it was."""
    made = []

    def pairs():
        for name, a in _arrays().items():
            made.append(name)
            yield name, a

    path = tmp_path / "calib"
    save_bundle(path, pairs(), META)
    arrays, meta = load_bundle(path)
    assert meta == META and made == list(_arrays())
    for name, a in _arrays().items():
        assert np.array_equal(arrays[name], a) and arrays[name].dtype == a.dtype
    before = path.read_bytes()
    with pytest.raises(ValueError, match="appear once"):
        save_bundle(path, [("a", np.ones(2)), ("a", np.zeros(2))], {})

    def failing():
        yield "a", np.ones(2)
        raise RuntimeError("encoder failed")

    with pytest.raises(RuntimeError, match="encoder failed"):
        save_bundle(path, failing(), {})
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["calib"]


def test_save_refusals(tmp_path: Path) -> None:
    path = tmp_path / "calib"
    with pytest.raises(ValueError, match="object dtype"):
        save_bundle(path, {"o": np.array([None, 1], dtype=object)}, {})
    with pytest.raises(ValueError, match="name"):
        save_bundle(path, {"../evil": np.zeros(1)}, {})
    with pytest.raises(ValueError, match="JSON"):
        save_bundle(path, {}, {"x": {1, 2}})
    with pytest.raises(ValueError, match="JSON"):
        save_bundle(path, {}, {"x": float("nan")})
    assert list(tmp_path.iterdir()) == []


def test_truncated(tmp_path: Path) -> None:
    path = _save(tmp_path / "calib")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(BundleError) as info:
        load_bundle(path)
    msg = str(info.value)
    assert str(path) in msg and "truncated" in msg
    assert "copy the file again, or run `viewcomp calibrate" in msg


def test_flipped_bytes_in_a_member(tmp_path: Path) -> None:
    path = _save(tmp_path / "calib")
    with zipfile.ZipFile(path) as zf:
        info = zf.getinfo("Ww.npy")
    data = bytearray(path.read_bytes())
    # local header: 30 bytes + name + extra field, then the member's data
    name_len = int.from_bytes(data[info.header_offset + 26 : info.header_offset + 28], "little")
    extra_len = int.from_bytes(data[info.header_offset + 28 : info.header_offset + 30], "little")
    start = info.header_offset + 30 + name_len + extra_len
    mid = start + info.compress_size // 2
    data[mid : mid + 4] = bytes(b ^ 0xFF for b in data[mid : mid + 4])
    path.write_bytes(bytes(data))
    with pytest.raises(BundleError, match=r"damaged: cannot read Ww\.npy") as info_err:
        load_bundle(path)
    assert str(path) in str(info_err.value)


def test_any_single_flipped_byte_is_refused_or_harmless(tmp_path: Path) -> None:
    path = tmp_path / "calib"
    save_bundle(path, {"a": np.arange(50, dtype=np.float32)}, {"k": "v"})
    good = path.read_bytes()
    for pos in range(len(good)):
        for mask in (0x01, 0x80, 0xFF):
            bad = bytearray(good)
            bad[pos] ^= mask
            path.write_bytes(bytes(bad))
            try:
                arrays, meta = load_bundle(path)
            except BundleError:
                continue
            # a flip in a field nobody checks (a timestamp, say) must not change the content
            assert meta == {"k": "v"} and np.array_equal(arrays["a"], np.arange(50))


def test_unknown_and_newer_schema(tmp_path: Path) -> None:
    path = _save(tmp_path / "calib")
    for schema, expected in [
        (
            7,
            "written by a newer viewcomp (schema 7); this viewcomp reads schema 3 - "
            "upgrade viewcomp or recalibrate",
        ),
        (
            2,
            "written by an older viewcomp (schema 2, full float32 maps); this viewcomp reads "
            "schema 3 - run `viewcomp calibrate CAPTURE_DIR -o CALIB` again on its capture set",
        ),
        (0, "unknown schema 0; this viewcomp reads schema 3"),
        ("1", "unknown schema '1'"),
    ]:
        doc = _meta_doc(path)
        doc["schema"] = schema
        out = tmp_path / f"schema_{schema}"
        _rewrite(path, out, {"meta.json": json.dumps(doc).encode()})
        with pytest.raises(BundleError) as info:
            load_bundle(out)
        assert expected in str(info.value) and str(out) in str(info.value)


def test_not_a_zip(tmp_path: Path) -> None:
    path = tmp_path / "calib.png"
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(100))
    with pytest.raises(BundleError, match="not a viewcomp calibration bundle"):
        load_bundle(path)
    with pytest.raises(BundleError, match="not found"):
        load_bundle(tmp_path / "missing")
    with pytest.raises(BundleError, match="not a file"):
        load_bundle(tmp_path)


def test_other_zip_files_are_refused(tmp_path: Path) -> None:
    src = _save(tmp_path / "calib")
    npz = tmp_path / "arrays.npz"
    np.savez(npz, a=np.zeros(3))
    with pytest.raises(BundleError, match=r"no meta\.json inside"):
        load_bundle(npz)
    doc = _meta_doc(src)
    doc["format"] = "something-else"
    _rewrite(src, tmp_path / "fmt", {"meta.json": json.dumps(doc).encode()})
    with pytest.raises(BundleError, match="format is 'something-else'"):
        load_bundle(tmp_path / "fmt")
    _rewrite(src, tmp_path / "badjson", {"meta.json": b"{not json"})
    with pytest.raises(BundleError, match="not valid JSON"):
        load_bundle(tmp_path / "badjson")


def test_listed_member_missing(tmp_path: Path) -> None:
    src = _save(tmp_path / "calib")
    _rewrite(src, tmp_path / "b", {"fwd_lut.npy": None})
    with pytest.raises(BundleError, match=r"'fwd_lut' is listed in meta\.json but fwd_lut\.npy"):
        load_bundle(tmp_path / "b")


def test_member_disagreeing_with_meta_or_unlisted(tmp_path: Path) -> None:
    src = _save(tmp_path / "calib")
    buf = tmp_path / "x.npy"
    np.save(buf, np.zeros((2, 2), np.float64))
    _rewrite(src, tmp_path / "b", {"fwd_lut.npy": buf.read_bytes()})
    with pytest.raises(BundleError, match=r"member fwd_lut\.npy is <f8 \[2, 2\]"):
        load_bundle(tmp_path / "b")
    with zipfile.ZipFile(tmp_path / "b", "a") as zf:
        zf.writestr("stray.npy", buf.read_bytes())
    with pytest.raises(BundleError, match=r"not listed in meta\.json: stray\.npy"):
        load_bundle(tmp_path / "b")


def test_pickled_member_is_refused(tmp_path: Path) -> None:
    src = _save(tmp_path / "calib")
    pkl = tmp_path / "o.npy"
    np.save(pkl, np.array([{"evil": 1}], dtype=object), allow_pickle=True)
    _rewrite(src, tmp_path / "b", {"gamma.npy": pkl.read_bytes()})
    with pytest.raises(BundleError, match=r"damaged member gamma\.npy"):
        load_bundle(tmp_path / "b")
