"""scripts/convert_neural_brdf.py: Neural-BRDF weights (Keras HDF5, or npy folders) -> the
measured-material .npz that `simulate --material` reads."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.support.scripts import load_script
from viewcomp.calib.sim.materials import load_material

NAMES = ("W1", "b1", "W2", "b2", "W3", "b3")


def _script():
    return load_script("scripts/convert_neural_brdf.py")


def _keras_h5(path: Path, arrays: dict[str, np.ndarray], whole_model: bool) -> None:
    """A weight file in Keras 2's HDF5 layout: the root (or ``model_weights``) lists the
    layers in ``layer_names``; each layer group lists its datasets in ``weight_names``
    (``dense_1/kernel:0``), stored at ``layer/dense_1/kernel:0``. An input layer without
    weights comes first, as in a saved Sequential model."""
    h5py = pytest.importorskip("h5py")
    with h5py.File(path, "w") as f:
        root = f.create_group("model_weights") if whole_model else f
        names = ["input_1", "dense_1", "dense_2", "dense_3"]
        root.attrs["layer_names"] = np.array([n.encode() for n in names])
        root.create_group("input_1").attrs["weight_names"] = np.array([], dtype="S1")
        for i, layer in enumerate(names[1:], start=1):
            g = root.create_group(layer)
            g.attrs["weight_names"] = np.array(
                [f"{layer}/kernel:0".encode(), f"{layer}/bias:0".encode()]
            )
            g.create_dataset(f"{layer}/kernel:0", data=arrays[f"W{i}"])
            g.create_dataset(f"{layer}/bias:0", data=arrays[f"b{i}"])


def test_h5_and_npy_folders_convert_to_the_same_material(
    materials_dir: Path, tmp_path: Path
) -> None:
    """red-specular-plastic's arrays written as Keras HDF5 (weights alone and a whole model)
    and as the repository's npy folder all convert to its arrays, and the converted file
    evaluates to the reference values of the materials' README (t = 0: 12.9 11.1 11.1)."""
    script = _script()
    source = np.load(materials_dir / "red-specular-plastic.npz")
    arrays = {k: source[k] for k in NAMES}
    inputs = tmp_path / "in"
    inputs.mkdir()
    _keras_h5(inputs / "weights.h5", arrays, whole_model=False)
    _keras_h5(inputs / "model.h5", arrays, whole_model=True)
    npy = inputs / "npy"
    npy.mkdir()
    for suffix, key in (("fc1", "W1"), ("b1", "b1"), ("fc2", "W2"), ("b2", "b2"),
                        ("fc3", "W3"), ("b3", "b3")):  # fmt: skip
        np.save(npy / f"folder_{suffix}.npy", arrays[key])
    out = tmp_path / "out"
    assert script.main([str(inputs / "weights.h5"), str(inputs / "model.h5"), str(npy),
                        "-o", str(out)]) == 0  # fmt: skip
    s, c = np.sin(np.radians(10.0)), np.cos(np.radians(10.0))
    for name in ("weights", "model", "folder"):
        got = np.load(out / f"{name}.npz", allow_pickle=False)
        for k in NAMES:
            assert np.array_equal(got[k], arrays[k].astype(np.float32)), (name, k)
        brdf = load_material(out / f"{name}.npz").brdf(
            np.array([-s, 0.0, c]), np.array([s, 0.0, c])
        )
        assert np.allclose(brdf, [12.9, 11.1, 11.1], rtol=0.01), (name, brdf)


def test_bad_inputs_exit_2_and_write_nothing(
    materials_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    script = _script()
    source = np.load(materials_dir / "spectralon.npz")
    arrays = {k: source[k] for k in NAMES}
    bad = dict(arrays, W2=arrays["W2"][:, :20])  # a layer of the wrong width
    _keras_h5(tmp_path / "wrong.h5", bad, whole_model=False)
    (tmp_path / "text.h5").write_text("not hdf5")
    out = tmp_path / "out"
    for name, said in (("wrong.h5", "W2"), ("text.h5", "not an HDF5 file"),
                       ("x.txt", "neither")):  # fmt: skip
        assert script.main([str(tmp_path / name), "-o", str(out)]) == 2
        assert said in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())
    good = tmp_path / "good.h5"
    _keras_h5(good, arrays, whole_model=False)
    assert script.main([str(good), "-o", str(out)]) == 0
    assert script.main([str(good), "-o", str(out)]) == 2  # no --force: kept
    assert "--force" in capsys.readouterr().err
    assert script.main([str(good), "-o", str(out), "--force"]) == 0
