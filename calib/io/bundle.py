"""The calibration bundle: one versioned zip file, readable without pickle.

Layout (a plain zip, inspectable with any unzip tool)::

    meta.json        {"format": "viewcomp-bundle", "schema": 3,
                      "arrays": {name: {"dtype": "<f4", "shape": [h, w, 3]}, ...},
                      "meta": {...the caller's meta...}}
    <name>.npy       one per array, numpy's .npy format (np.lib.format, no pickle)

The file is written at exactly the given path (no extension added) through a temporary file
in the same folder and ``os.replace``, so a reader never sees a half-written bundle. Loading
validates the whole file before returning anything.
"""

from __future__ import annotations

import json
import math
import re
import struct
import zipfile
import zlib
from collections.abc import Iterable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from viewcomp.calib.errors import BundleError
from viewcomp.calib.io import npy
from viewcomp.calib.io.atomic import atomic_open
from viewcomp.calib.io.npy import MAX_ARRAY_BYTES
from viewcomp.calib.io.paths import InputFileError, check_input_file

SCHEMA_VERSION = 3
FORMAT = "viewcomp-bundle"
META_MEMBER = "meta.json"

_NAME_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")
_RECALIBRATE = "run `viewcomp calibrate CAPTURE_DIR -o CALIB` again"
# What a damaged zip can raise while being read; all of it becomes a BundleError.
_ZIP_ERRORS = (
    zipfile.BadZipFile,
    zipfile.LargeZipFile,
    zlib.error,
    EOFError,
    OSError,
    ValueError,
    NotImplementedError,
    RuntimeError,  # e.g. a flipped "encrypted" flag: "password required"
    struct.error,
    KeyError,
    OverflowError,
    UnicodeDecodeError,
)


