"""wavebrdf.design: the same design as the CLI from the same seed, a pattern given as an array
scored independently, and one-line errors for bad input."""
import json
import os
import subprocess

import numpy as np
import pytest

import wavebrdf as wb

SMALL = dict(size=16, spectral=3, band_um=(0.45, 0.65), levels=4, height_range_um=1.0, iterations=8,
             refine_passes=4, seed=7)


def test_cli_and_python_give_the_same_design(cli, tmp_path):
    r = wb.design(**SMALL)
    out = tmp_path / "run"
    subprocess.run([cli, "design", "--out", str(out), "--size", "16", "--spectral", "3", "--band-um", "0.45,0.65",
                    "--levels", "4", "--height-range-um", "1", "--iterations", "8", "--refine-passes", "4",
                    "--seed", "7", "--quiet"], check=True)
    hf = wb.Heightfield.from_exr(str(out / "heights.exr"))
    heights = np.asarray(hf.values) * hf.texel_um * hf.vscale
    # heights.exr stores float32 texel widths: equal to rounding.
    np.testing.assert_allclose(heights.reshape(16, 16), r["heights_um"], atol=1e-6)
    doc = json.loads((out / "design.json").read_text())
    assert doc["levels_um"] == pytest.approx(r["levels_um"], abs=0)
    assert doc["metrics"]["exact"]["specular_fraction"] == pytest.approx(
        r["metrics"]["exact"]["specular_fraction"], rel=1e-12)


def test_pattern_from_an_array():
    image = np.zeros((4, 4))
    image[1:3, 1:3] = 1.0
    r = wb.design(target="pattern", image=image, size=32, lambda_um=0.5, window=0.3, levels=8,
                  height_range_um=1.0, iterations=60, refine_passes=20)
    m = r["metrics"]["exact"]
    assert -1.0 <= m["correlation"] <= 1.0
    # The far-field picture (power per unit projected solid angle over +-picture_extent, which is
    # the window here) integrates to the reported efficiency, the window's share of the power.
    pic = r["far_field"][:, :, 0].astype(float)
    n = pic.shape[0]
    pixel_area = (2 * r["picture_extent"] / n) ** 2
    assert pic.sum() * pixel_area == pytest.approx(m["efficiency"][0], rel=1e-5)
    assert m["correlation"] > 0.5


def test_bad_input_is_a_value_error_before_any_work():
    with pytest.raises(ValueError, match="min-feature-um"):
        wb.design(min_feature_um=1.0, size=8)
    with pytest.raises(ValueError, match="#12"):
        wb.design(target="colour:#12", size=8)
    with pytest.raises(ValueError, match="image"):
        wb.design(target="anti-mirror", image=np.ones((2, 2)), size=8)
    with pytest.raises(ValueError, match="uniform"):
        wb.design(target="pattern", image=np.ones((2, 2)), size=8)
    with pytest.raises(ValueError, match="window"):
        wb.design(target="pattern", image=np.eye(3), window=0.9, size=8)
    with pytest.raises(ValueError, match="lambda_um"):
        wb.design(lambda_um=0.5, spectral=4, size=8)


