"""What a new user trips over and what hostile input finds, from Python: each test names the trap."""
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

import wavebrdf as wb

SMALL = dict(resolution=8, sigma_p_um=1.5, x_um=3.0, y_um=3.0)


def rough(seed=0, shape=(12, 12)):
    return 0.4 * np.random.default_rng(seed).standard_normal(shape)


# --- a Heightfield's own scale -------------------------------------------------------------

def test_render_slice_of_a_heightfield_uses_its_scale():
    v = rough()
    hf = wb.Heightfield(v, texel_um=0.35, vscale=2.0)
    scaled = wb.render_slice(v, texel_um=0.35, vscale=2.0, **SMALL)
    unscaled = wb.render_slice(v, **SMALL)
    assert not np.allclose(scaled, unscaled)  # the scale matters for this surface
    np.testing.assert_array_equal(wb.render_slice(hf, **SMALL), scaled)
    w = np.random.default_rng(1).standard_normal((8, 8, 3))
    np.testing.assert_array_equal(wb.slice_gradient(hf, w, **SMALL),
                                  wb.slice_gradient(v, w, texel_um=0.35, vscale=2.0, **SMALL))
    # The same value again is allowed; a different one is refused, naming both.
    np.testing.assert_array_equal(wb.render_slice(hf, texel_um=0.35, **SMALL), scaled)
    with pytest.raises(ValueError, match=r"texel_um = 1 conflicts with the Heightfield's texel_um 0\.35"):
        wb.render_slice(hf, texel_um=1.0, **SMALL)
    with pytest.raises(ValueError, match=r"vscale = 1 conflicts with the Heightfield's vscale 2"):
        wb.slice_gradient(hf, w, vscale=1.0, **SMALL)


# --- batch axes -----------------------------------------------------------------------------

@pytest.mark.parametrize("shape", [(16, 16, 1), (3, 16, 1), (4, 1, 16)])
def test_a_trailing_singleton_axis_is_not_a_batch(shape):
    with pytest.raises(ValueError, match=r"read as a batch .*batch axes lead: \(\.\.\., rows, cols\)"):
        wb.render_slice(np.zeros(shape), resolution=8)
    with pytest.raises(ValueError, match=r"heights\[\.\.\., 0\]"):
        wb.slice_gradient(np.zeros(shape), np.zeros(shape[:-2] + (8, 8, 3)), resolution=8)


# An RGB(A) or two-channel export read with batch axes: (H, W, C) would be H surfaces W x C.
@pytest.mark.parametrize("shape", [(16, 16, 3), (16, 16, 4), (32, 24, 2), (2, 3, 16, 16, 3)])
def test_image_channels_are_not_a_batch_of_narrow_surfaces(shape):
    heights = rough(shape=shape)
    rows, cols = shape[-2:]
    message = (r"heights has shape \(%s\), read as a batch .* of %dx%d surfaces \(batch axes lead: "
               r"\(\.\.\., rows, cols\), the last two axes are one surface\).*pass heights\[\.\.\., 0\]"
               % (", ".join(str(e) for e in shape), rows, cols))
    with pytest.raises(ValueError, match=message):
        wb.render_slice(heights, resolution=8)
    # A footprint narrower than the channels does not let the image through either.
    with pytest.raises(ValueError, match=r"shaped as an image's colour channels"):
        wb.render_slice(heights, resolution=8, sigma_p_um=0.1)
    with pytest.raises(ValueError, match=message):
        wb.slice_gradient(heights, np.zeros(shape[:-2] + (8, 8, 3)), resolution=8)
    torch = pytest.importorskip("torch", reason="python3-torch is installed by scripts/setup.sh")
    import wavebrdf.torch as wt
    with pytest.raises(ValueError, match=message):
        wt.render_slice(torch.tensor(heights, requires_grad=True), resolution=8)


def test_a_batch_of_surfaces_narrower_than_the_footprint_is_refused():
    # Two 40 x 3 surfaces under a footprint of 6 sigma_p = 60 texels: the image-channel shape does
    # not apply (2 < 4 * 3), the footprint rule does.
    with pytest.raises(ValueError, match=r"a 40x3 surface is narrower than the footprint \(6 sigma_p = 60 um, "
                                         r"60 texels\) and 13 times longer than wide"):
        wb.render_slice(rough(shape=(2, 40, 3)), resolution=8, sigma_p_um=10.0)
    with pytest.raises(ValueError, match=r"a 3x40 surface is narrower than the footprint"):
        wb.render_slice(rough(shape=(2, 3, 40)), resolution=8, sigma_p_um=10.0)


