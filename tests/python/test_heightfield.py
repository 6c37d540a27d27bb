"""Heightfield: NumPy in and out (views, no copies where none are needed), EXR files, the
generators, and errors."""
import copy
import subprocess
import warnings

import numpy as np
import pytest

import wavebrdf as wb


def test_from_numpy_and_back(rng):
    v = rng.normal(size=(5, 7))
    hf = wb.Heightfield(v, texel_um=0.5, vscale=2.0)
    assert hf.shape == (5, 7) and hf.rows == 5 and hf.cols == 7
    assert hf.texel_um == 0.5 and hf.vscale == 2.0
    assert hf.period_x_um == 2.5 and hf.period_y_um == 3.5
    np.testing.assert_array_equal(hf.values, v)
    np.testing.assert_array_equal(hf.to_numpy(), v)
    np.testing.assert_array_equal(np.asarray(hf), v)
    np.testing.assert_allclose(hf.heights_um(), 2.0 * 0.5 * v)
    # float32 input is widened exactly.
    v32 = v.astype(np.float32)
    np.testing.assert_array_equal(wb.Heightfield(v32).values, v32.astype(np.float64))
    # Slope by periodic central differences, times vscale (x along rows).
    sx, sy = hf.slope(0, 0)
    assert sx == pytest.approx(0.5 * 2.0 * (v[1, 0] - v[4, 0]))
    assert sy == pytest.approx(0.5 * 2.0 * (v[0, 1] - v[0, 6]))


def test_values_is_a_readonly_view_and_assignment_is_in_place(rng):
    hf = wb.Heightfield(rng.normal(size=(4, 4)))
    view = hf.values
    assert view.dtype == np.float64 and not view.flags.writeable
    assert not view.flags.owndata  # a view of the heightfield's memory, not a copy
    with pytest.raises(ValueError):
        view[0, 0] = 1.0
    new = rng.normal(size=(4, 4)).astype(np.float32)
    hf.values = new
    np.testing.assert_array_equal(view, new)  # the old view sees the new values
    copy_ = hf.to_numpy()
    copy_[0, 0] = 99.0
    assert hf.values[0, 0] != 99.0
    del hf  # the view keeps the heightfield alive
    np.testing.assert_array_equal(view, new)
    with pytest.raises(ValueError, match=r"values has shape \(3, 4\)"):
        h2 = wb.Heightfield(np.zeros((4, 4)))
        h2.values = np.zeros((3, 4))
    with pytest.raises(ValueError, match=r"values\[1, 2\]"):
        h3 = wb.Heightfield(np.zeros((4, 4)))
        bad = np.zeros((4, 4))
        bad[1, 2] = np.nan
        h3.values = bad
    np.testing.assert_array_equal(h3.values, 0.0)  # unchanged after a rejected assignment


def test_copies_are_independent(rng):
    hf = wb.Heightfield(rng.normal(size=(3, 3)))
    for other in (hf.copy(), copy.copy(hf), copy.deepcopy(hf), hf.with_values(hf.values)):
        other.values = np.zeros((3, 3))
        assert hf.values.any()
    scaled = hf.with_scale(2.0, 0.5)
    assert scaled.texel_um == 2.0 and scaled.vscale == 0.5
    np.testing.assert_array_equal(scaled.values, hf.values)


@pytest.mark.parametrize("args,kwargs,message", [
    ((np.zeros(4),), {}, "values has shape (4,)"),
    ((np.zeros((0, 3)),), {}, "values has shape (0, 3)"),
    ((np.zeros((2, 2, 2)),), {}, "values has shape"),
    ((np.zeros((2, 2), dtype=np.int32),), {}, "values has dtype int32"),
    ((np.zeros((2, 2), dtype=np.complex128),), {}, "values has dtype complex128"),
    ((np.zeros((2, 2), dtype=">f8"),), {}, "values has dtype >f8"),
    ((np.array([[0.0, np.nan]]),), {}, "values[0, 1]"),
    ((np.zeros((2, 2)),), {"texel_um": 0.0}, "texel_um"),
    ((np.zeros((2, 2)),), {"texel_um": -1.0}, "texel_um"),
    ((np.zeros((2, 2)),), {"vscale": np.inf}, "vscale"),
    ((None,), {}, "values"),
])
def test_errors(args, kwargs, message):
    with pytest.raises(ValueError) as e:
        wb.Heightfield(*args, **kwargs)
    assert message in str(e.value)


