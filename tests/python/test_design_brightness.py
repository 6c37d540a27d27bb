"""A colour design that ends its schedule below Y 0.05 continues, trading Δu′v′ for brightness
up to --delta-uv-ceiling: the CLI and Python give the same design with a tolerance and the trade,
the reported loss is the colour loss recomputed here from the relief's own chromaticity and Y at
the tolerance the trade used, and a ceiling of 0 (or a colour bright after its schedule) leaves
the design as the schedule made it."""
import json
import math
import subprocess

import numpy as np
import pytest

import wavebrdf as wb

# 16 levels within 2 µm on a 16² tile of 0.5 µm: blue ends its short schedule far below Y 0.05.
# On its tile alone (auto would continue a dim blue, whose earlier tile runs its own trade).
BLUE = dict(target="colour:#0000FF", size=16, texel_um=0.5, levels=16, height_range_um=2.0, spectral=8,
            iterations=20, refine_passes=6, seed=5, continuation="off")


def colour_loss(uv, target_uv, y, tolerance):
    """docs/design.md's colour loss, written out independently of the library."""
    delta = math.hypot(uv[0] - target_uv[0], uv[1] - target_uv[1])
    excess = max(0.0, delta - tolerance) if tolerance > 0 else delta
    return (excess / 0.01) ** 2 + 4.0 * (max(0.0, 0.1 - y) / 0.1) ** 2


def test_cli_and_python_give_the_same_design_with_a_tolerance_and_the_trade(cli, tmp_path):
    r = wb.design(**BLUE, delta_uv_tolerance=0.005, delta_uv_ceiling=0.03)
    trade = r["design"]["brightness_trade"]
    assert trade["blocks"] >= 1  # the trade ran, so both front ends went through it
    out = tmp_path / "run"
    subprocess.run([cli, "design", "--target", "colour:#0000FF", "--out", str(out), "--size", "16", "--texel-um", "0.5",
                    "--levels", "16", "--height-range-um", "2", "--spectral", "8", "--iterations", "20",
                    "--refine-passes", "6", "--seed", "5", "--continuation", "off", "--delta-uv-tolerance", "0.005",
                    "--delta-uv-ceiling", "0.03", "--no-view-survey", "--quiet", "--no-plots"], check=True)
    hf = wb.Heightfield.from_exr(str(out / "heights.exr"))
    heights = np.asarray(hf.values) * hf.texel_um * hf.vscale
    # heights.exr stores float32 texel widths: equal to rounding (a level is 0.133 µm apart).
    np.testing.assert_allclose(heights.reshape(16, 16), r["heights_um"], atol=1e-6)
    doc = json.loads((out / "design.json").read_text())
    assert doc["target"]["delta_uv_tolerance"] == 0.005 and doc["target"]["delta_uv_ceiling"] == 0.03
    for key in ("blocks", "tolerance_used", "model_y_before", "model_y_after", "final_loss"):
        assert doc["brightness_trade"][key] == pytest.approx(trade[key], rel=1e-12, abs=0)
    for key in ("delta_uv", "luminous_efficiency"):
        assert doc["metrics"]["exact"][key] == pytest.approx(r["metrics"]["exact"][key], rel=1e-12)


def test_the_trade_continues_the_schedule_and_reports_the_loss_at_its_tolerance():
    plain = wb.design(**BLUE, delta_uv_ceiling=0.0)
    assert "brightness_trade" not in plain["design"]
    traded = wb.design(**BLUE)  # the default ceiling
    trade = traded["design"]["brightness_trade"]
    assert plain["metrics"]["model"]["luminous_efficiency"] < 0.05
    # It starts from the relief the schedule made: the same relief as without the trade.
    assert trade["model_y_before"] == pytest.approx(plain["metrics"]["model"]["luminous_efficiency"], rel=1e-12)
    assert trade["blocks"] >= 1 and 0.0 < trade["tolerance_used"] <= 0.04
    # Stopped for a stated reason: bright enough, the block cap, or a block at the ceiling that
    # did not lower the loss.
    assert (trade["model_y_after"] >= 0.05 or trade["blocks"] == trade["max_blocks"]
            or trade["tolerance_used"] == pytest.approx(0.04))
    m = traded["metrics"]["model"]
    assert trade["model_y_after"] == pytest.approx(m["luminous_efficiency"], rel=1e-12)
    expected = colour_loss(m["uv"], m["target_uv"], m["luminous_efficiency"], trade["tolerance_used"])
    assert traded["metrics"]["final_loss"] == pytest.approx(expected, rel=1e-9)
    assert trade["final_loss"] == pytest.approx(expected, rel=1e-9)
    # The kept relief's loss at the trade's tolerance is no higher than the schedule's relief's.
    p = plain["metrics"]["model"]
    assert expected <= colour_loss(p["uv"], p["target_uv"], p["luminous_efficiency"], trade["tolerance_used"]) + 1e-12


def test_a_colour_bright_after_its_schedule_is_untouched():
    green = dict(BLUE, target="colour:#00FF00", levels=8)
    plain = wb.design(**green, delta_uv_ceiling=0.0)
    assert plain["metrics"]["model"]["luminous_efficiency"] >= 0.05
    traded = wb.design(**green)
    assert traded["design"]["brightness_trade"]["blocks"] == 0
    np.testing.assert_array_equal(traded["heights_um"], plain["heights_um"])


def test_bad_ceiling_is_one_line():
    with pytest.raises(ValueError, match="--delta-uv-ceiling"):
        wb.design(**BLUE, delta_uv_ceiling=0.5)
