"""Self-calibration (calibration.h) through Python: the calibrate= keyword of recover() and
recover_heights(), the refined values they return, the simulated acquisition errors, and the
plane-removed metric."""
import numpy as np
import pytest

import wavebrdf as wb

# The small study of tests/recover_cli_test.cpp: 8x8 texels of 2 um, heights within 0.1 um.
SMALL = dict(size=8, texel_um=2.0, sigma_p_um=3.0, height_range_um=0.1, seed=5051)


def test_recover_refines_exposures_and_returns_them():
    r = wb.recover(**SMALL, calibrate=("exposure",), quiet=True,
                   settings=wb.RecoverSettings(simulate_exposure=(0.5, 2.0)))
    c = r.calibration
    assert c["refined"] == "exposure"
    assert c["position_offsets_um"] is None and c["sigma_p_scale"] == 1.0
    n = len(r.observations)
    assert c["exposures"].shape == (n,)
    true = c["truth"]["exposures"]
    assert true.shape == (n,) and true.min() >= 0.5 and true.max() <= 2.0 and true.std() > 0.1
    np.testing.assert_allclose(c["exposures"], true, rtol=0.02)
    assert c["truth"]["sigma_p_scale"] == 1.0
    assert np.isfinite(r.metrics["height_rel_rmse_plane_removed"][-1])
    assert r.metrics["height_rel_rmse_plane_removed"][-1] <= r.metrics["height_rel_rmse"][-1] + 1e-12


def test_recover_without_calibration_has_no_truth_and_plain_values():
    r = wb.recover(**SMALL, quiet=True, settings=wb.RecoverSettings(field_iterations=2, refine_iterations=1))
    assert r.calibration["refined"] == "none" and r.calibration["truth"] is None
    assert r.calibration["exposures"] is None


def test_recover_heights_returns_the_calibration_when_asked():
    plan = wb.plan_acquisition(rows=8, texel_um=2.0, sigma_p_um=3.0, height_range_um=0.1, resolution=32)
    truth = wb.with_height_range(wb.Heightfield.generate("isotropic", rows=8, texel_um=2.0, seed=5052), 0.1)
    obs = wb.simulate_observations(truth, plan)
    plain = wb.recover_heights(obs, 8, 2.0, settings=wb.RecoverSettings(field_iterations=3, refine_iterations=2))
    assert isinstance(plain, wb.Heightfield)
    est, c = wb.recover_heights(obs, 8, 2.0, calibrate="exposure,sigma",
                                settings=wb.RecoverSettings(field_iterations=3, refine_iterations=2))
    assert isinstance(est, wb.Heightfield)
    assert c["refined"] == "exposure,sigma"
    assert c["exposures"].shape == (len(obs),)
    np.testing.assert_allclose(c["exposures"], 1.0, rtol=0.2)  # rendered exactly: 1 (few iterations here)
    assert 0.8 < c["sigma_p_scale"] < 1.25
    _, none = wb.recover_heights(obs, 8, 2.0, calibrate=[],
                                 settings=wb.RecoverSettings(field_iterations=1, refine_iterations=1))
    assert none["refined"] == "none"


def test_position_passes_bounds_the_position_loop():
    args = dict(SMALL, calibrate="positions", quiet=True)
    fast = dict(simulate_position_error_texels=0.5, field_iterations=3, refine_iterations=3)
    one = wb.recover(**args, settings=wb.RecoverSettings(**fast, position_passes=1))
    stages = list(one.metrics["stage"])
    assert stages.count("positions:register") == 1 and stages.count("positions:newton") == 1
    assert one.calibration["position_offsets_um"].shape == (len(one.observations), 2)
    off = wb.recover(**args, settings=wb.RecoverSettings(**fast, position_passes=0))
    assert "positions:register" not in list(off.metrics["stage"])


@pytest.mark.parametrize("call, needles", [
    (lambda: wb.recover(size=8, calibrate="exposure,focus"), ["calibrate", "'focus'", "positions, exposure"]),
    (lambda: wb.recover(size=8, calibrate=("exposure", 3)), ["calibrate", "sequence"]),
    (lambda: wb.recover(size=8, calibrate=5), ["calibrate", "sequence"]),
    (lambda: wb.recover(size=8,
                        settings=wb.RecoverSettings(simulate_exposure=(2.0, 1.0))), ["simulate_exposure", "at most the max"]),
    (lambda: wb.recover(size=8, settings=wb.RecoverSettings(simulate_exposure="0.5,2")), ["simulate_exposure"]),
    (lambda: wb.recover(size=8,
                        settings=wb.RecoverSettings(simulate_sigma_factor=9.0)), ["simulate_sigma_factor", "9"]),
    (lambda: wb.recover(size=8,
                        settings=wb.RecoverSettings(simulate_position_error_texels=-1.0)), ["simulate_position_error_texels"]),
    (lambda: wb.recover(size=8, calibrate="positions",
                        settings=wb.RecoverSettings(position_passes=101)), ["position_passes", "101", "0 to 100"]),
    (lambda: wb.recover(size=8, calibrate="positions",
                        settings=wb.RecoverSettings(position_passes=-2)), ["position_passes", "-2"]),
])
def test_bad_calibration_arguments_name_themselves(call, needles):
    with pytest.raises(ValueError) as e:
        call()
    for n in needles:
        assert n in str(e.value), (n, str(e.value))


def test_plane_removed_metric_ignores_a_tilt():
    rng = np.random.default_rng(5053)
    truth = wb.Heightfield(rng.normal(size=(10, 12)), texel_um=2.0)
    i, j = np.meshgrid(np.arange(10), np.arange(12), indexing="ij")
    tilted = truth.with_values(truth.values + 0.3 + 0.05 * i - 0.02 * j)
    assert wb.height_rel_rmse(tilted, truth) > 0.01
    assert wb.height_rel_rmse_plane_removed(tilted, truth) == pytest.approx(0.0, abs=1e-12)
