"""invert(comm=...), render_table(comm=...) and render_slice(comm=...) with an mpi4py
communicator: `mpiexec -n 2 /usr/bin/python3 -c SCRIPT` (started with an argument list, no
shell) runs each both ways on every rank, alone and split over the two ranks, and rank 0
reports how far they differ: the inversion's heights bit for bit (the sums over observations are
exact and order-independent), the table and the batch bit for bit (one slice does not depend on
the others rendered with it)."""
import json
import os
import shutil
import subprocess

import pytest

from conftest import BUILD, INSTALLED

MPIEXEC = shutil.which("mpiexec") or "/usr/bin/mpiexec"

SCRIPT = r"""
import json, sys
import numpy as np
from mpi4py import MPI
import wavebrdf

comm = MPI.COMM_WORLD
out = {"ranks": comm.Get_size()}
kw = dict(size=12, resolution=12, spectral=3, sigma_p_um=2.0, epochs=5, quiet=True,
          positions=[[3, 3], [9, 4], [5, 11], [12, 12], [7, 7]])
try:
    many = wavebrdf.invert(comm=comm, **kw)
except RuntimeError as e:
    if "without MPI" in str(e):
        if comm.Get_rank() == 0:
            print(json.dumps({"skip": str(e)}))
        sys.exit(0)
    raise
one = wavebrdf.invert(**kw)
a, b = np.asarray(one.estimate), np.asarray(many.estimate)
out["invert_rel"] = float(np.abs(a - b).max() / np.abs(a).max())
out["moved"] = float(np.abs(a - np.asarray(wavebrdf.invert(**dict(kw, epochs=0)).estimate)).max())
out["share"] = len(many.observations)
# Every rank holds the same estimate (allreduce_sum: the same bits everywhere).
gathered = comm.gather(b.tobytes(), root=0)
out["same_on_ranks"] = gathered is None or all(g == gathered[0] for g in gathered)

q = wavebrdf.Query(x_um=7.0, y_um=9.0, sigma_p_um=3.0, spectral=3)
t_many = wavebrdf.render_table(one.truth, q, lights=(5, 4), resolution=12, comm=comm)
t_one = wavebrdf.render_table(one.truth, q, lights=(5, 4), resolution=12)
if comm.Get_rank() == 0:
    out["table_equal"] = bool(np.array_equal(np.asarray(t_one.values), np.asarray(t_many.values)))
else:
    out["table_none"] = t_many is None

lights = np.array([[0.1 * k - 0.3, 0.05 * k] for k in range(7)])
s_many = wavebrdf.render_slice(np.asarray(one.truth), resolution=12, sigma_p_um=3.0, lambda_um=0.5,
                               light=lights, x_um=4.0, y_um=6.0, comm=comm)
s_one = wavebrdf.render_slice(np.asarray(one.truth), resolution=12, sigma_p_um=3.0, lambda_um=0.5,
                              light=lights, x_um=4.0, y_um=6.0)
if comm.Get_rank() == 0:
    out["batch_equal"] = bool(np.array_equal(s_one, s_many)) and s_many.shape == (7, 12, 12, 3)
else:
    out["batch_none"] = s_many is None
reports = comm.gather(out, root=0)
if comm.Get_rank() == 0:
    print(json.dumps(reports))
"""


def run_on_ranks(ranks):
    if not os.path.exists(MPIEXEC):
        pytest.skip("no mpiexec")
    try:
        import mpi4py  # noqa: F401
    except ImportError:
        pytest.skip("no mpi4py")
    env = dict(os.environ)
    env.update({"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1", "OMP_NUM_THREADS": "1",
                "ASAN_OPTIONS": "detect_leaks=0"})
    if not INSTALLED:
        env["PYTHONPATH"] = os.path.join(BUILD, "python") + os.pathsep + env.get("PYTHONPATH", "")
    args = [MPIEXEC, "-n", str(ranks), "--oversubscribe", "--bind-to", "none", "/usr/bin/python3", "-c", SCRIPT]
    r = subprocess.run(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout.strip().splitlines()[-1])
    if isinstance(report, dict) and "skip" in report:
        pytest.skip(report["skip"])
    return report


def test_invert_table_and_batch_split_over_two_ranks_equal_one_process():
    reports = run_on_ranks(2)
    assert len(reports) == 2
    for rank, out in enumerate(reports):
        assert out["ranks"] == 2
        assert out["invert_rel"] == 0.0, out
        assert out["moved"] > 0.0  # the run did something
        assert out["same_on_ranks"] is True
    # Five positions over two ranks: three and two.
    assert [out["share"] for out in reports] == [3, 2]
    assert reports[0]["table_equal"] is True and reports[1]["table_none"] is True
    assert reports[0]["batch_equal"] is True and reports[1]["batch_none"] is True
