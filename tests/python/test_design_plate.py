"""wavebrdf.design_plate: the same plate as the CLI from the same seed, a picture given as an
array, and ValueErrors for bad input."""
import json
import subprocess

import numpy as np
import pytest

import wavebrdf as wb

GREEN, MAGENTA = (0, 255, 0), (255, 0, 255)
PICTURE = np.array([[GREEN, MAGENTA], [MAGENTA, GREEN]], dtype=np.uint8)
SMALL = dict(palette="#00FF00;#FF00FF", size=8, spectral=3, levels=4, height_range_um=1.0, iterations=6,
             refine_passes=2, seed=5, plate_pixel_um=8.0)


def write_png(path, rgb):
    """A minimal 8-bit RGB PNG, written here (not by wavebrdf)."""
    import struct
    import zlib
    rows, cols, _ = rgb.shape
    raw = b"".join(b"\x00" + rgb[i].tobytes() for i in range(rows))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", cols, rows, 8, 2, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def test_cli_and_python_give_the_same_plate(cli, tmp_path):
    r = wb.design_plate(PICTURE, **SMALL)
    assert r["heights_um"].shape == (32, 32)
    assert r["assignment"].tolist() == [[0, 1], [1, 0]]
    assert r["appearance"].shape == (1, 2, 2, 3)
    write_png(tmp_path / "pic.png", PICTURE)
    out = tmp_path / "run"
    subprocess.run([cli, "design", "--target", "image:" + str(tmp_path / "pic.png"), "--palette", "#00FF00;#FF00FF",
                    "--size", "8", "--spectral", "3", "--levels", "4", "--height-range-um", "1", "--iterations", "6",
                    "--refine-passes", "2", "--seed", "5", "--plate-pixel-um", "8", "--out", str(out), "--quiet"],
                   check=True)
    hf = wb.Heightfield.from_exr(str(out / "heights.exr"))
    heights = np.asarray(hf.values) * hf.texel_um * hf.vscale
    np.testing.assert_allclose(heights.reshape(32, 32), r["heights_um"], atol=1e-6)
    doc = json.loads((out / "design.json").read_text())
    assert doc["target"]["kind"] == "image"
    np.testing.assert_allclose([e["views"][0]["uv"] for e in doc["entries"]],
                               [e["views"][0]["uv"] for e in r["design"]["entries"]], rtol=1e-12)
    # The Python call with out= writes the same directory.
    wb.design_plate(str(tmp_path / "pic.png"), out=tmp_path / "py", **SMALL)
    assert (tmp_path / "py" / "plate.png").is_file()


def test_bad_input_is_a_value_error_before_any_work(tmp_path):
    with pytest.raises(ValueError, match="palette"):
        wb.design_plate(PICTURE, palette="#00FF00", size=8, spectral=3)
    with pytest.raises(ValueError, match="picture"):
        wb.design_plate(PICTURE.astype(np.float64), palette="#00FF00;#FF00FF", size=8, spectral=3)
    with pytest.raises(ValueError, match="picture"):
        wb.design_plate(np.zeros((2, 2), dtype=np.uint8), palette="#00FF00;#FF00FF", size=8, spectral=3)
    with pytest.raises(ValueError, match="plate-pixel-um"):
        wb.design_plate(PICTURE, palette="#00FF00;#FF00FF", size=8, spectral=3, plate_pixel_um=5.0)
    with pytest.raises(ValueError, match="missing.png"):
        wb.design_plate(str(tmp_path / "missing.png"), palette="#00FF00;#FF00FF", size=8, spectral=3)
    assert not list(tmp_path.iterdir())
