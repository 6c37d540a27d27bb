"""Query: defaults, validated fields, wavelengths, and the keyword form of render_slice."""
import copy

import numpy as np
import pytest

import wavebrdf as wb


def test_defaults_and_fields():
    q = wb.Query()
    assert (q.x_um, q.y_um, q.sigma_p_um, q.light, q.model) == (0.0, 0.0, 10.0, (0.0, 0.0), "OHS")
    assert q.lambdas_um == [0.5] and not q.spectral
    s = wb.Query(spectral=8)
    assert s.spectral and s.lambdas_um == pytest.approx(wb.spectral_wavelengths_um(8))
    assert wb.Query(spectral=[0.4, 0.7]).lambdas_um == [0.4, 0.7]
    q.x_um, q.y_um, q.sigma_p_um, q.light, q.model = 1.0, 2.0, 3.0, (0.1, -0.2), "RGHS"
    assert (q.x_um, q.y_um, q.sigma_p_um, q.light, q.model) == (1.0, 2.0, 3.0, (0.1, -0.2), "RGHS")
    assert "RGHS" in repr(q) and "lambda_um=0.5" in repr(q)
    c = copy.copy(q)
    c.x_um = 9.0
    assert q.x_um == 1.0 and q.copy().x_um == 1.0


@pytest.mark.parametrize("field,value,message", [
    ("x_um", float("nan"), "x_um"), ("sigma_p_um", 0.0, "sigma_p_um"), ("light", (0.0, 1.0), "light"),
    ("model", "Beckmann", "model"),
])
def test_setters_validate(field, value, message):
    q = wb.Query()
    with pytest.raises(ValueError, match=message):
        setattr(q, field, value)
    with pytest.raises(ValueError, match=message):
        wb.Query(**{field: value})


def test_kwargs_drive_render_slice(rng):
    h = rng.normal(0, 0.3, (10, 10))
    for q in (wb.Query(x_um=3, y_um=4, sigma_p_um=2, light=(0.1, 0.1), model="GHS", lambda_um=0.6),
              wb.Query(x_um=3, y_um=4, sigma_p_um=2, spectral=3)):
        a = wb.render_slice(h, resolution=8, **q.kwargs())
        b = wb.render(wb.Heightfield(h), q, 8)
        np.testing.assert_array_equal(a, b)
