"""wavebrdf.write_fabrication_exports (docs/fabrication.md), read back with readers of its own:
Pillow for the PNGs (16-bit grey and 1-bit masks), NumPy for the binary STL."""
import json
import os

import numpy as np
import pytest

import wavebrdf as wb

Image = pytest.importorskip("PIL.Image")


def read_stl(path):
    data = open(path, "rb").read()
    n = int.from_bytes(data[80:84], "little")
    assert len(data) == 84 + 50 * n
    rec = np.frombuffer(data[84:], dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]), count=n)
    return rec["n"].astype(np.float64), rec["v"].astype(np.float64)


def test_exports_read_back(tmp_path):
    rows, cols, levels, height_um = 12, 9, 5, 1.6
    step = height_um / (levels - 1)
    k = np.random.default_rng(4).integers(0, levels, size=(rows, cols))
    h = k * step
    files = wb.write_fabrication_exports(str(tmp_path), h, texel_um=0.5, height_range_um=height_um, levels=levels)

    im = Image.open(files["heights_png"])
    assert im.size == (cols, rows)
    assert float(im.info["wavebrdf:height_range_um"]) == height_um
    grey = np.asarray(im, dtype=np.float64)
    np.testing.assert_allclose(grey / 65535 * height_um, h, atol=0.5 * height_um / 65535)

    # 5 levels: 4 cumulative masks; the relief is the top minus the exposed depths.
    meta = json.load(open(files["masks_json"]))
    assert len(meta["masks"]) == levels - 1 == len(files["masks"])
    etched = np.zeros((rows, cols))
    for m in meta["masks"]:
        mask = np.asarray(Image.open(os.path.join(tmp_path, m["file"])).convert("L")) > 0
        etched += mask * m["depth_um"]
    np.testing.assert_allclose(height_um - etched, h, atol=1e-12)

    normals, v = read_stl(files["heights_stl"])
    assert len(v) == files["stl_triangles"]
    cross = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    np.testing.assert_allclose(normals, cross / np.linalg.norm(cross, axis=1)[:, None], atol=1e-6)
    volume = np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6
    base = max(height_um, 0.5)  # the exports' base thickness: max(height range, texel)
    np.testing.assert_allclose(volume, (0.5 ** 2 * (h + base)).sum(), rtol=1e-5)


def test_bad_inputs_raise(tmp_path):
    with pytest.raises(ValueError, match="2-D"):
        wb.write_fabrication_exports(str(tmp_path), np.zeros(5), 0.5, 1.0)
    h = np.full((3, 3), 0.5)
    h[2, 1] = 1.5
    with pytest.raises(ValueError, match=r"texel \(2, 1\)"):
        wb.write_fabrication_exports(str(tmp_path), h, 0.5, 1.0)
    with pytest.raises(ValueError, match="levels"):
        wb.write_fabrication_exports(str(tmp_path), np.zeros((3, 3)), 0.5, 1.0, levels=1)
    assert os.listdir(tmp_path) == []


def test_exports_hold_an_x3p_with_the_same_heights(tmp_path):
    # heights.x3p read back by the surface reader (the x3p plugin; rows along y there, transposed
    # back to the heightfield's rows along x by Heightfield.read).
    rng = np.random.default_rng(4)
    heights = rng.integers(0, 4, size=(6, 9)) * 0.5
    files = wb.write_fabrication_exports(str(tmp_path), heights, texel_um=0.25, height_range_um=1.5, levels=4)
    assert files["heights_x3p"] == str(tmp_path / "heights.x3p") and files["x3p_note"] == ""
    hf = wb.Heightfield.read(files["heights_x3p"])
    back = np.asarray(hf.values) * hf.texel_um * hf.vscale
    np.testing.assert_allclose(back.reshape(6, 9), heights, atol=1e-12)
    assert hf.texel_um == pytest.approx(0.25)