def test_exr_round_trip(tmp_path, rng):
    v = rng.normal(size=(6, 9)).astype(np.float32)  # EXR stores float
    hf = wb.Heightfield(v)
    path = str(tmp_path / "h.exr")
    hf.save_exr(path)
    # Given values that differ from the file's (1, 1) win, with a warning naming both.
    with pytest.warns(UserWarning, match="texel_um 0.25 disagrees"):
        back = wb.Heightfield.from_exr(path, texel_um=0.25, vscale=3.0)
    assert back.shape == (6, 9) and back.texel_um == 0.25 and back.vscale == 3.0
    np.testing.assert_array_equal(back.values, v)
    hf.save_png(str(tmp_path / "h.png"))
    assert (tmp_path / "h.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_exr_errors(tmp_path):
    with pytest.raises(RuntimeError, match="missing.exr"):
        wb.Heightfield.from_exr(str(tmp_path / "missing.exr"))
    (tmp_path / "bad.exr").write_bytes(b"not an exr file")
    with pytest.raises(RuntimeError, match="bad.exr"):
        wb.Heightfield.from_exr(str(tmp_path / "bad.exr"))
    with pytest.raises(ValueError, match="texel_um"):
        wb.Heightfield.from_exr(str(tmp_path / "bad.exr"), texel_um=0)
    with pytest.raises(RuntimeError):
        wb.Heightfield(np.zeros((2, 2))).save_exr(str(tmp_path / "no" / "such" / "dir.exr"))


def test_generate_matches_the_cli(tmp_path, cli):
    hf = wb.Heightfield.generate("isotropic", rows=32, cols=24, texel_um=0.5, rms_height_um=0.2,
                                 correlation_um=2.0, seed=7)
    assert hf.shape == (32, 24) and hf.texel_um == 0.5 and hf.vscale == 1.0
    # The requested rms height is realised exactly (the generator rescales): an independent check.
    heights = hf.heights_um()
    assert np.sqrt(np.mean((heights - heights.mean()) ** 2)) == pytest.approx(0.2, rel=1e-9)
    assert hf.stats()["rms_height_um"] == pytest.approx(0.2, rel=1e-9)
    exr = tmp_path / "g.exr"
    subprocess.run([cli, "heightfield", "--type", "isotropic", "--size", "32x24", "--texel-um", "0.5",
                    "--rms-height-um", "0.2", "--correlation-um", "2", "--seed", "7", "--no-png", "--quiet",
                    "--out", str(exr)], check=True)
    from_cli = wb.Heightfield.from_exr(str(exr))
    assert from_cli.texel_um == 0.5  # the file's own
    np.testing.assert_allclose(from_cli.values, hf.values, rtol=1e-6, atol=1e-6 * np.abs(hf.values).max())
    grating = wb.Heightfield.generate("grating", rows=16, cols=4, amplitude_um=0.1, period_um=8.0)
    x = (np.arange(16) + 0.5) * 1.0
    np.testing.assert_allclose(grating.heights_um()[:, 2], 0.1 * np.sin(2 * np.pi * x / 8.0), atol=1e-12)
    with pytest.raises(ValueError, match="'wavy'"):
        wb.Heightfield.generate("wavy")
    with pytest.raises(ValueError):
        wb.Heightfield.generate("isotropic", rows=0)


# Issue 11: `wavebrdf heightfield --texel-um 0.5`, then from_exr, gave texel_um 1.0 (a silent
# 2x error). The file now says 0.5, and from_exr uses it; a disagreeing value wins with a warning.
def test_from_exr_reads_the_texel_size_the_cli_wrote(tmp_path, cli):
    exr = tmp_path / "g.exr"
    subprocess.run([cli, "heightfield", "--size", "32", "--texel-um", "0.5", "--seed", "3", "--no-png", "--quiet",
                    "--out", str(exr)], check=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no option given: nothing to warn about
        hf = wb.Heightfield.from_exr(str(exr))
        assert wb.Heightfield.from_exr(str(exr), texel_um=0.5).texel_um == 0.5  # agrees: no warning
    assert hf.texel_um == 0.5 and hf.vscale == 1.0
    info = wb.Heightfield.exr_attributes(str(exr))
    assert info["texel_um"] == 0.5 and info["vscale"] == 1.0
    assert "seed=3" in info["made_by"] and info["version"] == wb.__version__
    assert "texel_um" in info["units"]
    with pytest.warns(UserWarning) as record:
        hf1 = wb.Heightfield.from_exr(str(exr), texel_um=1.0)
    assert hf1.texel_um == 1.0
    assert len(record) == 1
    assert str(record[0].message) == "texel_um 1 disagrees with %s's texel_um 0.5; using 1" % exr


@pytest.mark.parametrize("texel_um, vscale", [(0.37, 1.0), (2.5, -0.5), (0.5, 0.0), (1e-4, 1e4)])
def test_save_exr_from_exr_round_trip_keeps_the_scale(tmp_path, rng, texel_um, vscale):
    v = rng.normal(size=(5, 7)).astype(np.float32)
    path = str(tmp_path / "h.exr")
    wb.Heightfield(v, texel_um=texel_um, vscale=vscale).save_exr(path)
    back = wb.Heightfield.from_exr(path)
    assert back.texel_um == texel_um and back.vscale == vscale
    np.testing.assert_array_equal(back.values, v)
    info = wb.Heightfield.exr_attributes(path)
    assert info["made_by"] == "python" and info["texel_um"] == texel_um


# A slice the CLI rendered says which query rendered it: rendering that query again from Python
# gives the same slice, and the unit is f_r in 1/sr.
def test_read_slice_returns_the_query_that_rendered_it(tmp_path, cli):
    hf_path = tmp_path / "g.exr"
    subprocess.run([cli, "heightfield", "--size", "32", "--texel-um", "0.5", "--rms-height-um", "0.05",
                    "--no-png", "--quiet", "--out", str(hf_path)], check=True)
    out = tmp_path / "s.exr"
    subprocess.run([cli, "render", "--heightfield", str(hf_path), "--x-um", "3", "--y-um", "-2", "--sigma-p-um", "4",
                    "--light-x", "0.2", "--light-y", "-0.1", "--spectral", "3", "--model", "GHS",
                    "--resolution", "24", "--quiet", "--out", str(out)], check=True)
    image, info = wb.read_slice(str(out))
    assert image.shape == (24, 24, 3) and image.dtype == np.float32
    assert info["x_um"] == 3.0 and info["y_um"] == -2.0 and info["sigma_p_um"] == 4.0
    assert info["light"] == (0.2, -0.1) and info["model"] == "GHS"
    assert info["lambdas_um"] == list(wb.spectral_wavelengths_um(3))
    assert info["resolution"] == 24 and info["channels"] == 3
    assert info["texel_um"] == 0.5 and info["vscale"] == 1.0 and info["heightfield_size"] == (32, 32)
    assert info["heightfield_file"] == str(hf_path)
    assert info["unit"].startswith("f_r (BRDF) in 1/sr")
    assert info["version"] == wb.__version__ and info["made_by"] == "wavebrdf render"
    hf = wb.Heightfield.from_exr(info["heightfield_file"])
    again = wb.render_slice(hf.values.astype(np.float32), resolution=info["resolution"], texel_um=info["texel_um"],
                            vscale=info["vscale"], x_um=info["x_um"], y_um=info["y_um"],
                            sigma_p_um=info["sigma_p_um"], spectral=info["lambdas_um"], light=info["light"],
                            model=info["model"])
    np.testing.assert_allclose(again, image, rtol=1e-5, atol=1e-6 * float(np.abs(image).max()))


def test_version_is_the_one_in_the_file_version():
    import pathlib
    version = (pathlib.Path(__file__).resolve().parents[2] / "VERSION").read_text().strip()
    assert wb.__version__ == version
