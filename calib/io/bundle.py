"""The calibration bundle: one versioned zip file, readable without pickle.

Layout (a plain zip, inspectable with any unzip tool)::

    meta.json        {"format": "viewcomp-bundle", "schema": 1,
                      "arrays": {name: {"dtype": "<f4", "shape": [h, w, 3]}, ...},
                      "meta": {...the caller's meta...}}
    <name>.npy       one per array, numpy's .npy format (np.lib.format, no pickle)

The file is written at exactly the given path (no extension added) through a temporary file
in the same folder and ``os.replace``, so a reader never sees a half-written bundle. Loading
validates the whole file before returning anything.
"""

from __future__ import annotations

import io
import json
import re
import struct
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from viewcomp.calib.errors import ViewcompError
from viewcomp.calib.io.atomic import atomic_open

SCHEMA_VERSION = 1
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


class BundleError(ViewcompError, ValueError):
    """A calibration bundle that cannot be used; the message names file, cause and fix."""


def save_bundle(path: str | Path, arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> None:
    """Write a calibration bundle at exactly ``path``, atomically.

    ``arrays`` maps names (letters, digits, ``_ . -``) to numpy arrays of any shape and
    non-object dtype; ``meta`` is a JSON-serialisable dict (lists come back as lists, tuples
    as lists). Parent folders are created. Raises ``ValueError`` for an unsafe name, an object
    array or meta that JSON cannot hold; nothing is written then.
    """
    p = Path(path)
    listing: dict[str, dict[str, Any]] = {}
    checked: dict[str, np.ndarray] = {}
    for name, arr in arrays.items():
        if not isinstance(name, str) or not _NAME_RE.match(name):
            raise ValueError(f"bundle array name {name!r} must be letters, digits, '_', '.', '-'")
        a = np.asarray(arr)
        if a.dtype.hasobject:
            raise ValueError(f"bundle array {name!r} has an object dtype, which needs pickle")
        checked[name] = a
        listing[name] = {"dtype": a.dtype.str, "shape": list(a.shape)}
    if not isinstance(meta, dict):
        raise ValueError(f"bundle meta must be a dict, got {type(meta).__name__}")
    doc = {"format": FORMAT, "schema": SCHEMA_VERSION, "arrays": listing, "meta": meta}
    try:
        meta_bytes = json.dumps(doc, indent=1, allow_nan=False).encode("utf-8")
    except (TypeError, ValueError) as exc:
        raise ValueError(f"bundle meta is not JSON-serialisable: {exc}") from None

    p.parent.mkdir(parents=True, exist_ok=True)
    with (
        atomic_open(p) as f,
        zipfile.ZipFile(f, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf,
    ):
        zf.writestr(META_MEMBER, meta_bytes)
        for name, a in checked.items():
            with zf.open(f"{name}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, a, allow_pickle=False)


def _fail(p: Path, cause: str, fix: str) -> BundleError:
    return BundleError(f"{p}: {cause} - {fix}")


def load_bundle(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Read a calibration bundle: (arrays, meta), with meta as given to :func:`save_bundle`.

    Everything is checked before anything is returned: the zip's structure and every
    member's CRC, meta.json, the format, the schema version (a newer or unknown schema is
    refused), and that each array listed in meta.json is present with its dtype and shape.
    Raises :class:`BundleError` naming the file, the cause and the fix.
    """
    p = Path(path)
    if not p.exists():
        raise _fail(
            p, "not found", f"give the file written by `viewcomp calibrate`, or {_RECALIBRATE}"
        )
    if not p.is_file():
        raise _fail(p, "is not a file", "give the bundle file written by `viewcomp calibrate`")
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

    members: dict[str, bytes] = {}
    current = "the zip directory"
    try:
        with zipfile.ZipFile(p, "r") as zf:
            for info in zf.infolist():
                current = info.filename
                members[info.filename] = zf.read(info)  # checks the CRC of each member
    except _ZIP_ERRORS as exc:
        raise _fail(
            p, f"damaged: cannot read {current} ({exc})", f"copy the file again, or {_RECALIBRATE}"
        ) from None

    if META_MEMBER not in members:
        raise _fail(
            p,
            f"no {META_MEMBER} inside, so not a viewcomp calibration bundle",
            "give the file written by `viewcomp calibrate`",
        )
    try:
        doc = json.loads(members[META_MEMBER].decode("utf-8"))
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
    if schema != SCHEMA_VERSION:
        raise _fail(
            p, f"unknown schema {schema}; this viewcomp reads schema {SCHEMA_VERSION}", _RECALIBRATE
        )
    listing = doc.get("arrays")
    user_meta = doc.get("meta")
    if not isinstance(listing, dict) or not isinstance(user_meta, dict):
        raise _fail(p, f"{META_MEMBER} lacks its 'arrays' or 'meta' table", _RECALIBRATE)

    expected = {f"{name}.npy" for name in listing} | {META_MEMBER}
    unlisted = sorted(set(members) - expected)
    if unlisted:
        raise _fail(p, f"members not listed in {META_MEMBER}: {', '.join(unlisted)}", _RECALIBRATE)
    arrays: dict[str, np.ndarray] = {}
    for name, spec in listing.items():
        member = f"{name}.npy"
        if member not in members:
            raise _fail(
                p,
                f"array {name!r} is listed in {META_MEMBER} but {member} is missing",
                _RECALIBRATE,
            )
        try:
            a = np.lib.format.read_array(io.BytesIO(members[member]), allow_pickle=False)
        except (ValueError, EOFError, OSError) as exc:
            raise _fail(p, f"damaged member {member} ({exc})", _RECALIBRATE) from None
        if (
            not isinstance(spec, dict)
            or spec.get("dtype") != a.dtype.str
            or spec.get("shape") != list(a.shape)
        ):
            raise _fail(
                p,
                f"member {member} is {a.dtype.str} {list(a.shape)}, but {META_MEMBER} says {spec}",
                _RECALIBRATE,
            )
        arrays[name] = a
    return arrays, user_meta