def test_iridescent_cli_and_python_give_the_same_design(cli, tmp_path):
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps({"pairs": [{"view": [0.25, 0.0], "colour": "#ff8000"},
                                          {"view": [-0.25, 0.0], "colour": "#0080ff"}]}))
    target = "iridescent:" + str(spec)
    r = wb.design(target=target, size=16, spectral=4, band_um=(0.42, 0.68), levels=4, height_range_um=1.0,
                  view_cone=0.1, iterations=8, refine_passes=4, seed=3)
    out = tmp_path / "run"
    subprocess.run([cli, "design", "--target", target, "--out", str(out), "--size", "16", "--spectral", "4",
                    "--band-um", "0.42,0.68", "--levels", "4", "--height-range-um", "1", "--view-cone", "0.1",
                    "--iterations", "8", "--refine-passes", "4", "--seed", "3", "--quiet", "--no-plots"], check=True)
    hf = wb.Heightfield.from_exr(str(out / "heights.exr"))
    heights = np.asarray(hf.values) * hf.texel_um * hf.vscale
    np.testing.assert_allclose(heights.reshape(16, 16), r["heights_um"], atol=1e-6)
    doc = json.loads((out / "design.json").read_text())
    assert doc["target"]["kind"] == "iridescent"
    assert len(r["metrics"]["exact"]["pairs"]) == 2
    assert doc["metrics"]["exact"]["delta_uv"] == pytest.approx(r["metrics"]["exact"]["delta_uv"], rel=1e-12)
    assert doc["metrics"]["exact"]["luminous_efficiency"] == pytest.approx(
        r["metrics"]["exact"]["luminous_efficiency"], rel=1e-12)
    # Both pairs end the schedule dim, so both front ends ran the per-pair brightness trade.
    trade = r["design"]["brightness_trade"]
    assert trade["blocks"] >= 1 and len(trade["tolerance_used"]) == 2
    for key in ("blocks", "tolerance_used", "model_y_before", "model_y_after", "final_loss"):
        assert doc["brightness_trade"][key] == pytest.approx(trade[key], rel=1e-12, abs=0)


def test_bad_iridescent_spec_is_one_line(tmp_path):
    spec = tmp_path / "spec.json"
    spec.write_text('{"pairs": [{"view": [1.5, 0], "colour": "#ff0000"}]}')
    with pytest.raises(ValueError, match="visible disk") as e:
        wb.design(target="iridescent:" + str(spec), spectral=4, size=8)
    assert "\n" not in str(e.value)
    with pytest.raises(ValueError, match="view"):
        spec.write_text('{"pairs": [{"view": [0.2, 0], "colour": "#ff0000"}]}')
        wb.design(target="iridescent:" + str(spec), spectral=4, size=8, view=(0.1, 0.1))


def test_brdf_against_a_lobe_file_cli_and_python_agree(cli, tmp_path):
    # The table written by another command (wavebrdf lobe), designed for by the CLI and by
    # wb.design from one seed: the same heights and relative L2, which beats the random start's.
    table = tmp_path / "ggx.exr"
    subprocess.run([cli, "lobe", "--distribution", "ggx", "--alpha", "0.2", "--lights", "1", "--resolution", "16",
                    "--out", str(table)], check=True, capture_output=True)
    target = "brdf:" + str(table)
    options = dict(size=24, levels=4, height_range_um=1.0, iterations=20, refine_passes=5, seed=2)
    r = wb.design(target=target, **options)
    out = tmp_path / "run"
    subprocess.run([cli, "design", "--target", target, "--out", str(out), "--size", "24", "--levels", "4",
                    "--height-range-um", "1", "--iterations", "20", "--refine-passes", "5", "--seed", "2",
                    "--quiet", "--no-plots"], check=True)
    hf = wb.Heightfield.from_exr(str(out / "heights.exr"))
    heights = np.asarray(hf.values) * hf.texel_um * hf.vscale
    np.testing.assert_allclose(heights.reshape(24, 24), r["heights_um"], atol=1e-6)
    doc = json.loads((out / "design.json").read_text())
    assert doc["target"]["kind"] == "brdf"
    assert doc["metrics"]["exact"]["relative_l2"] == pytest.approx(r["metrics"]["exact"]["relative_l2"], rel=1e-12)
    start = wb.design(target=target, **dict(options, iterations=0, refine_passes=0))
    assert r["metrics"]["exact"]["relative_l2"] < start["metrics"]["exact"]["relative_l2"]
    with pytest.raises(ValueError, match="lambda_um"):
        wb.design(target=target, lambda_um=0.6, size=8)


