"""The measured-roughness plan from Python (docs/surfaces.md, "Recovery on the real scans";
docs/recovery.md, "Rough surfaces"): wb.measure_roughness reads what the CLI's --truth planner
reads, matching closed forms on a cosine; wb.recover(truth=...) plans a truth for its measured
roughness as `wavebrdf recover --truth` does (same notes, observations, warnings and
convergence verdict), and for the stated one when correlation_texels is given;
wb.plan_acquisition(roughness=...) makes that plan; result.convergence judges the run without
the truth as the CLI's run.json does."""
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

import wavebrdf as wb

import conftest

ONE_THREAD = dict(os.environ, OMP_NUM_THREADS="1")
FAST_SETTINGS = dict(field_iterations=1, refine_iterations=1)
FAST = dict(resolution=16, settings=wb.RecoverSettings(**FAST_SETTINGS))
FAST_CLI = ["--field-iterations", "1", "--refine-iterations", "1", "--resolution", "16"]


def cosine_surface(rows=20, cols=8, period=10, amplitude_um=1.0, texel_um=1.0):
    """A cos(2 pi x / L) along x (the Heightfield's rows), grooves along y: steep (rms slope 0.42)."""
    x = np.arange(rows)[:, None] * texel_um
    heights_um = amplitude_um * np.cos(2 * np.pi * x / (period * texel_um)) * np.ones((1, cols))
    return wb.Heightfield.from_um(heights_um, texel_um)


def test_measured_roughness_of_a_cosine_is_its_closed_form():
    amplitude, period, w = 1.0, 10, 1.0
    hf = cosine_surface(rows=40, cols=16, period=period, amplitude_um=amplitude, texel_um=w)
    m = wb.measure_roughness(hf)
    assert set(m) == {"range_um", "rms_slope", "rim_fraction", "correlation_um", "aspect", "lay_deg"}
    # Samples at x = 0 and L/2 reach +-A exactly.
    assert m["range_um"] == pytest.approx(2 * amplitude, rel=1e-12)
    # Central differences of A cos(kx): -A sin(kx) sin(kw) / w, rms over whole periods / sqrt(2).
    k = 2 * np.pi / (period * w)
    assert m["rms_slope"] == pytest.approx(amplitude * np.sin(k * w) / (w * np.sqrt(2)), rel=1e-12)
    # |slope| > 0.5 where |sin(kx)| > 0.5 / sin(kw) = 0.85: x = 2, 3, 7, 8 of every 10.
    assert m["rim_fraction"] == pytest.approx(0.4, abs=1e-12)
    # Sal, Str, Std are ISO 25178-2's (surface_stats); Sal near the closed form L acos(0.2) / 2 pi
    # of the ACF cos(k tau) across the grooves (sampled 10 times a period: linear between lags).
    p = wb.surface_stats(hf)
    assert (m["correlation_um"], m["aspect"], m["lay_deg"]) == (p["Sal"], p["Str"], p["Std"])
    assert m["correlation_um"] == pytest.approx(period * w * math.acos(0.2) / (2 * math.pi), rel=0.05)
    assert m["lay_deg"] == pytest.approx(90.0, abs=0.5)
    assert m["aspect"] < 0.5


