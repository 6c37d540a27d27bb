"""Recovery from observations with per-pixel weights (Python): slices with corrupted pixels of
weight 0 recover as well as the clean slices, through recover_heights and recover(), and the
same corrupted slices without the weights do not."""
import numpy as np
import pytest

import wavebrdf as wb

# The small study of test_recover.py: 8x8 texels of 2 um, heights within 0.1 um, on the
# planner's slices (48x48), seeds 3-5: there 3 % of the pixels can hide a slice's specular
# peak, which the model check, when it read the filled values unweighted, took for a misfit of
# the refined heights and swapped them for the field model's, 2.3-3.0 % off (clean 3-4e-6;
# experiments/2026-11-30-masked-pixels-model-check.md).
SMALL = dict(size=8, texel_um=2.0, sigma_p_um=3.0, height_range_um=0.1)


def _corrupted(observations, mask, seed=5, fraction=0.03):
    """3 % of each slice's pixels hot (up to 20x its peak) or dead (0, and one NaN where masked)."""
    rng = np.random.default_rng(seed)
    out = []
    for o in observations:
        ref = np.array(o.reference, dtype=np.float64)
        bad = rng.random(ref.shape[:2]) < fraction
        ref[bad] = np.where(rng.random(bad.sum()) < 0.5, 0.0, 20.0 * rng.random(bad.sum()) * ref.max())
        if not mask:
            out.append(wb.Observation(o.query, ref))
            continue
        if bad.any():
            ref[np.argwhere(bad)[0][0], np.argwhere(bad)[0][1]] = np.nan
        out.append(wb.Observation(o.query, ref, weights=(~bad).astype(np.float64)))
    return out


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_masked_corrupted_pixels_recover_as_well_as_clean_slices(seed):
    clean = wb.recover(**SMALL, seed=seed)
    truth = clean.truth
    masked = _corrupted(clean.observations, True)
    assert all(o.weights is not None for o in masked)
    err_clean = wb.height_rel_rmse(wb.recover_heights(clean.observations, 8, 2.0), truth)
    err_masked = wb.height_rel_rmse(wb.recover_heights(masked, 8, 2.0), truth)
    err_unmasked = wb.height_rel_rmse(wb.recover_heights(_corrupted(clean.observations, False), 8, 2.0), truth)
    assert err_clean < 1e-3
    assert err_masked < max(2 * err_clean, 1e-3)
    assert err_unmasked > 10 * max(err_masked, 1e-4)
    # recover() takes the same weighted observations (its checks, error bars and convergence).
    r = wb.recover(observations=masked, size=8, texel_um=2.0, height_range_um=0.1)
    assert wb.height_rel_rmse(r.estimate, truth) < max(2 * err_clean, 1e-3)
    assert all(o.weights is not None for o in r.observations)
