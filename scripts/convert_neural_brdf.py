#!/usr/bin/env python3
"""Convert published Neural-BRDF weights into viewcomp's measured-material ``.npz`` files.

Sztrajman et al., "Neural BRDF Representation and Importance Sampling" (CGF 2021) publish
their fitted materials (MERL, RGL-EPFL, Nielsen 2015) as Keras HDF5 weight files, one
``MATERIAL.h5`` per material (beside a ``MATERIAL.json`` holding the architecture, which this
script does not need), and as folders of NumPy arrays ``MATERIAL_fc1.npy``, ``_fc2``, ``_fc3``,
``_b1``, ``_b2``, ``_b3``. viewcomp's `simulate --material` and `evaluate --materials` read one
``.npz`` per material with the arrays ``W1 (6, 21) b1 W2 (21, 21) b2 W3 (21, 3) b3``.

    .venv/bin/python scripts/convert_neural_brdf.py merl_nbrdf/*.h5 -o materials/
    .venv/bin/python scripts/convert_neural_brdf.py merl_nbrdf/npy/ -o materials/

The HDF5 reader needs ``h5py`` (``.venv/bin/python -m pip install h5py``; the test set-up
installs it). It takes the three Dense layers in the order of the file's ``layer_names``
attribute (Keras's own record of the model's order; under ``model_weights`` when the whole
model was saved), each layer's kernel and bias by its ``weight_names``. Every written file is
read back with viewcomp's own loader (:func:`viewcomp.calib.sim.materials.load_material`) and
the BRDF evaluated once, so a file that converts is a file viewcomp can use. Nothing is
written for an input that fails; an existing output is replaced only with ``--force``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

NAMES = ("W1", "b1", "W2", "b2", "W3", "b3")
NPY_SUFFIXES = {"fc1": "W1", "b1": "b1", "fc2": "W2", "b2": "b2", "fc3": "W3", "b3": "b3"}


class ConvertError(Exception):
    """An input that cannot be converted; the message names it and says why."""


def _attr_names(obj: object, key: str) -> list[str]:
    attrs = getattr(obj, "attrs", {})
    if key not in attrs:
        return []
    return [v.decode("utf-8") if isinstance(v, bytes) else str(v) for v in attrs[key]]


def read_h5(path: Path) -> dict[str, np.ndarray]:
    """The six arrays of a Keras HDF5 weight file (save_weights or a whole saved model)."""
    try:
        import h5py
    except ImportError:
        raise ConvertError(
            f"{path}: reading .h5 files needs h5py; install it with "
            "`.venv/bin/python -m pip install h5py`, or convert the npy/ folder instead"
        ) from None
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise ConvertError(f"{path}: not an HDF5 file h5py can read ({exc})") from None
    with f:
        root = f["model_weights"] if "model_weights" in f else f
        layers = _attr_names(root, "layer_names")
        if not layers:
            raise ConvertError(
                f"{path}: no 'layer_names' attribute: not a Keras weight file (expected the "
                "Neural-BRDF repository's MATERIAL.h5)"
            )
        dense: list[tuple[np.ndarray, np.ndarray]] = []
        for name in layers:
            weights = _attr_names(root[name], "weight_names")
            if not weights:
                continue  # a layer without weights (input, activation)
            arrays = {
                w.rsplit("/", 1)[-1].split(":")[0]: np.asarray(root[name][w]) for w in weights
            }
            if set(arrays) != {"kernel", "bias"}:
                raise ConvertError(
                    f"{path}: layer {name} holds {sorted(arrays)}, not a Dense layer's kernel "
                    "and bias"
                )
            dense.append((arrays["kernel"], arrays["bias"]))
    if len(dense) != 3:
        raise ConvertError(
            f"{path}: {len(dense)} layers with weights, the Neural-BRDF network has 3 (6-21-21-3)"
        )
    return {
        "W1": dense[0][0], "b1": dense[0][1],
        "W2": dense[1][0], "b2": dense[1][1],
        "W3": dense[2][0], "b3": dense[2][1],
    }  # fmt: skip


def read_npy_folder(folder: Path) -> dict[str, dict[str, np.ndarray]]:
    """Materials of a folder of ``MATERIAL_fc1.npy`` ... ``MATERIAL_b3.npy`` arrays."""
    found: dict[str, dict[str, np.ndarray]] = {}
    for p in sorted(folder.glob("*.npy")):
        stem, _, suffix = p.stem.rpartition("_")
        if suffix in NPY_SUFFIXES and stem:
            found.setdefault(stem, {})[NPY_SUFFIXES[suffix]] = np.load(p, allow_pickle=False)
    for name, arrays in found.items():
        missing = [k for k in NAMES if k not in arrays]
        if missing:
            raise ConvertError(
                f"{folder}: material {name} lacks {', '.join(missing)} (its _fc/_b .npy)"
            )
    if not found:
        raise ConvertError(f"{folder}: no MATERIAL_fc1.npy ... MATERIAL_b3.npy arrays in it")
    return found


def write_material(arrays: dict[str, np.ndarray], out: Path, force: bool) -> None:
    """Write one ``.npz`` atomically and check it with viewcomp's loader."""
    from viewcomp.calib.io.atomic import atomic_path
    from viewcomp.calib.sim.materials import MaterialError, load_material

    if out.exists() and not force:
        raise ConvertError(f"{out} exists; pass --force to replace it")
    data = {k: np.ascontiguousarray(arrays[k], np.float32) for k in NAMES}
    with atomic_path(out) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, **data)
        try:
            material = load_material(tmp)
            s, c = np.sin(np.radians(10.0)), np.cos(np.radians(10.0))
            value = material.brdf(np.array([-s, 0.0, c]), np.array([s, 0.0, c]))
        except MaterialError as exc:
            raise ConvertError(
                f"{out}: the converted arrays are not a usable material: {exc}"
            ) from None
        if not np.all(np.isfinite(value)):
            raise ConvertError(f"{out}: the converted material's BRDF is not finite")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="Convert Neural-BRDF weights (.h5 files, or npy/ folders) into viewcomp's "
        "measured-material .npz files (for simulate --material, evaluate --materials)."
    )
    parser.add_argument("inputs", nargs="+", help="MATERIAL.h5 files and/or folders of .npy arrays")
    parser.add_argument("-o", "--output", required=True, help="folder to write MATERIAL.npz into")
    parser.add_argument("--force", action="store_true", help="replace existing .npz files")
    args = parser.parse_args(argv)
    out_dir = Path(args.output)
    if out_dir.exists() and not out_dir.is_dir():
        print(f"convert_neural_brdf: error: {out_dir} is a file, not a folder", file=sys.stderr)
        return 2
    jobs: list[tuple[str, dict[str, np.ndarray]]] = []
    try:
        for item in map(Path, args.inputs):
            if item.is_dir():
                jobs += sorted(read_npy_folder(item).items())
            elif item.suffix == ".h5":
                jobs.append((item.stem, read_h5(item)))
            else:
                raise ConvertError(f"{item}: neither a .h5 file nor a folder of .npy arrays")
        out_dir.mkdir(parents=True, exist_ok=True)
        for name, arrays in jobs:
            target = out_dir / f"{name}.npz"
            write_material(arrays, target, args.force)
            print(f"wrote {target}")
    except ConvertError as exc:
        print(f"convert_neural_brdf: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