def test_plan_acquisition_takes_a_measured_roughness():
    hf = cosine_surface()
    m = wb.measure_roughness(hf)
    base = dict(rows=hf.rows, cols=hf.cols, texel_um=hf.texel_um, height_range_um=m["range_um"], seed=1)
    smooth = wb.plan_acquisition(**base)
    rough = wb.plan_acquisition(**base, roughness=hf)
    # Steep (rms slope 0.42 > 0.2): long wavelengths appended, every one longer than the ladder's,
    # and the ring of oblique lights; the plan says what it measured.
    assert list(rough.lambdas_um[:len(smooth.lambdas_um)]) == list(smooth.lambdas_um)
    added = rough.lambdas_um[len(smooth.lambdas_um):]
    assert len(added) >= 1 and min(added) > max(smooth.lambdas_um)
    assert len(rough.oblique_lights) == 4 and smooth.oblique_lights == []
    assert any("measured roughness" in n for n in rough.notes)
    # The dict gives the same plan as the Heightfield; without oblique lights, none.
    same = wb.plan_acquisition(**base, roughness=m)
    assert list(same.lambdas_um) == list(rough.lambdas_um) and same.notes == rough.notes
    assert wb.plan_acquisition(**base, roughness=m, oblique_lights=False).oblique_lights == []
    # Given wavelengths stay as given.
    given = wb.plan_acquisition(**base, roughness=m, lambdas_um=[0.5])
    assert list(given.lambdas_um) == [0.5]
    # A flat surface's roughness changes nothing.
    flat = wb.Heightfield.from_um(np.zeros((8, 8)), 1.0)
    assert list(wb.plan_acquisition(rows=8, texel_um=1.0, roughness=flat).lambdas_um) == \
        list(wb.plan_acquisition(rows=8, texel_um=1.0).lambdas_um)


@pytest.fixture(scope="module")
def steep_truth(tmp_path_factory):
    path = tmp_path_factory.mktemp("measured") / "steep.exr"
    cosine_surface().save(str(path))
    return path


def test_recover_plans_a_truth_as_the_cli_does(steep_truth, tmp_path):
    cli = os.path.join(conftest.BUILD, "bin", "wavebrdf")
    assert os.path.exists(cli), "%s is missing; build the wavebrdf_cli target" % cli
    out = tmp_path / "cli"
    subprocess.run([cli, "recover", "--truth", str(steep_truth), *FAST_CLI, "--noise", "poisson:1e4", "--no-plots",
                    "--quiet", "--out", str(out)], check=True, env=ONE_THREAD, capture_output=True)
    run = json.load(open(out / "run.json"))
    saved = tmp_path / "py.json"
    script = (
        "import json, wavebrdf as wb\n"
        "r = wb.recover(truth=%r, noise='poisson:1e4', quiet=True, resolution=16,\n"
        "               settings=wb.RecoverSettings(**%r))\n"
        "json.dump(dict(notes=r.notes, warnings=r.warnings, observations=len(r.observations),\n"
        "               lambdas=sorted({l for o in r.observations for l in o.lambdas_um}),\n"
        "               convergence=r.convergence), open(%r, 'w'))\n" % (str(steep_truth), FAST_SETTINGS, str(saved)))
    env = dict(ONE_THREAD, PYTHONPATH=os.path.join(conftest.BUILD, "python"))
    subprocess.run([sys.executable, "-c", script], check=True, env=env)
    py = json.load(open(saved))
    # The measured plan: what was measured, long wavelengths and oblique lights.
    assert py["notes"] == run["plan"]
    assert any("measured roughness" in n for n in py["notes"])
    assert py["observations"] == run["observations"]
    assert max(py["lambdas"]) > 0.7
    # One field and one refinement iteration cannot converge: both say so, with the same verdict.
    assert py["warnings"] == run["warnings"]
    assert any("did not converge" in w for w in py["warnings"])
    c, cj = py["convergence"], run["convergence"]
    assert c["converged"] is False and cj["converged"] is False
    assert c["floor"] == cj["floor"] == "poisson"
    assert c["reasons"] == cj["reasons"]
    assert c["misfit_ratio"] == pytest.approx(cj["misfit_ratio"], rel=1e-9)
    assert c["warning"] == py["warnings"][-1]


def test_recover_plans_as_stated_when_a_correlation_is_given(steep_truth):
    stated = wb.recover(truth=str(steep_truth), correlation_texels=4, quiet=True, **FAST)
    off = wb.recover(truth=str(steep_truth), quiet=True, resolution=16,
                    settings=wb.RecoverSettings(**FAST_SETTINGS, plan_from_truth=False))
    assert not any("measured roughness" in n for n in stated.notes)
    assert stated.notes == off.notes and len(stated.observations) == len(off.observations)
    measured = wb.recover(truth=str(steep_truth), quiet=True, resolution=16,
                         settings=wb.RecoverSettings(**FAST_SETTINGS, plan_from_truth=True))
    assert any("measured roughness" in n for n in measured.notes)
    assert len(measured.observations) > len(stated.observations)


