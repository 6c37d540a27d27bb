"""recover_heights takes its rarely used settings as recover() does: a wb.RecoverSettings given as
settings= (the schedule's settings both share and the stages' own); its old keywords still work
for one release with a FutureWarning and the same result; each function refuses the settings it
does not read (recover() the stages' own, recover_heights the acquisition's)."""
import numpy as np
import pytest

import wavebrdf as wb


@pytest.fixture(scope="module")
def small():
    plan = wb.plan_acquisition(rows=8, texel_um=2.0, sigma_p_um=3.0, height_range_um=0.1, resolution=32)
    truth = wb.with_height_range(wb.Heightfield.generate("isotropic", rows=8, texel_um=2.0, seed=5), 0.1)
    return truth, wb.simulate_observations(truth, plan)


def stages(obs, settings=None, **old):
    seen = []
    est = wb.recover_heights(obs, 8, 2.0, settings=settings, callback=lambda m: seen.append(
        (m["stage"], m["iteration"])) or True, **old)
    return est, seen


def test_settings_and_the_old_keywords_run_the_same_recovery(small):
    _, obs = small
    kw = dict(blur_widths=[4.0, 2.0], blur_iterations=3, field_iterations=2, refine_iterations=2)
    a, seen_a = stages(obs, wb.RecoverSettings(**kw))
    with pytest.warns(FutureWarning, match=r"recover_heights\(blur_iterations=\.\.\.\) is deprecated"):
        b, seen_b = stages(obs, **kw)
    np.testing.assert_array_equal(a.values, b.values)
    assert seen_a == seen_b
    # The settings reach the stages: two blur widths of 3 iterations, 2 field iterations.
    assert {s for s, _ in seen_a if s.startswith("blur:")} == {"blur:0", "blur:1"}
    assert max(i for s, i in seen_a if s == "blur:1") == 3
    assert max(i for s, i in seen_a if s.startswith("field:")) <= 2
    # Another setting, another run.
    c, _ = stages(obs, wb.RecoverSettings(**dict(kw, blur_iterations=1)))
    assert not np.array_equal(a.values, c.values)


def test_each_function_refuses_the_settings_it_does_not_read(small):
    _, obs = small
    with pytest.raises(ValueError, match=r"settings\.overlap = 0\.7 .*recover_heights"):
        wb.recover_heights(obs, 8, 2.0, settings=wb.RecoverSettings(overlap=0.7))
    with pytest.raises(ValueError, match=r"settings\.simulate_position_error_texels"):
        wb.recover_heights(obs, 8, 2.0, settings=wb.RecoverSettings(simulate_position_error_texels=0.5))
    with pytest.raises(ValueError, match=r"settings\.blur_widths = \[2\.0\] .*recover\(\)"):
        wb.recover(size=8, settings=wb.RecoverSettings(blur_widths=[2.0]))
    with pytest.raises(ValueError, match=r"settings\.refine_loss"):
        wb.recover(size=8, settings=wb.RecoverSettings(refine_loss="mse"))


@pytest.mark.parametrize("call, error, needle", [
    (lambda obs: wb.recover_heights(obs, 8, 2.0, blur_iteration=2), TypeError, "blur_iteration"),
    (lambda obs: wb.recover_heights(obs, 8, 2.0, overlap=0.7), TypeError, "overlap"),
    (lambda obs: wb.recover_heights(obs, 8, 2.0, settings="fast"), ValueError, "RecoverSettings"),
    (lambda obs: wb.recover_heights(obs, 8, 2.0, settings=wb.RecoverSettings(refine=2)), ValueError, "refine = 2"),
    (lambda obs: wb.recover_heights(obs, 8, 2.0, settings=wb.RecoverSettings(blur_iterations=-1)), ValueError,
     "blur_iterations = -1"),
    (lambda obs: wb.recover_heights(obs, 8, 2.0, settings=wb.RecoverSettings(blur_widths=[-1.0])), ValueError,
     "blur_widths = -1"),
    (lambda obs: wb.recover_heights(obs, 8, 2.0, settings=wb.RecoverSettings(refine_history=0)), ValueError,
     "refine_history = 0"),
    (lambda obs: wb.recover_heights(obs, 8, 2.0, settings=wb.RecoverSettings(max_range_um=0.0)), ValueError,
     "max_range_um"),
])
def test_bad_settings_name_themselves(small, call, error, needle):
    _, obs = small
    with pytest.raises(error) as info:
        call(obs)
    assert needle in str(info.value) and "\n" not in str(info.value), str(info.value)


def test_band_limit_reaches_the_field_stage(small):
    # Off, the field stage's unknowns are the object grid's samples rather than the band the
    # slices see: another retrieval from the same start, so other losses after its first step.
    _, obs = small

    def field_losses(**kw):
        seen = []
        wb.recover_heights(obs, 8, 2.0, callback=lambda m: seen.append((m["stage"], m["loss"])) or True,
                           settings=wb.RecoverSettings(blur_widths=[4.0], blur_iterations=2, field_iterations=3,
                                                       refine_iterations=0, **kw))
        return [(s, loss) for s, loss in seen if s.startswith("field:")]

    on, off = field_losses(), field_losses(band_limit=False)
    assert on and [s for s, _ in on] == [s for s, _ in off]
    assert [loss for _, loss in on] != [loss for _, loss in off]
