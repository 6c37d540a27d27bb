"""Traps a new user still found from Python: the amplitude loss's gradient outside the unit disk,
paths as pathlib.Path in every function that takes a file, NumPy integers as sizes."""
import pathlib

import numpy as np
import pytest

import wavebrdf as wb

N = 16
OPTS = dict(resolution=N, sigma_p_um=2.0, x_um=5.0, y_um=5.0, lambda_um=0.5)


def inside_disk(n):
    """Pixels with |omega_o| <= 1, omega_o = ((i + 1/2) / n * 2 - 1, ...): the rendered ones."""
    w = (np.arange(n) + 0.5) / n * 2 - 1
    return w[:, None] ** 2 + w[None, :] ** 2 <= 1


def heights(seed):
    return 0.3 * np.random.default_rng(seed).standard_normal((10, 10))


def amplitude_loss(h, reference):
    """sum over the disk of (sqrt(I) - sqrt(R))^2, from render_slice alone."""
    inside = inside_disk(N)
    slice_ = wb.render_slice(h, **OPTS)
    return np.sum((np.sqrt(slice_[inside]) - np.sqrt(reference[inside])) ** 2)


def test_amplitude_loss_gradient_outside_the_disk_is_ignored():
    h, reference = heights(0), wb.render_slice(heights(1), **OPTS)
    slice_ = wb.render_slice(h, **OPTS)
    assert np.all(slice_[~inside_disk(N)] == 0) and np.all(slice_[inside_disk(N)] > 0)
    # dL/dI of (sqrt(I) - sqrt(R))^2 as a user writes it: inf or NaN where I = 0 (outside the disk).
    with np.errstate(divide="ignore", invalid="ignore"):
        weights = (np.sqrt(slice_) - np.sqrt(reference)) / np.sqrt(slice_)
    assert not np.all(np.isfinite(weights))
    assert np.all(np.isfinite(weights[inside_disk(N)]))
    gradient = wb.slice_gradient(h, weights, **OPTS)
    # Finite differences of the loss (evidence independent of the adjoint).
    step = 1e-5
    for i, j in [(0, 0), (4, 7), (9, 2)]:
        e = np.zeros_like(h)
        e[i, j] = step
        fd = (amplitude_loss(h + e, reference) - amplitude_loss(h - e, reference)) / (2 * step)
        assert gradient[i, j] == pytest.approx(fd, rel=1e-5, abs=1e-12 * max(1.0, abs(fd)))
    # The same through a batch, and inside the disk a non-finite weight is still refused by index.
    batch = wb.slice_gradient(np.stack([h, h]), np.stack([weights, weights]), **OPTS)
    np.testing.assert_array_equal(batch[1], gradient)
    bad = np.where(np.isfinite(weights), weights, 0.0)
    bad[N // 2, N // 2, 1] = np.inf
    with pytest.raises(ValueError, match=rf"weights\[{N // 2}, {N // 2}, 1\] = inf .*inside the unit disk"):
        wb.slice_gradient(h, bad, **OPTS)


def test_torch_amplitude_loss_backward_ignores_the_outside_of_the_disk():
    torch = pytest.importorskip("torch", reason="python3-torch is installed by scripts/setup.sh")
    import wavebrdf.torch as wt
    h, reference = heights(0), wb.render_slice(heights(1), **OPTS)
    x = torch.tensor(h, requires_grad=True)
    slice_ = wt.render_slice(x, **OPTS)
    loss = ((torch.sqrt(slice_) - torch.sqrt(torch.tensor(reference))) ** 2).sum()
    loss.backward()  # torch's sqrt backward gives NaN at I = 0, outside the disk
    with np.errstate(divide="ignore", invalid="ignore"):
        s = wb.render_slice(h, **OPTS)
        weights = (np.sqrt(s) - np.sqrt(reference)) / np.sqrt(s)
    np.testing.assert_allclose(x.grad.numpy(), wb.slice_gradient(h, weights, **OPTS), rtol=1e-12, atol=1e-15)


def test_paths_may_be_pathlib_wherever_a_file_is_given(tmp_path):
    hf = wb.Heightfield(heights(2), texel_um=0.5)
    hf.save(tmp_path / "h.exr")
    back = wb.Heightfield.read(tmp_path / "h.exr")
    assert back.texel_um == 0.5
    hf.save(tmp_path / "h.npy")
    assert (tmp_path / "h.npy").is_file()
    out = tmp_path / "fab"
    out.mkdir()
    files = wb.write_fabrication_exports(out, np.where(heights(3) > 0, 2.0, 0.0), 1.0, 2.0, 2)
    assert pathlib.Path(files["heights_png"]).is_file()
    from wavebrdf.table import read_table, render_table
    render_table(tmp_path / "h.exr", wb.Query(sigma_p_um=2.0), lights=(2, 2), resolution=4, out=tmp_path / "t.exr")
    assert read_table(tmp_path / "t.exr").values.shape[:2] == (2, 2)
    result = wb.invert(truth=tmp_path / "h.exr", epochs=1, resolution=8, sigma_p_um=2.0, quiet=True)
    assert np.asarray(result.estimate).shape == (10, 10)


def test_numpy_integers_are_sizes_in_the_main_calls():
    h = heights(4)
    plain = wb.render_slice(h, **OPTS)
    np.testing.assert_array_equal(wb.render_slice(h, **dict(OPTS, resolution=np.int64(N))), plain)
    np.testing.assert_array_equal(wb.render_slice(h, **dict(OPTS, resolution=np.int32(N))), plain)
    np.testing.assert_array_equal(
        wb.render_slice(h, **dict(OPTS, resolution=np.int64(N), spectral=np.int64(3), lambda_um=None)),
        wb.render_slice(h, **dict(OPTS, spectral=3, lambda_um=None)))


MPI_SCRIPT = r"""
import json, sys
import numpy as np
from mpi4py import MPI
import wavebrdf as wb

comm = MPI.COMM_WORLD
rank = comm.Get_rank()
h = 0.3 * np.random.default_rng(7).standard_normal((10, 10))
out = {}
for case in ("nan_on_one_rank", "batch_shapes_differ", "heights_differ"):
    heights = h
    if case == "nan_on_one_rank" and rank == 1:
        heights = h.copy(); heights[3, 4] = np.nan
    lights = np.zeros((4 if case == "batch_shapes_differ" and rank == 1 else 3, 2))
    if case == "heights_differ" and rank == 1:
        heights = h + 0.1
    try:
        wb.render_slice(heights, resolution=8, sigma_p_um=2.0, light=lights, comm=comm)
        out[case] = "ran"
    except Exception as e:  # every rank must get here, none may hang
        out[case] = type(e).__name__ + ": " + str(e)
reports = comm.gather(out, root=0)
if rank == 0:
    print(json.dumps(reports))
"""


def test_render_slice_over_ranks_stops_every_rank_when_one_fails_or_they_disagree():
    import json
    import os
    import shutil
    import subprocess
    from conftest import BUILD, INSTALLED
    mpiexec = shutil.which("mpiexec") or "/usr/bin/mpiexec"
    if not os.path.exists(mpiexec):
        pytest.skip("no mpiexec")
    pytest.importorskip("mpi4py", reason="python3-mpi4py is installed by scripts/setup.sh")
    env = dict(os.environ)
    env.update({"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1", "OMP_NUM_THREADS": "1",
                "ASAN_OPTIONS": "detect_leaks=0"})
    if not INSTALLED:
        env["PYTHONPATH"] = os.path.join(BUILD, "python") + os.pathsep + env.get("PYTHONPATH", "")
    args = [mpiexec, "-n", "2", "--oversubscribe", "--bind-to", "none", "/usr/bin/python3", "-c", MPI_SCRIPT]
    # A hang fails (TimeoutExpired) instead of blocking the suite.
    r = subprocess.run(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    reports = json.loads(r.stdout.strip().splitlines()[-1])
    if any("without MPI" in v for v in reports[0].values()):
        pytest.skip("wavebrdf built without MPI")
    for report in reports:
        assert "heights" in report["nan_on_one_rank"] and "not finite" in report["nan_on_one_rank"], report
        assert "different" in report["batch_shapes_differ"], report
        assert "different" in report["heights_differ"], report