def test_a_converged_study_says_so():
    r = wb.recover(size=8, texel_um=2.0, sigma_p_um=3.0, height_range_um=0.1, seed=3, quiet=True)
    assert r.convergence["converged"] is True and r.convergence["warning"] == ""
    assert r.convergence["floor"] == "noiseless" and r.convergence["relative_misfit"] < 1e-5
    assert not any("did not converge" in w for w in r.warnings)


def test_the_checks_error_bars_follow_check_error_bars():
    # Photon counts on nm heights: the misfit on the floor, the bars (default: by the cost rule;
    # 'always' here, the rule being timing-dependent) warn; 'off' leaves the noise limit unjudged.
    kw = dict(size=16, resolution=48, noise="poisson:1e4", seed=4, height_range_um=0.02, quiet=True,
              target_error=0)  # one exposure per slice: the photon limit as it comes
    on = wb.recover(check_error_bars="always", **kw)
    assert on.convergence["error_bars"] == "computed"
    assert on.convergence["predicted_error_relative"] > 0.01
    assert on.convergence["error_bars_seconds"] > 0 and on.convergence["run_seconds"] > 0
    assert any("likely inaccurate" in w for w in on.warnings)
    off = wb.recover(check_error_bars="off", **kw)
    assert off.convergence["error_bars"] == "off" and off.convergence["judged"] is True
    assert "predicted_error_relative" not in off.convergence
    assert not any("likely inaccurate" in w for w in off.warnings)
    assert off.convergence["misfit_ratio"] == pytest.approx(on.convergence["misfit_ratio"], rel=1e-12)
    # The texture check (texel_texture.h) reads the estimate at the bars' σ where they exist: a
    # smooth generated surface holds no texel-scale spikes; without bars or a plan it is not judged.
    t = on.convergence["texture"]
    assert t["sigma_source"] == "error bars"
    assert t["sigma_relative"] == pytest.approx(on.convergence["predicted_error_relative"], rel=1e-12)
    assert t["fraction"] < 0.05 and t["warned"] is False
    assert "texture" not in off.convergence


@pytest.mark.parametrize("kwargs, needles", [
    (dict(check_error_bars="sometimes"), ["check_error_bars", "'sometimes'"]),
    (dict(settings=wb.RecoverSettings(plan_from_truth=True)), ["plan_from_truth", "truth"]),
    (dict(truth=np.eye(4), settings=wb.RecoverSettings(plan_from_truth=True), correlation_texels=3),
     ["plan_from_truth", "correlation_texels"]),
    (dict(truth=np.eye(4), settings=wb.RecoverSettings(plan_from_truth="yes")), ["plan_from_truth", "'yes'"]),
    (dict(correlation_texels=-1), ["correlation_texels"]),
])
def test_bad_plan_arguments_name_themselves(kwargs, needles):
    with pytest.raises(ValueError) as info:
        wb.recover(size=4, **kwargs)
    message = str(info.value)
    assert "\n" not in message
    for needle in needles:
        assert needle in message, message


@pytest.mark.parametrize("roughness, needles", [
    ({"range_um": 1.0}, ["roughness", "rms_slope"]),
    ({"range_um": 1.0, "rms_slope": float("nan"), "correlation_um": 2.0}, ["rms_slope", "nan"]),
    ("rough", ["roughness", "measure_roughness"]),
])
def test_bad_roughness_names_itself(roughness, needles):
    with pytest.raises(ValueError) as info:
        wb.plan_acquisition(rows=8, texel_um=1.0, roughness=roughness)
    message = str(info.value)
    assert "\n" not in message
    for needle in needles:
        assert needle in message, message
