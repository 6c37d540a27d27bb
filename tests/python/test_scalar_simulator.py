"""recover(simulator="scalar"): the observations come from the scalar-diffraction simulator
(scalar_diffraction.h), not from the Gabor model. On a flat truth both agree (the model is exact
for a plane); on a rough one they differ (the model's tangent planes are an approximation) while
staying within a bound; bad values and given observations are refused."""
import numpy as np
import pytest

import wavebrdf as wb

# A tiny, fast study: 8x8 texels of 2 um, sigma_p = 3 um, 16x16 slices; the callback stops the
# recovery at its first step (the observations are what is tested).
FAST = dict(texel_um=2.0, sigma_p_um=3.0, resolution=16, seed=5204, callback=lambda m: False)


def references(result):
    return np.concatenate([np.asarray(o.reference, dtype=float).ravel() for o in result.observations])


def rel_l2(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def test_flat_truth_gives_the_gabor_models_slices():
    flat = wb.Heightfield(np.full((8, 8), 0.25), texel_um=2.0)
    scalar = wb.recover(flat, **FAST, settings=wb.RecoverSettings(simulator="scalar"))
    gabor = wb.recover(flat, **FAST)
    assert rel_l2(references(scalar), references(gabor)) < 1e-6


def test_rough_truth_gives_other_slices():
    study = dict(size=8, height_range_um=0.1, **FAST)
    scalar = wb.recover(**study, settings=wb.RecoverSettings(simulator="scalar"))
    gabor = wb.recover(**study, settings=wb.RecoverSettings(simulator="gabor"))
    d = rel_l2(references(scalar), references(gabor))
    # Measured 0.127: the distance grows linearly with the heights (it is the interference of the
    # specular lobe with the model's first-order error in the scattered field; 0.018 at +-5 nm,
    # 2e-4 at +-0.05 nm), so it is far from 0 but bounded.
    assert 0.01 < d < 0.3
    assert scalar.stopped and len(scalar.observations) == len(gabor.observations)


def test_bad_simulator_and_given_observations_are_refused():
    with pytest.raises(ValueError, match="simulator 'exact'"):
        wb.recover(size=8, settings=wb.RecoverSettings(simulator="exact"))
    plan = wb.plan_acquisition(rows=8, texel_um=2.0, sigma_p_um=3.0, height_range_um=0.1, resolution=16)
    truth = wb.Heightfield(np.zeros((8, 8)), texel_um=2.0)
    observations = wb.simulate_observations(truth, plan)
    with pytest.raises(ValueError, match="simulator 'scalar'"):
        wb.recover(observations=observations, size=8, texel_um=2.0, settings=wb.RecoverSettings(simulator="scalar"))