def test_a_start_relief_cli_and_python_give_the_same_design(cli, tmp_path):
    # An earlier design's heights.exr as the start of both: the same relief and metrics; with no
    # iterations and no passes the start itself comes back.
    first = tmp_path / "first"
    args = ["--size", "16", "--spectral", "3", "--band-um", "0.45,0.65", "--levels", "4", "--height-range-um", "1",
            "--seed", "7", "--quiet", "--no-plots"]
    subprocess.run([cli, "design", "--out", str(first), "--iterations", "8", "--refine-passes", "4"] + args, check=True)
    hf = wb.Heightfield.from_exr(str(first / "heights.exr"))
    start = (np.asarray(hf.values) * hf.texel_um * hf.vscale).reshape(16, 16)
    kept = wb.design(**dict(SMALL, iterations=0, refine_passes=0), start=start)
    # The anti-mirror's step is the start's (from float32 heights: equal to their rounding).
    np.testing.assert_array_equal(kept["level"], np.rint(start / kept["levels_um"][1]).astype(int))
    np.testing.assert_allclose(kept["heights_um"], start, rtol=0, atol=1e-7)
    second = tmp_path / "second"
    subprocess.run([cli, "design", "--out", str(second), "--start", str(first / "heights.exr"), "--iterations", "8",
                    "--refine-passes", "4"] + args, check=True)
    r = wb.design(**SMALL, start=start)
    hf2 = wb.Heightfield.from_exr(str(second / "heights.exr"))
    np.testing.assert_allclose((np.asarray(hf2.values) * hf2.texel_um).reshape(16, 16), r["heights_um"], atol=1e-6)
    doc = json.loads((second / "design.json").read_text())
    assert doc["start"].startswith("the given relief")
    assert doc["metrics"]["exact"]["region_fraction"] == pytest.approx(r["metrics"]["exact"]["region_fraction"],
                                                                      rel=1e-12)
    # From a random start the same seed gives another relief.
    assert not np.array_equal(wb.design(**SMALL)["heights_um"], r["heights_um"])


def test_a_bad_start_is_one_line_before_any_work(cli, tmp_path):
    with pytest.raises(ValueError, match="start"):
        wb.design(**SMALL, start=np.zeros((8, 8)))
    bad = np.zeros((16, 16))
    bad[2, 3] = 0.2
    with pytest.raises(ValueError, match="0.2 um is not on the levels"):
        wb.design(**dict(SMALL, target="colour:#80a0c0"), start=bad)
    first = tmp_path / "first"
    subprocess.run([cli, "design", "--out", str(first), "--size", "8", "--spectral", "3", "--iterations", "2",
                    "--refine-passes", "1", "--quiet", "--no-plots"], check=True)
    p = subprocess.run([cli, "design", "--out", str(tmp_path / "b"), "--size", "16", "--start",
                        str(first / "heights.exr")], capture_output=True, text=True)
    assert p.returncode != 0
    assert p.stderr.strip().count("\n") == 0 and "8 x 8 texels; expected 16 x 16" in p.stderr
    assert not (tmp_path / "b" / "design.json").exists()


