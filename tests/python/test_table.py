"""BRDF tables: wb.render_table entries equal wb.render of that light, the file written by
`wavebrdf table` reads back with every axis, the specular peak follows the light, and bad
files and arguments are refused."""
import subprocess

import numpy as np
import pytest

import wavebrdf as wb


def surface(rng, n=24):
    return wb.Heightfield(rng.normal(0.0, 0.3, (n, n)), texel_um=0.5)


def test_entries_are_the_lights_slices(rng, tmp_path):
    hf = surface(rng)
    q = wb.Query(x_um=3.0, y_um=4.0, sigma_p_um=3.0, spectral=3)
    out = tmp_path / "t.exr"
    t = wb.render_table(hf, q, lights=(3, 4), max_light_sin=0.8, resolution=12, out=out)
    assert t.values.shape == (3, 4, 12, 12, 3) and t.values.dtype == np.float32
    assert t.light_x.shape == (3,) and t.light_y.shape == (4,) and t.rendered.shape == (3, 4)
    np.testing.assert_array_equal(t.light_x, 0.8 * ((np.arange(3) + 0.5) / 3 * 2 - 1))
    np.testing.assert_array_equal(t.omega_o, (np.arange(12) + 0.5) / 12 * 2 - 1)
    for a in range(3):
        for b in range(4):
            if not t.rendered[a, b]:
                assert not t.values[a, b].any()
                continue
            q.light = t.light(a, b)
            alone = wb.render(hf, q, 12, precision="float")
            np.testing.assert_array_equal(t.values[a, b], alone)
    # The file holds the same table with all its axes.
    r = wb.read_table(out)
    np.testing.assert_array_equal(r.values, t.values)
    np.testing.assert_array_equal(r.light_x, t.light_x)
    np.testing.assert_array_equal(r.light_y, t.light_y)
    np.testing.assert_array_equal(r.rendered, t.rendered)
    assert r.max_light_sin == 0.8 and r.resolution == 12 and r.spectral
    assert r.lambdas_um == q.lambdas_um and r.query.sigma_p_um == 3.0 and r.query.x_um == 3.0
    assert r.texel_um == 0.5 and r.vscale == 1.0 and r.heightfield_size == (24, 24)
    assert r.version == wb.__version__ and r.precision == "float"
    assert "3x4 lights" in repr(r)


def test_cli_table_reads_back_and_peaks_follow_the_light(cli, tmp_path):
    # A flat mirror: each entry's brightest pixel at omega_o = -omega_i (docs/conventions.md).
    subprocess.run([cli, "heightfield", "--type", "flat", "--size", "64", "--out", "flat.exr", "--no-png",
                    "--quiet"], cwd=tmp_path, check=True)
    r = subprocess.run([cli, "table", "--heightfield", "flat.exr", "--sigma-p-um", "2", "--x-um", "10",
                        "--lights", "4x5", "--max-light-sin", "0.7", "--resolution", "40", "--out", "t.exr",
                        "--quiet"], cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    t = wb.read_table(tmp_path / "t.exr")
    assert t.values.shape == (4, 5, 40, 40, 3) and t.query.model == "OHS" and t.lambdas_um == [0.5]
    checked = 0
    for a in range(4):
        for b in range(5):
            if not t.rendered[a, b]:
                continue
            p, q = np.unravel_index(np.argmax(t.values[a, b, :, :, 0]), (40, 40))
            assert abs(t.omega_o[p] + t.light_x[a]) <= 1.5 / 40
            assert abs(t.omega_o[q] + t.light_y[b]) <= 1.5 / 40
            checked += 1
    assert checked >= 12


def test_refuses_files_that_are_not_tables(cli, tmp_path):
    subprocess.run([cli, "heightfield", "--size", "16", "--out", "h.exr", "--no-png", "--quiet"], cwd=tmp_path,
                   check=True)
    # Its attributes are read first (before any pixel): a heightfield says what it is.
    with pytest.raises(RuntimeError, match="h.exr: attribute wavebrdf:kind is 'heightfield'"):
        wb.read_table(tmp_path / "h.exr")
    with pytest.raises(RuntimeError, match="does not exist"):
        wb.read_table(tmp_path / "missing.exr")


def test_bad_arguments(rng):
    hf = surface(rng, 8)
    q = wb.Query(sigma_p_um=2.0)
    with pytest.raises(ValueError, match="max sin theta 1"):
        wb.render_table(hf, q, lights=2, max_light_sin=1.0, resolution=4)
    with pytest.raises(ValueError, match="lights"):
        wb.render_table(hf, q, lights=(0, 2), resolution=4)
    with pytest.raises(ValueError, match="precision"):
        wb.render_table(hf, q, lights=2, resolution=4, precision="half")
    with pytest.raises(MemoryError, match="table"):
        wb.render_table(hf, q, lights=32, resolution=512, max_memory_gb=0.01)


def test_render_table_of_a_file_uses_its_texel_size(cli, tmp_path):
    subprocess.run([cli, "heightfield", "--size", "32", "--texel-um", "0.5", "--out", "h.exr", "--no-png",
                    "--quiet"], cwd=tmp_path, check=True)
    q = wb.Query(sigma_p_um=3.0)
    assert wb.render_table(str(tmp_path / "h.exr"), q, lights=(2, 2), resolution=8).texel_um == 0.5
    assert wb.render_table(tmp_path / "h.exr", q, lights=(2, 2), resolution=8).texel_um == 0.5
