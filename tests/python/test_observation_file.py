"""HDF5 observation files from Python (docs/observations_hdf5.md): write_observations / read_observations
dispatch on the extension; the round trip is exact but for the slices' rounding to float32 (checked
against NumPy's own rounding); indices read a subset; the shares of 1..4 ranks partition a file;
read_observation_index gives the queries without the slices; bad files raise one-line errors."""
import ast
import os

import numpy as np
import pytest

import wavebrdf as wb

pytestmark = pytest.mark.skipif(not wb.built_with_hdf5(), reason="built without HDF5")


def make_observations(rng, count, spectral, n=6):
    out = []
    models = ["OHS", "GHS", "ROHS", "RGHS", "Kirchhoff"]
    for i in range(count):
        position = i % 3
        q = wb.Query(x_um=1.5 + 2.25 * position, y_um=-0.75 * position, sigma_p_um=2.0 + 0.1 * i,
                     light=(0.1 * rng.random(), -0.05), model=models[i % 5],
                     spectral=spectral, lambda_um=None if spectral else 0.4 + 0.05 * i)
        shape = (n, n, 3) if spectral else (n, n)
        out.append(wb.Observation(q, np.exp(rng.normal(size=shape))))
    return out


@pytest.mark.parametrize("spectral", [None, 8], ids=["mono", "spectral"])
def test_round_trip_exact_in_float32(tmp_path, rng, spectral):
    written = make_observations(rng, 7, spectral)
    path = str(tmp_path / "obs.h5")
    wb.write_observations(path, written)
    read = wb.read_observations(path)
    assert len(read) == len(written)
    for r, w in zip(read, written):
        assert r.query.x_um == w.query.x_um and r.query.y_um == w.query.y_um
        assert r.query.sigma_p_um == w.query.sigma_p_um and r.query.light == w.query.light
        assert r.query.model == w.query.model and r.lambdas_um == w.lambdas_um
        assert r.resolution == w.resolution and r.channels == w.channels
        np.testing.assert_array_equal(r.reference, w.reference.astype(np.float32).astype(np.float64))
    index = wb.read_observation_index(path)
    assert index["resolution"] == 6 and index["channels"] == (3 if spectral else 1)
    assert [q.lambdas_um for q in index["queries"]] == [w.lambdas_um for w in written]
    np.testing.assert_array_equal(index["positions_um"], [[w.query.x_um, w.query.y_um] for w in written])


def test_subsets_and_rank_shares(tmp_path, rng):
    written = make_observations(rng, 10, None)
    h5, js = str(tmp_path / "o.hdf5"), str(tmp_path / "o.json")
    wb.write_observations(h5, written)
    wb.write_observations(js, wb.read_observations(h5))  # the same (float-rounded) values as JSON
    full = wb.read_observations(h5)
    for indices in ([9, 0, 4, 4], []):
        part = wb.read_observations(h5, indices)
        assert [p.query.x_um for p in part] == [full[i].query.x_um for i in indices]
        for p, i in zip(part, indices):
            np.testing.assert_array_equal(p.reference, full[i].reference)
        assert [p.query.x_um for p in wb.read_observations(js, indices)] == [full[i].query.x_um for i in indices]
    with pytest.raises(IndexError, match="out of range"):
        wb.read_observations(h5, [10])
    for size in range(1, 5):
        seen = []
        for rank in range(size):
            share = wb.read_observations(h5, rank=rank, size=size)
            from_json = wb.read_observations(js, rank=rank, size=size)
            assert [o.query.x_um for o in share] == [o.query.x_um for o in from_json]
            seen += [o.query.sigma_p_um for o in share]  # distinct per observation here
        assert sorted(seen) == sorted(o.query.sigma_p_um for o in full)


def test_bad_files_raise_one_line(tmp_path, rng):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not an hdf5 file")
    with pytest.raises(RuntimeError, match="bad.h5") as e:
        wb.read_observations(str(bad))
    assert "\n" not in str(e.value)
    good = str(tmp_path / "good.h5")
    wb.write_observations(good, make_observations(rng, 3, 4))
    cut = tmp_path / "cut.h5"
    cut.write_bytes(open(good, "rb").read()[: os.path.getsize(good) // 2])
    with pytest.raises(RuntimeError, match="cut.h5"):
        wb.read_observations(str(cut))
    mixed = make_observations(rng, 2, None) + make_observations(rng, 1, None, n=5)
    with pytest.raises(ValueError, match="one resolution"):
        wb.write_observations(str(tmp_path / "mixed.h5"), mixed)
    assert not os.path.exists(tmp_path / "mixed.h5")
    with pytest.raises(ValueError, match="exclude"):
        wb.read_observations(good, [0], rank=0, size=2)


def test_cli_reads_what_python_wrote(tmp_path, rng, cli):
    import subprocess
    truth = wb.Heightfield(rng.normal(0, 0.02, (8, 8)), texel_um=2.0)
    obs = [wb.Observation(q, wb.render(truth, q, 12)[..., 0])
           for q in (wb.Query(x_um=x, y_um=y, sigma_p_um=3.0, lambda_um=0.5) for x in (4.0, 12.0) for y in (4.0, 12.0))]
    wb.write_observations(str(tmp_path / "o.h5"), obs)
    r = subprocess.run([cli, "invert", "--observations", "o.h5", "--size", "8", "--epochs", "2", "--out", "run",
                        "--no-plots", "--quiet"], cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert os.path.exists(tmp_path / "run" / "estimate.exr")


MPI_SCRIPT = r"""
import sys
import numpy as np
from mpi4py import MPI
import wavebrdf as wb
comm = MPI.COMM_WORLD
path = sys.argv[1]
share = wb.read_observations(path, rank=comm.Get_rank(), size=comm.Get_size())
rows = [(o.query.x_um, o.query.y_um, o.query.sigma_p_um, float(np.sum(o.reference))) for o in share]
everything = comm.gather(rows, root=0)
if comm.Get_rank() == 0:
    with open(sys.argv[2], "w") as out:
        out.write(repr([sorted(r) for r in everything]))
"""


@pytest.mark.parametrize("ranks", [2, 3])
def test_ranks_read_their_shares_at_once_under_mpiexec(tmp_path, rng, ranks):
    """Every rank of an MPI run opens the file at once and reads its share: together the whole file."""
    import shutil
    import subprocess
    import sys
    mpiexec = shutil.which("mpiexec")
    try:
        import mpi4py  # noqa: F401
    except ImportError:
        mpiexec = None
    if mpiexec is None:
        pytest.skip("no mpiexec or mpi4py")
    written = make_observations(rng, 12, None)
    path = str(tmp_path / "o.h5")
    wb.write_observations(path, written)
    full = wb.read_observations(path)
    script = tmp_path / "read_share.py"
    script.write_text(MPI_SCRIPT)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMP_NUM_THREADS="1",
               PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    r = subprocess.run([mpiexec, "-n", str(ranks), "--oversubscribe", "--bind-to", "none", sys.executable,
                        str(script), path, str(tmp_path / "shares.txt")], env=env, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    shares = ast.literal_eval((tmp_path / "shares.txt").read_text())
    assert len(shares) == ranks
    together = sorted(row for share in shares for row in share)
    assert together == sorted((o.query.x_um, o.query.y_um, o.query.sigma_p_um, float(np.sum(o.reference)))
                              for o in full)
    assert all(len(s) > 0 for s in shares)