def test_small_square_tiles_and_single_narrow_surfaces_still_render():
    # A periodic tile smaller than the footprint is valid: square tiles in a batch render.
    tiles = rough(shape=(5, 4, 4))
    out = wb.render_slice(tiles, resolution=8, sigma_p_um=10.0)
    assert out.shape == (5, 8, 8, 3)
    np.testing.assert_allclose(out[2], wb.render_slice(tiles[2], resolution=8, sigma_p_um=10.0), rtol=1e-9,
                               atol=1e-12 * out.max())
    # Narrow surfaces wider than the footprint, and a batch too short to be an image's rows.
    assert wb.render_slice(rough(shape=(2, 40, 3)), resolution=8, sigma_p_um=0.4).shape == (2, 8, 8, 3)
    assert wb.render_slice(rough(shape=(3, 12, 3)), resolution=8, sigma_p_um=0.4).shape == (3, 8, 8, 3)
    # One 2-D surface is never read as a batch, whatever its shape.
    assert wb.render_slice(rough(shape=(40, 3)), resolution=8, sigma_p_um=10.0).shape == (8, 8, 3)


def test_a_real_batch_still_renders():
    out = wb.render_slice(np.zeros((2, 6, 6)), resolution=8)
    assert out.shape == (2, 8, 8, 3)


# --- torch ------------------------------------------------------------------------------------

def _torch():
    return pytest.importorskip("torch", reason="python3-torch is installed by scripts/setup.sh")


def test_torch_light_that_requires_grad_is_refused():
    torch = _torch()
    import wavebrdf.torch as wt
    h = torch.tensor(rough(), requires_grad=True)
    light = torch.tensor([0.1, 0.2], dtype=torch.float64, requires_grad=True)
    with pytest.raises(ValueError, match=r"light requires grad.*only with respect to heights"):
        wt.render_slice(h, light=light, **SMALL)
    x = torch.tensor(3.0, dtype=torch.float64, requires_grad=True)
    with pytest.raises(ValueError, match=r"x_um requires grad"):
        wt.render_slice(h, **dict(SMALL, x_um=x))
    # Detached it renders as the NumPy function does.
    out = wt.render_slice(h, light=light.detach(), **SMALL)
    np.testing.assert_array_equal(out.detach().numpy(), wb.render_slice(rough(), light=(0.1, 0.2), **SMALL))


def test_torch_double_backward_says_it_is_not_supported():
    torch = _torch()
    import wavebrdf.torch as wt
    h = torch.tensor(rough(), requires_grad=True)
    loss = (wt.render_slice(h, **SMALL) ** 2).sum()
    (g,) = torch.autograd.grad(loss, h, create_graph=True)
    # The first derivative is the adjoint's, as without create_graph.
    (g0,) = torch.autograd.grad((wt.render_slice(h, **SMALL) ** 2).sum(), h)
    np.testing.assert_allclose(g.detach().numpy(), g0.numpy(), rtol=0, atol=0)
    with pytest.raises(RuntimeError, match=r"second derivatives \(double backward\) are not supported"):
        g.sum().backward()


def test_torch_sparse_and_meta_tensors_are_named():
    torch = _torch()
    import wavebrdf.torch as wt
    with pytest.raises(ValueError, match=r"heights is a sparse_coo tensor; expected a dense"):
        wt.render_slice(torch.zeros(6, 6, dtype=torch.float64).to_sparse(), **SMALL)
    with pytest.raises(ValueError, match=r"heights is on the meta device"):
        wt.render_slice(torch.zeros(6, 6, dtype=torch.float64, device="meta"), **SMALL)


# --- the report plotter on hostile or interrupted run directories ------------------------------

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def _report(d):
    env = dict(os.environ, PYTHONPATH=os.path.dirname(os.path.dirname(wb.__file__)), MPLBACKEND="Agg")
    return subprocess.run([sys.executable, "-m", "wavebrdf.report", str(d)], capture_output=True, text=True,
                          env=env, timeout=60)


RECOVER_HEADER = "stage,iteration,loss,seconds,height_rel_rmse,height_rel_rmse_plane_removed\n"
INVERT_HEADER = "epoch,loss,brdf_mse,cmsle_1,cmsle_0_001,rgb_mse,rgb_gamma_mse,height_mse,seconds\n"


