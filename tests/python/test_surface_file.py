"""Measured surfaces from Python: Heightfield.read takes NumPy files (written here by NumPy),
x3p and SDF files, and hf.save writes them; orientation and units as docs/surfaces.md says."""
import os
import subprocess

import numpy as np
import pytest

import wavebrdf as wb


def image(rng, rows=6, cols=9):
    """Heights in um, rows along y, columns along x (the image convention of the files)."""
    return rng.normal(size=(rows, cols)) * 0.2 + np.arange(cols)[None, :] * 0.01


@pytest.mark.parametrize("dtype", ["<f8", ">f8", "<f4", ">f4"])
@pytest.mark.parametrize("order", ["C", "F"])
def test_read_numpy_files(tmp_path, rng, dtype, order):
    a = image(rng).astype(dtype)
    a = np.asfortranarray(a) if order == "F" else np.ascontiguousarray(a)
    path = str(tmp_path / "s.npy")
    np.save(path, a)
    hf = wb.Heightfield.read(path, texel_um=0.5)
    # Transposed: the heightfield's row index runs along x; heights kept in um.
    assert hf.values.shape == (9, 6)
    assert hf.texel_um == 0.5 and hf.vscale == 1.0
    np.testing.assert_array_equal(hf.values * hf.texel_um * hf.vscale, a.astype(np.float64).T)


def test_read_needs_spacing_and_refuses_nan(tmp_path, rng):
    a = image(rng)
    path = str(tmp_path / "s.npy")
    np.save(path, a)
    with pytest.raises(RuntimeError, match="states no spacing"):
        wb.Heightfield.read(path)
    a[2, 3] = np.nan
    np.save(path, a)
    with pytest.raises(ValueError, match="wavebrdf convert"):
        wb.Heightfield.read(path, texel_um=1.0)
    with pytest.raises(RuntimeError, match="'<i8'"):
        np.save(path, np.zeros((3, 3), dtype=np.int64))
        wb.Heightfield.read(path, texel_um=1.0)


def test_save_and_read_back(tmp_path, rng):
    hf = wb.Heightfield(rng.normal(size=(8, 5)), texel_um=0.25, vscale=2.0)
    heights = hf.values * hf.texel_um * hf.vscale
    for ext in (".x3p", ".sdf", ".exr"):
        path = str(tmp_path / ("h" + ext))
        hf.save(path)
        back = wb.Heightfield.read(path)
        assert back.texel_um == pytest.approx(0.25)
        tol = 1e-6 if ext == ".exr" else 1e-13  # EXR holds float32
        np.testing.assert_allclose(back.values * back.texel_um * back.vscale, heights, rtol=tol, atol=tol)
    path = str(tmp_path / "h.npy")
    hf.save(path)
    np.testing.assert_array_equal(np.load(path), heights.T)  # rows along y in the file
    with pytest.raises(ValueError, match=r"\.x3p, \.sdf, \.npy or \.exr"):
        hf.save(str(tmp_path / "h.tif"))


def test_cli_takes_a_measured_truth_file(tmp_path, rng, cli):
    # --heightfield of `render` with a NumPy file and its spacing.
    path = str(tmp_path / "s.npy")
    np.save(path, image(rng, 16, 16) * 0.01)
    out = str(tmp_path / "slice.exr")
    r = subprocess.run([cli, "render", "--heightfield", path, "--texel-um", "1", "--out", out, "--resolution", "8",
                        "--sigma-p-um", "3", "--quiet"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert os.path.exists(out)
    r = subprocess.run([cli, "render", "--heightfield", path, "--out", out, "--resolution", "8", "--quiet"],
                       capture_output=True, text=True)
    assert r.returncode != 0 and "states no spacing" in r.stderr
