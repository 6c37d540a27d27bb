"""wavebrdf.lobe_table / lobe_brdf (docs/table.md, "Analytic lobes"): the Python table equals
the file it writes as read back by read_table, entries are lobe_brdf at the pixel centres, the
peak at normal light is 1 / (4 pi alpha_x alpha_y), and bad values raise ValueError."""
import math

import numpy as np
import pytest

import wavebrdf as wb


def test_lobe_table_round_trip_and_values(tmp_path):
    out = tmp_path / "lobe.exr"
    t = wb.lobe_table("ggx", alpha_x=0.3, alpha_y=0.15, lights=(3, 4), max_light_sin=0.6, resolution=16, out=out)
    back = wb.read_table(out)
    np.testing.assert_array_equal(t.values, back.values)
    assert back.source.startswith("analytic lobe: ggx alpha_x 0.3 alpha_y 0.15")
    assert t.values.shape == (3, 4, 16, 16, 3)
    for a, b, p, q in [(1, 1, 8, 7), (0, 2, 3, 9), (2, 3, 10, 4)]:
        wi, wo = t.light(a, b), (t.omega_o[p], t.omega_o[q])
        expected = wb.lobe_brdf(wi, wo, "ggx", alpha_x=0.3, alpha_y=0.15) if t.rendered[a, b] else 0.0
        assert t.values[a, b, p, q, 0] == pytest.approx(expected, rel=1e-6)
        assert t.values[a, b, p, q, 0] == t.values[a, b, p, q, 2]


def test_peak_at_normal_light():
    for d in ("ggx", "beckmann"):
        assert wb.lobe_brdf((0, 0), (0, 0), d, alpha_x=0.1, alpha_y=0.2) == pytest.approx(1 / (4 * math.pi * 0.02))


def test_bad_values_raise():
    with pytest.raises(ValueError, match="alpha_x 0"):
        wb.lobe_table(alpha_x=0.0)
    with pytest.raises(ValueError, match="phong"):
        wb.lobe_table("phong")
    with pytest.raises(ValueError, match="fresnel_f0"):
        wb.lobe_brdf((0, 0), (0, 0), fresnel_f0=2.0)