def save_bundle(
    path: str | Path,
    arrays: Mapping[str, np.ndarray] | Iterable[tuple[str, np.ndarray]],
    meta: dict[str, Any],
) -> None:
    """Write a calibration bundle at exactly ``path``, atomically.

    ``arrays`` maps names (letters, digits, ``_ . -``) to numpy arrays of any shape and
    non-object dtype, or yields (name, array) pairs: each array is written as it comes and
    can be freed before the next is made (a 4K calibration's maps are encoded one at a time).
    ``meta`` is a JSON-serialisable dict (lists come back as lists, tuples as lists). Parent
    folders are created. Raises ``ValueError`` for an unsafe or repeated name, an object
    array or meta that JSON cannot hold; ``path`` is left as it was then.
    """
    p = Path(path)
    if not isinstance(meta, dict):
        raise ValueError(f"bundle meta must be a dict, got {type(meta).__name__}")
    try:
        json.dumps(meta, allow_nan=False)  # before anything is written
    except (TypeError, ValueError) as exc:
        raise ValueError(f"bundle meta is not JSON-serialisable: {exc}") from None
    pairs = arrays.items() if isinstance(arrays, Mapping) else arrays
    listing: dict[str, dict[str, Any]] = {}
    p.parent.mkdir(parents=True, exist_ok=True)
    with (
        atomic_open(p) as f,
        zipfile.ZipFile(f, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=6) as zf,
    ):
        for name, arr in pairs:
            if not isinstance(name, str) or not _NAME_RE.match(name) or name in listing:
                raise ValueError(
                    f"bundle array name {name!r} must be letters, digits, '_', '.', '-', "
                    "and appear once"
                )
            a = np.asarray(arr)
            if a.dtype.hasobject:
                raise ValueError(f"bundle array {name!r} has an object dtype, which needs pickle")
            listing[name] = {"dtype": a.dtype.str, "shape": list(a.shape)}
            with zf.open(f"{name}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, a, allow_pickle=False)
            del a, arr
        # meta.json last: its listing is of what was written (the loader reads by name).
        doc = {"format": FORMAT, "schema": SCHEMA_VERSION, "arrays": listing, "meta": meta}
        zf.writestr(META_MEMBER, json.dumps(doc, indent=1, allow_nan=False).encode("utf-8"))


def _fail(p: Path, cause: str, fix: str) -> BundleError:
    return BundleError(f"{p}: {cause} - {fix}")


@dataclass(frozen=True)
class ArrayRule:
    """What one array of a bundle may be, checked by :func:`load_bundle`.

    ``shape``: each axis an int, ``"H"``/``"W"`` (the projector grid from the bundle's own
    rig) or ``"*"`` (any length); ``kinds``: the numpy dtype kinds allowed (``"f"`` float);
    ``low``/``high``: the range of the values (besides being finite).
    """

    shape: tuple[int | str, ...]
    kinds: str = "f"
    low: float = -math.inf
    high: float = math.inf


# The arrays of a calibration bundle (viewcomp.calib.fit.calibrate.Calibration): one line
# per array. Arrays without a line get the generic checks only (size cap, finite floats).
# The per-pixel maps are byte planes of error-bounded integers (viewcomp.calib.io.compact),
# each with its quantisation steps; the geometry is not stored (the rig gives it).
CALIBRATION_ARRAYS: dict[str, ArrayRule] = {
    "paper.n": ArrayRule((3,)),
    "paper.means_c": ArrayRule((4, 3)),
    "paper.ramp_cols_c": ArrayRule(("W", 3)),
    "paper.w_tilde_w": ArrayRule((3, 3)),
    "paper.rho_w": ArrayRule((256, 3)),
    "paper.ksis": ArrayRule((3,)),
    "paper.gamma": ArrayRule((3,)),
    "paper.stat_mask": ArrayRule(("H", "W"), kinds="u", low=0, high=1),
    "pixel.f_lut": ArrayRule((256, 3), low=-0.001, high=1.001),  # normalised response
    "pixel.Ww.gain": ArrayRule((4, "H", "W", 3), kinds="u"),
    "pixel.Ww.gain_step": ArrayRule((3,)),
    "pixel.Ww.mix": ArrayRule((4, "H", "W", 6), kinds="u"),
    "pixel.Ww.mix_step": ArrayRule((6,)),
    "pixel.Aw": ArrayRule((4, "H", "W", 3), kinds="u"),
    "pixel.Aw_step": ArrayRule((3,)),
    "pixel.Wc.gain": ArrayRule((4, "H", "W", 3), kinds="u"),
    "pixel.Wc.gain_step": ArrayRule((3,)),
    "pixel.Wc.mix": ArrayRule((4, "H", "W", 6), kinds="u"),
    "pixel.Wc.mix_step": ArrayRule((6,)),
    "pixel.Ac": ArrayRule((4, "H", "W", 3), kinds="u"),
    "pixel.Ac_step": ArrayRule((3,)),
    "pixel.lobe": ArrayRule(("*", 3), low=0.0),  # the tabulated lobe (units of s)
    "pixel.baseline": ArrayRule((3,)),
    "pixel.black_share": ArrayRule((3,), low=0.0, high=1.0),
}

MAX_MEMBERS = 256  # members of one bundle
MAX_META_BYTES = 16 << 20  # meta.json: the rig's text and the fit statistics
MAX_BUNDLE_BYTES = 8 << 30  # all arrays together, as declared before reading any
_MAX_NPY_HEADER = 1 << 16  # bytes of a .npy header (numpy's own limit is 10000)


def _grid(p: Path, user_meta: dict[str, Any]) -> dict[str, int]:
    """{"H": h, "W": w}: the projector grid of the rig the bundle's meta holds."""
    import tomllib

    try:
        rig = tomllib.loads(user_meta["rig"])
        w, h = rig["projector"]["resolution"]
        if not all(isinstance(v, int) and 0 < v <= 65536 for v in (w, h)):
            raise ValueError(f"resolution {w}x{h}")
    except (KeyError, TypeError, ValueError, tomllib.TOMLDecodeError) as exc:
        raise _fail(
            p, f"its rig has no usable projector resolution ({exc})", _RECALIBRATE
        ) from None
    return {"H": h, "W": w}


def _listed_spec(p: Path, name: str, spec: Any) -> tuple[np.dtype, tuple[int, ...], int]:
    """(dtype, shape, bytes) of one array as meta.json lists it, checked against the caps."""
    try:
        dtype = np.dtype(spec["dtype"])
        shape = tuple(spec["shape"])
        if dtype.hasobject or not all(isinstance(n, int) and n >= 0 for n in shape):
            raise ValueError(spec)
    except (KeyError, TypeError, ValueError):
        raise _fail(
            p, f"{META_MEMBER} lists array {name!r} as {spec!r:.80}", _RECALIBRATE
        ) from None
    nbytes = math.prod(shape) * dtype.itemsize
    if nbytes > MAX_ARRAY_BYTES:
        raise _fail(
            p,
            f"{META_MEMBER} lists array {name!r} as {dtype.str} {list(shape)}: "
            f"{nbytes / 2**30:.1f} GiB, over the {MAX_ARRAY_BYTES / 2**30:g} GiB limit",
            _RECALIBRATE,
        )
    return dtype, shape, nbytes


def _check_rule(
    p: Path, name: str, dtype: np.dtype, shape: tuple[int, ...], rule: ArrayRule, dims: dict
) -> None:
    want = tuple(dims.get(a, a) if isinstance(a, str) else a for a in rule.shape)
    fits = len(want) == len(shape) and all(
        w == "*" or w == n for w, n in zip(want, shape, strict=True)
    )
    if dtype.kind not in rule.kinds or not fits:
        shown = "x".join(str(a) for a in want)
        raise _fail(
            p,
            f"array {name!r} is {dtype.str} {list(shape)}, but a calibration for this rig's "
            f"{dims.get('W')}x{dims.get('H')} projector needs a {rule.kinds!r}-kind array of "
            f"shape {shown}",
            _RECALIBRATE,
        )


def _check_values(p: Path, name: str, a: np.ndarray, rule: ArrayRule | None) -> None:
    if a.dtype.kind not in "fc":
        return
    finite = np.isfinite(a)
    if not finite.all():
        raise _fail(
            p,
            f"array {name!r} holds {int(a.size - np.count_nonzero(finite))} NaN or infinite "
            "value(s)",
            _RECALIBRATE,
        )
    if rule is not None and a.size and (a.min() < rule.low or a.max() > rule.high):
        raise _fail(
            p,
            f"array {name!r} has values from {a.min():g} to {a.max():g}, outside "
            f"[{rule.low:g}, {rule.high:g}]",
            _RECALIBRATE,
        )


def load_bundle(
    path: str | Path, rules: dict[str, ArrayRule] | None = None
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Read a calibration bundle: (arrays, meta), with meta as given to :func:`save_bundle`.

    Everything is checked before anything is returned, and every size before the data it
    sizes is read: the zip listing (member count and names, each member's declared size
    against what meta.json lists, caps on meta.json, on each array and on all of them),
    meta.json (format, schema version: a newer or unknown one is refused), each ``.npy``
    header against meta.json (dtype, shape) and against ``rules`` (for a calibration,
    :data:`CALIBRATION_ARRAYS`: shapes from the bundle's own rig); then each member's CRC and
    values (finite, in the rule's range). Nothing is ever decompressed beyond the size its
    listing declares, so a zip bomb is refused before it is inflated.
    Raises :class:`BundleError` naming the file, the cause and the fix.
    """
    p = Path(path)
    _check_container(p)
    rules = rules or {}
    current = "the zip directory"
    try:
        with zipfile.ZipFile(p, "r") as zf:
            by_name = _members(p, zf)
            current = META_MEMBER
            listing, user_meta, specs = _listing(p, zf, by_name)
            _check_listing(p, by_name, listing, user_meta, specs, rules)
            arrays: dict[str, np.ndarray] = {}

            def read(name: str) -> np.ndarray:
                dtype, shape, _ = specs[name]
                a = _read_member(p, zf, by_name[f"{name}.npy"], listing[name], dtype, shape)
                _check_values(p, name, a, rules.get(name))
                return a

            # Two members at a time: zlib inflates and numpy checks with the GIL released, so
            # a second core halves the wait (zipfile serialises the file reads themselves).
            with ThreadPoolExecutor(max_workers=2) as pool:
                futures = {name: pool.submit(read, name) for name in specs}
                for name, future in futures.items():
                    current = f"{name}.npy"
                    arrays[name] = future.result()
    except BundleError:
        raise
    except _ZIP_ERRORS as exc:
        raise _fail(
            p, f"damaged: cannot read {current} ({exc})", f"copy the file again, or {_RECALIBRATE}"
        ) from None
    return arrays, user_meta


def _check_container(p: Path) -> None:
    """A readable file that is a zip (with its directory): else BundleError saying which."""
    if not p.exists() and not p.is_symlink():
        raise _fail(
            p, "not found", f"give the file written by `viewcomp calibrate`, or {_RECALIBRATE}"
        )
    try:
        check_input_file(p, "bundle", "the bundle file written by `viewcomp calibrate`")
    except InputFileError as exc:
        cause = str(exc).split(": ", 1)[1].rsplit(" - ", 1)[0]
        if cause == "is a folder, not a file":
            cause = "is not a file (a folder)"
        raise _fail(p, cause, "give the bundle file written by `viewcomp calibrate`") from None
    with p.open("rb") as fh:
        head = fh.read(4)
    if not zipfile.is_zipfile(p):
        if head == b"PK\x03\x04":
            cause = (
                "truncated or damaged: it starts like a bundle but its end "
                "(the zip directory) is missing"
            )
            fix = f"copy the file again, or {_RECALIBRATE}"
        else:
            cause = "not a viewcomp calibration bundle (not a zip file)"
            fix = "give the file written by `viewcomp calibrate`"
        raise _fail(p, cause, fix)


def _members(p: Path, zf: zipfile.ZipFile) -> dict[str, zipfile.ZipInfo]:
    """The zip's members by name: few enough, each name once, meta.json among them."""
    infos = zf.infolist()
    if len(infos) > MAX_MEMBERS:
        raise _fail(p, f"{len(infos)} members, more than a bundle has", _RECALIBRATE)
    by_name = {i.filename: i for i in infos}
    if len(by_name) != len(infos):
        raise _fail(p, "a member name appears twice", _RECALIBRATE)
    if META_MEMBER not in by_name:
        raise _fail(
            p,
            f"no {META_MEMBER} inside, so not a viewcomp calibration bundle",
            "give the file written by `viewcomp calibrate`",
        )
    return by_name


Spec = tuple[np.dtype[Any], tuple[int, ...], int]  # dtype, shape, bytes of a listed array


def _listing(
    p: Path, zf: zipfile.ZipFile, by_name: dict[str, zipfile.ZipInfo]
) -> tuple[dict[str, Any], dict[str, Any], dict[str, Spec]]:
    """meta.json (its size capped before it is read): the arrays' listing, the caller's meta
    and each listed array's (dtype, shape, bytes), their total capped."""
    meta_info = by_name[META_MEMBER]
    if meta_info.file_size > MAX_META_BYTES:
        raise _fail(
            p,
            f"{META_MEMBER} declares {meta_info.file_size} bytes, over the "
            f"{MAX_META_BYTES >> 20} MiB a bundle's meta.json can be",
            _RECALIBRATE,
        )
    doc = _parse_meta(p, zf.read(meta_info))
    listing, user_meta = doc["arrays"], doc["meta"]
    specs = {name: _listed_spec(p, name, spec) for name, spec in listing.items()}
    total = sum(s[2] for s in specs.values())
    if total > MAX_BUNDLE_BYTES:
        raise _fail(
            p,
            f"{META_MEMBER} lists {total / 2**30:.1f} GiB of arrays, over the "
            f"{MAX_BUNDLE_BYTES / 2**30:g} GiB limit",
            _RECALIBRATE,
        )
    return listing, user_meta, specs


def _check_listing(
    p: Path,
    by_name: dict[str, zipfile.ZipInfo],
    listing: dict[str, Any],
    user_meta: dict[str, Any],
    specs: dict[str, Spec],
    rules: dict[str, ArrayRule],
) -> None:
    """Each listed array against ``rules`` (shapes from the bundle's grid), every member
    listed, every listed array present with no more bytes than its listing says."""
    if any(name in rules for name in specs):
        dims = _grid(p, user_meta)
        for name, (dtype, shape, _) in specs.items():
            if name in rules:
                _check_rule(p, name, dtype, shape, rules[name], dims)
    expected = {f"{name}.npy" for name in listing} | {META_MEMBER}
    unlisted = sorted(set(by_name) - expected)
    if unlisted:
        raise _fail(p, f"members not listed in {META_MEMBER}: {', '.join(unlisted)}", _RECALIBRATE)
    for name, (_, _, nbytes) in specs.items():
        member = f"{name}.npy"
        if member not in by_name:
            raise _fail(
                p,
                f"array {name!r} is listed in {META_MEMBER} but {member} is missing",
                _RECALIBRATE,
            )
        info = by_name[member]
        if info.file_size > nbytes + _MAX_NPY_HEADER:
            raise _fail(
                p,
                f"member {member} declares {info.file_size} bytes, but {META_MEMBER} "
                f"lists {listing[name]} ({nbytes} bytes)",
                _RECALIBRATE,
            )


def _parse_meta(p: Path, data: bytes) -> dict[str, Any]:
    """meta.json's document, checked: format, schema, an 'arrays' and a 'meta' table."""
    try:
        doc = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise _fail(p, f"{META_MEMBER} is not valid JSON ({exc})", _RECALIBRATE) from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise _fail(
            p,
            f'not a viewcomp calibration bundle (format is {got!r}, expected "{FORMAT}")',
            "give the file written by `viewcomp calibrate`",
        )
    schema = doc.get("schema")
    if not isinstance(schema, int) or isinstance(schema, bool):
        raise _fail(
            p,
            f"unknown schema {schema!r}; this viewcomp reads schema {SCHEMA_VERSION}",
            _RECALIBRATE,
        )
    if schema > SCHEMA_VERSION:
        raise _fail(
            p,
            f"written by a newer viewcomp (schema {schema}); this viewcomp reads schema "
            f"{SCHEMA_VERSION}",
            "upgrade viewcomp or recalibrate",
        )
    if schema in (1, 2):  # before the compact per-pixel maps (viewcomp.calib.io.compact)
        raise _fail(
            p,
            f"written by an older viewcomp (schema {schema}, full float32 maps); this "
            f"viewcomp reads schema {SCHEMA_VERSION}",
            "run `viewcomp calibrate CAPTURE_DIR -o CALIB` again on its capture set",
        )
    if schema != SCHEMA_VERSION:
        raise _fail(
            p, f"unknown schema {schema}; this viewcomp reads schema {SCHEMA_VERSION}", _RECALIBRATE
        )
    if not isinstance(doc.get("arrays"), dict) or not isinstance(doc.get("meta"), dict):
        raise _fail(p, f"{META_MEMBER} lacks its 'arrays' or 'meta' table", _RECALIBRATE)
    return doc


def _read_member(
    p: Path,
    zf: zipfile.ZipFile,
    info: zipfile.ZipInfo,
    spec: Any,
    dtype: np.dtype,
    shape: tuple[int, ...],
) -> np.ndarray:
    """One array member: its header is compared with meta.json's listing before its data is
    read; the data is read to its declared end, so the member's CRC is checked."""
    member = info.filename
    with zf.open(info) as f:
        try:
            got_shape, got_dtype = npy.read_header(f)
        except ValueError as exc:
            raise _fail(p, f"damaged member {member} ({exc})", _RECALIBRATE) from None
        if got_dtype != dtype or got_shape != shape or got_dtype.str != spec.get("dtype"):
            raise _fail(
                p,
                f"member {member} is {got_dtype.str} {list(got_shape)}, but {META_MEMBER} says "
                f"{spec}",
                _RECALIBRATE,
            )
        nbytes = math.prod(shape) * dtype.itemsize
        if info.file_size != f.tell() + nbytes:
            raise _fail(
                p,
                f"member {member} declares {info.file_size} bytes, but its header says "
                f"{dtype.str} {list(shape)} ({f.tell() + nbytes} bytes with the header)",
                _RECALIBRATE,
            )
        try:
            a = npy.read_data(f, shape, dtype)
        except ValueError as exc:
            raise _fail(p, f"damaged member {member} ({exc})", _RECALIBRATE) from None
        if f.read(1):  # never true after the size check; reading to the end checks the CRC
            raise _fail(p, f"damaged member {member} (data after the array)", _RECALIBRATE)
    return a
