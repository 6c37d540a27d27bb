"""wavebrdf.recover(comm=...) under mpiexec (docs/scale.md): every rank gets the same estimate,
the same bits for two runs and as the one-process run (exact sums); comm=None stays one process."""
import os
import shutil
import subprocess

import numpy as np
import pytest

import wavebrdf
from conftest import BUILD, INSTALLED

MPIEXEC = shutil.which("mpiexec")

SCRIPT = r"""
import sys
import numpy as np
from mpi4py import MPI
import wavebrdf
comm = MPI.COMM_WORLD
r = wavebrdf.recover(size=12, seed=3, lambdas_um=[0.6], height_range_um=0.2, field_iterations=10,
                     refine_iterations=5, quiet=True, comm=comm)
h = r.estimate.heights_um()
all_h = comm.gather(np.asarray(h, dtype=np.float64), root=0)
counts = comm.gather(len(r.observations), root=0)
if comm.rank == 0:
    np.save(sys.argv[1], np.stack(all_h))
    np.save(sys.argv[1] + ".counts.npy", np.asarray(counts))
"""


def _environment():
    env = dict(os.environ)
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMP_NUM_THREADS="1",
               ASAN_OPTIONS="detect_leaks=0")
    if not INSTALLED:  # the ranks import this build's package, as this process does (conftest)
        env["PYTHONPATH"] = os.path.join(BUILD, "python") + os.pathsep + env.get("PYTHONPATH", "")
    return env


def _mpi_run(tmp_path, ranks, name):
    out = str(tmp_path / (name + ".npy"))
    script = tmp_path / "run.py"
    script.write_text(SCRIPT)
    subprocess.run([MPIEXEC, "-q", "-n", str(ranks), "--oversubscribe", "--bind-to", "none", "/usr/bin/python3",
                    str(script), out], check=True, env=_environment(), timeout=300)
    return np.load(out), np.load(out + ".counts.npy")


def _heights(hf):
    return np.asarray(hf.heights_um(), dtype=np.float64)


@pytest.mark.skipif(MPIEXEC is None, reason="needs mpiexec (openmpi-bin) and a wavebrdf built with MPI")
def test_recover_with_comm_shards_and_matches_one_process(tmp_path):
    pytest.importorskip("mpi4py")
    one = wavebrdf.recover(size=12, seed=3, lambdas_um=[0.6], height_range_um=0.2, 
                           quiet=True, settings=wavebrdf.RecoverSettings(field_iterations=10, refine_iterations=5))
    a, counts = _mpi_run(tmp_path, 2, "a")
    b, _ = _mpi_run(tmp_path, 2, "b")
    assert (a[0] == a[1]).all(), "every rank returns the same heights"
    assert (a == b).all(), "the same bits for the same number of ranks"
    assert counts.sum() == len(one.observations) and (counts > 0).all(), "each rank holds its share"
    ref = _heights(one.estimate)
    # Exact sums over observations: the one-process heights bit for bit (the bound is 1e-9).
    assert (a[0].reshape(ref.shape) == ref).all(), np.abs(a[0].reshape(ref.shape) - ref).max() / np.abs(ref).max()


def test_comm_none_is_one_process_and_a_bad_comm_is_refused():
    with pytest.raises(ValueError, match="comm"):
        wavebrdf.recover(size=12, comm=42)