@pytest.mark.parametrize("files", [
    {"metrics.csv": RECOVER_HEADER + "field,1,0.5,0.1,nan,nan\n"},                      # no run.json
    {"metrics.csv": "stage,loss\nfield,abc\n", "run.json": "{}"},                         # columns missing
    {"metrics.csv": RECOVER_HEADER + "field,1,0.5,0.1,nan,nan\nfield,2,0.", "run.json": "{\"size\": \"8x8\"}"},
    {"metrics.csv": INVERT_HEADER + "1,0.5", "run.json": "{\"texel_um\": \"wide\"}"},     # truncated, bad key
], ids=["recover-no-run-json", "recover-missing-columns", "recover-truncated", "invert-truncated"])
def test_report_of_a_hostile_directory_is_one_line_and_exit_2(tmp_path, files):
    pytest.importorskip("matplotlib")
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    r = _report(tmp_path)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("wavebrdf.report: error: "), r.stderr


def test_report_refuses_fifos_and_devices(tmp_path):
    os.mkfifo(tmp_path / "metrics.csv")
    r = _report(tmp_path)
    assert r.returncode == 2
    assert "metrics.csv is a FIFO, not a regular file" in r.stderr
    d = tmp_path / "zero"
    d.mkdir()
    (d / "run.json").write_text("{}")
    os.symlink("/dev/zero", d / "metrics.csv")
    r = _report(d)
    assert r.returncode == 2
    assert "metrics.csv is a character device" in r.stderr


def test_report_draws_at_most_twelve_snapshot_rows():
    from wavebrdf import report_invert
    epochs = list(range(300))
    drawn = report_invert._drawn_epochs(epochs)
    assert len(drawn) == report_invert.MAX_SNAPSHOT_ROWS == 12
    assert drawn[0] == 0 and drawn[-1] == 299 and drawn == sorted(set(drawn))
    assert report_invert._drawn_epochs([0, 5, 9]) == [0, 5, 9]


# --- Python habits: pathlib.Path and NumPy integers --------------------------------------------

def test_paths_may_be_pathlib(tmp_path):
    hf = wb.Heightfield(rough(), texel_um=0.5)
    hf.save_exr(tmp_path / "h.exr")
    back = wb.Heightfield.from_exr(tmp_path / "h.exr")
    np.testing.assert_array_equal(back.values, hf.values.astype(np.float32))  # EXR stores float32
    assert back.texel_um == 0.5
    assert wb.Heightfield.exr_attributes(tmp_path / "h.exr")["texel_um"] == 0.5
    obs = [wb.Observation(wb.Query(sigma_p_um=2.0), np.full((4, 4), 0.5))]
    wb.write_observations(tmp_path / "o.json", obs)
    read = wb.read_observations(tmp_path / "o.json")
    assert len(read) == 1
    assert len(wb.read_observation_index(tmp_path / "o.json")["queries"]) == 1


def test_numpy_integers_are_sizes():
    obs = [wb.Observation(wb.Query(sigma_p_um=2.0, x_um=float(k)), np.full((4, 4), 0.5)) for k in range(3)]
    b = wb.check_acquisition(obs, 8, 1.0)
    assert wb.check_acquisition(obs, np.int64(8), 1.0) == b
    assert wb.check_acquisition(obs, (np.int64(8), np.int32(8)), 1.0) == b
    with pytest.raises(ValueError, match="expected N or"):
        wb.check_acquisition(obs, True, 1.0)


def test_heightfield_files_are_written_in_the_format_their_name_says(tmp_path):
    hf = wb.Heightfield(np.zeros((4, 4)), texel_um=0.5)
    for save, wrong, expected in ((hf.save_exr, "h.png", ".exr"), (hf.save_png, "h.exr", ".png"),
                                  (hf.save_exr, "h.npy", ".exr")):
        with pytest.raises(ValueError, match=r"path .*%s.*expected a name ending in \%s" % (wrong, expected)):
            save(str(tmp_path / wrong))
        assert not (tmp_path / wrong).exists()
    # The extension's case does not matter, and what is written is what the name says.
    hf.save_exr(str(tmp_path / "h.EXR"))
    assert (tmp_path / "h.EXR").read_bytes()[:4] == b"\x76\x2f\x31\x01"  # OpenEXR's magic number
    hf.save_png(str(tmp_path / "h.png"))
    assert (tmp_path / "h.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
