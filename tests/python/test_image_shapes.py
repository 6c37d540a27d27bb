"""Camera images on spheres and cylinders, with disc lights, in single precision, and their gradient:
`wavebrdf image` and wb.render_image give the same picture bit for bit (sphere, cylinder, a disc
light, --precision float),
wb.image_gradient equals central differences of the double-precision picture, and bad shapes are
refused with one line before any work."""
import subprocess

import numpy as np
import pytest

import wavebrdf as wb


SPHERE_CLI = ["--sphere-radius-um", "300", "--camera", "-200,100,900", "--fov-deg", "45", "--resolution", "11,9",
              "--point-light", "400,-300,700", "--spectral", "3", "--sigma-p-um", "3", "--rotation-deg", "20"]
SPHERE_PY = dict(sphere_radius_um=300, camera=(-200, 100, 900), fov_deg=45, resolution=(11, 9),
                 point_light=(400, -300, 700), spectral=3, sigma_p_um=3, rotation_deg=20)
CYLINDER_CLI = ["--cylinder-radius-um", "200", "--cylinder-length-um", "500", "--camera", "0,-300,800",
                "--orthographic", "--resolution", "10,12", "--directional-light", "0.3,0.2,1", "--lambda-um",
                "0.55", "--sigma-p-um", "4"]
CYLINDER_PY = dict(cylinder_radius_um=200, cylinder_length_um=500, camera=(0, -300, 800), orthographic=True,
                   resolution=(10, 12), directional_light=(0.3, 0.2, 1), lambda_um=0.55, sigma_p_um=4)


@pytest.mark.parametrize("cli_args, py_args", [
    (SPHERE_CLI, SPHERE_PY),
    (SPHERE_CLI + ["--precision", "float"], dict(SPHERE_PY, precision="float")),
    (CYLINDER_CLI, CYLINDER_PY),
    (SPHERE_CLI + ["--disc-light", "300,-200,600,30", "--disc-order", "3"],
     dict(SPHERE_PY, disc_light=(300, -200, 600, 30), disc_order=3)),
    (CYLINDER_CLI + ["--precision", "float"], dict(CYLINDER_PY, precision="float")),
])
def test_cli_and_python_bit_identical(tmp_path, rng, cli, cli_args, py_args, random_heightfield_exr):
    hf = random_heightfield_exr(24)
    out = tmp_path / "i.exr"
    subprocess.run([cli, "image", "--heightfield", hf, *cli_args, "--out", str(out), "--quiet"], check=True)
    image = wb.render_image(hf, **py_args)
    image_file, _ = wb.read_slice(str(out))
    np.testing.assert_array_equal(np.asarray(image_file), image)
    # Some pixels see the sample and are lit, some see the background.
    assert image.max() > 0 and (image == 0).all(axis=2).any()


def test_float_precision_runs_in_float_within_its_error(tmp_path, rng, random_heightfield_exr):
    hf = random_heightfield_exr(24)
    double = wb.render_image(hf, dtype="float64", **SPHERE_PY)
    single = wb.render_image(hf, dtype="float64", precision="float", **SPHERE_PY)
    assert double.dtype == np.float64
    assert not np.array_equal(double, single)  # the float sum really ran
    assert np.abs(single - double).max() <= 1e-4 * np.abs(double).max()


def test_image_gradient_equals_central_differences(rng):
    heights = rng.normal(0.0, 0.15, (12, 12))
    scene = dict(texel_um=1.0, sphere_radius_um=150, camera=(30, -20, 500), fov_deg=30, resolution=(7, 6),
                 point_light=(200, 100, 400), spectral=2, sigma_p_um=2.5, model="RGHS", prune_tolerance=0)
    weights = rng.normal(size=(7, 6, 3))

    def loss(h):
        return float(np.sum(weights * wb.render_image(h, dtype="float64", **scene)))

    gradient = wb.image_gradient(heights, weights, **scene)
    assert gradient.shape == heights.shape
    eps = 1e-5
    for i, j in [(0, 0), (3, 7), (6, 2), (11, 11), (5, 5)]:
        plus, minus = heights.copy(), heights.copy()
        plus[i, j] += eps
        minus[i, j] -= eps
        fd = (loss(plus) - loss(minus)) / (2 * eps)
        assert gradient[i, j] == pytest.approx(fd, rel=1e-5, abs=1e-9 * np.abs(gradient).max())
    assert np.abs(gradient).max() > 0


@pytest.mark.parametrize("change, message", [
    (["--camera", "0,100,200"], "camera position 0,100,200 um is inside the sphere of radius 300 um"),
    (["--sphere-radius-um", "0"], "sphere radius 0 um is invalid"),
    (["--point-light", "0,0,-100"], "point light 0,0,-100 um is inside the sphere"),
])
def test_bad_shapes_fail_before_work(tmp_path, rng, cli, change, message, random_heightfield_exr):
    hf = random_heightfield_exr(16)
    args = list(SPHERE_CLI)
    for k in range(0, len(change), 2):
        args[args.index(change[k]) + 1] = change[k + 1]
    out = tmp_path / "bad.exr"
    r = subprocess.run([cli, "image", "--heightfield", hf, *args, "--out", str(out)], capture_output=True, text=True)
    assert r.returncode != 0 and message in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_bad_python_arguments(tmp_path, rng, random_heightfield_exr):
    hf = random_heightfield_exr(16)
    with pytest.raises(ValueError, match="cylinder radius -1 um is invalid"):
        wb.render_image(hf, cylinder_radius_um=-1, cylinder_length_um=100, camera=(0, 0, 500),
                        point_light=(0, 0, 600))
    with pytest.raises(ValueError, match="exactly one of"):
        wb.render_image(hf, plane_size_um=100, sphere_radius_um=50, camera=(0, 0, 500), point_light=(0, 0, 600))
    with pytest.raises(ValueError, match="precision"):
        wb.render_image(hf, plane_size_um=100, camera=(0, 0, 500), point_light=(0, 0, 600), precision="half")
    with pytest.raises(ValueError, match="dL_dimage"):
        wb.image_gradient(hf, np.zeros((3, 3, 3)), plane_size_um=100, camera=(0, 0, 500),
                          point_light=(0, 0, 600), resolution=4)