def test_a_continued_design_cli_and_python_give_the_same_design(cli, tmp_path):
    # The anti-mirror's default continuation (16 -> 8 first) and a given schedule: the CLI and
    # wb.design give the same relief and schedule; off is another design on the tile alone.
    args = ["--size", "16", "--spectral", "3", "--band-um", "0.45,0.65", "--levels", "4", "--height-range-um", "1",
            "--iterations", "8", "--refine-passes", "4", "--seed", "7", "--quiet", "--no-plots"]
    for schedule in ("auto", "4,8"):
        out = tmp_path / schedule.replace(",", "_")
        # The continuation alone: no annealed last stage (test_an_annealed_design_...).
        subprocess.run([cli, "design", "--out", str(out), "--continuation", schedule, "--anneal-sweeps", "0"] + args,
                       check=True)
        r = wb.design(**SMALL, continuation=schedule, anneal_sweeps=0)
        hf = wb.Heightfield.from_exr(str(out / "heights.exr"))
        np.testing.assert_allclose((np.asarray(hf.values) * hf.texel_um * hf.vscale).reshape(16, 16), r["heights_um"],
                                   atol=1e-6)
        doc = json.loads((out / "design.json").read_text())
        sizes = [s["size"] for s in doc["continuation"]["schedule"]]
        assert sizes == ([8, 16] if schedule == "auto" else [4, 8, 16])
        assert [s["size"] for s in r["design"]["continuation"]["schedule"]] == sizes
        # each earlier tile at the budget times (16/n)^2, the earlier tiles sharing one tile's, but
        # the first: the level-step survey's best tile, designed at the run's budget
        first = doc["continuation"]["schedule"][0]
        assert first["iterations"] == 8 and "designed_by" in first
        for k in range(1, len(sizes) - 1):
            assert doc["continuation"]["schedule"][k]["iterations"] == 8 * (16 // sizes[k]) ** 2 // (len(sizes) - 1)
        assert doc["metrics"]["exact"]["region_fraction_mean"] == pytest.approx(
            r["metrics"]["exact"]["region_fraction_mean"], rel=1e-12)
    off = wb.design(**SMALL, continuation="off", anneal_sweeps=0)
    assert [s["size"] for s in off["design"]["continuation"]["schedule"]] == [16]
    assert not np.array_equal(off["heights_um"], r["heights_um"])
    with pytest.raises(ValueError, match="--continuation 6: tile 6 does not divide 16"):
        wb.design(**SMALL, continuation="6")
    p = subprocess.run([cli, "design", "--out", str(tmp_path / "bad"), "--continuation", "fast"] + args,
                       capture_output=True, text=True)
    assert p.returncode != 0
    assert p.stderr.strip().count("\n") == 0 and "--continuation fast is not a schedule" in p.stderr
    assert not (tmp_path / "bad").exists()


def test_an_annealed_design_cli_and_python_give_the_same_design(cli, tmp_path):
    # The anti-mirror's annealed last stage, by default from a random start (400 sweeps) and with
    # --anneal-sweeps given: the loop designs the 8^2 tile, the anneal is its last stage, the 16^2
    # tile is that relief repeated; the CLI and wb.design give the same relief and anneal block.
    args = ["--size", "16", "--spectral", "3", "--band-um", "0.45,0.65", "--levels", "4", "--height-range-um", "1",
            "--iterations", "8", "--refine-passes", "4", "--seed", "7", "--quiet", "--no-plots"]
    for sweeps in (None, 30):
        out = tmp_path / f"anneal_{sweeps}"
        extra = [] if sweeps is None else ["--anneal-sweeps", str(sweeps)]
        subprocess.run([cli, "design", "--out", str(out)] + args + extra, check=True)
        r = wb.design(**SMALL, anneal_sweeps=sweeps)
        hf = wb.Heightfield.from_exr(str(out / "heights.exr"))
        np.testing.assert_allclose((np.asarray(hf.values) * hf.texel_um * hf.vscale).reshape(16, 16), r["heights_um"],
                                   atol=1e-6)
        doc = json.loads((out / "design.json").read_text())
        assert doc["anneal"]["sweeps"] == (400 if sweeps is None else sweeps)
        assert doc["anneal"]["tile"] == 8
        assert r["design"]["anneal"]["moves"] == doc["anneal"]["moves"]
        assert [s["size"] for s in doc["continuation"]["schedule"]] == [8, 16]
        level = r["level"]
        assert np.array_equal(level, np.tile(level[:8, :8], (2, 2)))
        assert doc["metrics"]["exact"]["region_fraction_mean"] == pytest.approx(
            r["metrics"]["exact"]["region_fraction_mean"], rel=1e-12)
        assert sum(1 for c in r["curve"] if c[2] == "anneal 8x8") == doc["anneal"]["sweeps_run"]
    with pytest.raises(ValueError, match="--anneal-sweeps -1"):
        wb.design(**SMALL, anneal_sweeps=-1)
    with pytest.raises(ValueError, match="--anneal-sweeps 5 with --target colour:#00FF00"):
        wb.design(**dict(SMALL, spectral=4), target="colour:#00FF00", anneal_sweeps=5)
    p = subprocess.run([cli, "design", "--out", str(tmp_path / "bad"), "--anneal-sweeps", "200000"] + args,
                       capture_output=True, text=True)
    assert p.returncode != 0
    assert p.stderr.strip().count("\n") == 0 and "--anneal-sweeps 200000" in p.stderr
    assert not (tmp_path / "bad").exists()
