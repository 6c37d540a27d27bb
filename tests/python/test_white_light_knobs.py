"""White light's smoothness continuation knobs (docs/recovery.md, White light): white_smoothness=
and white_smoothness_iterations= of wavebrdf.recover and recover_heights reach the pipeline
(the refine rows count weights x iterations), and bad values raise one clear ValueError."""
import numpy as np
import pytest

import wavebrdf as wb

SMALL_WHITE = dict(size=8, texel_um=2.0, sigma_p_um=3.0, height_range_um=0.1, seed=3, resolution=16, spectral=4)


def last_refine_iteration(metrics):
    return max(int(i) for s, i in zip(metrics["stage"], metrics["iteration"]) if s == "refine")


def test_recover_white_smoothness_sets_the_continuation():
    one = wb.recover(**SMALL_WHITE,
                     settings=wb.RecoverSettings(white_smoothness=[5.0], white_smoothness_iterations=3,
                                                 refine_iterations=1))
    two = wb.recover(**SMALL_WHITE,
                     settings=wb.RecoverSettings(white_smoothness=(5.0, 0.5), white_smoothness_iterations=3,
                                                 refine_iterations=1))
    assert last_refine_iteration(one.metrics) == 4
    assert last_refine_iteration(two.metrics) == 7
    for bad, match in [([-1.0], "white_smoothness"), ("10,1", "white_smoothness"), ([1.0] * 65, "at most 64"),
                       ([float("nan")], "white_smoothness")]:
        with pytest.raises(ValueError, match=match):
            wb.recover(**SMALL_WHITE, settings=wb.RecoverSettings(white_smoothness=bad))
    with pytest.raises(ValueError, match="white_smoothness_iterations"):
        wb.recover(**SMALL_WHITE, settings=wb.RecoverSettings(white_smoothness_iterations=-2))


def test_recover_heights_takes_white_smoothness():
    r = wb.recover(**SMALL_WHITE, settings=wb.RecoverSettings(refine_iterations=0, white_smoothness=[]))
    seen = []
    wb.recover_heights(r.observations, 8, 2.0, truth=r.truth,
                       callback=lambda m: seen.append((m["stage"], m["iteration"])) or True,
                       settings=wb.RecoverSettings(blur_widths=[4.0], blur_iterations=2, refine_iterations=1,
                                                   white_smoothness=[5.0, 0.5], white_smoothness_iterations=2))
    assert max(i for s, i in seen if s == "refine") == 5
    with pytest.raises(ValueError, match="white_smoothness"):
        wb.recover_heights(r.observations, 8, 2.0, settings=wb.RecoverSettings(white_smoothness=[1e13]))
    with pytest.raises(ValueError, match="white_smoothness_iterations"):
        wb.recover_heights(r.observations, 8, 2.0, settings=wb.RecoverSettings(white_smoothness_iterations=-1))
