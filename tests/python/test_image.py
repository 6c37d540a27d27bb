"""Camera images: wb.render_image and `wavebrdf image` give the same picture bit for bit, the EXR
says its unit, an orbit writes numbered frames, and bad scenes are refused with one line before
any work."""
import os
import subprocess

import numpy as np
import pytest

import wavebrdf as wb


SCENE = ["--plane-size-um", "400", "--camera", "-300,50,500", "--look-at", "0,0,0", "--fov-deg", "40",
         "--resolution", "12,10", "--point-light", "250,-40,400", "--spectral", "3", "--sigma-p-um", "3"]


def test_cli_and_python_bit_identical(tmp_path, rng, cli, random_heightfield_exr):
    hf = random_heightfield_exr(32)
    out = tmp_path / "i.exr"
    png = tmp_path / "i.png"
    subprocess.run([cli, "image", "--heightfield", hf, *SCENE, "--out", str(out), "--png", str(png), "--quiet"],
                   check=True)
    image = wb.render_image(hf, plane_size_um=400, camera=(-300, 50, 500), look_at=(0, 0, 0), fov_deg=40,
                            resolution=(12, 10), point_light=(250, -40, 400), spectral=3, sigma_p_um=3)
    assert image.shape == (12, 10, 3) and image.dtype == np.float32
    image_file, attributes = wb.read_slice(str(out))
    assert not attributes  # an image, not a slice: no slice attributes
    np.testing.assert_array_equal(np.asarray(image_file), image)
    assert image.max() > 0 and os.path.getsize(png) > 0


def test_orbit_writes_numbered_frames(tmp_path, rng, cli, random_heightfield_exr):
    hf = random_heightfield_exr(16)
    subprocess.run([cli, "image", "--heightfield", hf, *SCENE, "--png", str(tmp_path / "f.png"), "--frames", "3",
                    "--orbit", "light", "--start-deg", "0", "--end-deg", "90", "--quiet"], check=True)
    assert sorted(os.listdir(tmp_path)) == ["f_0000.png", "f_0001.png", "f_0002.png", "h.exr"]


@pytest.mark.parametrize("orbit", ["light", "camera"])
def test_orbit_frames_are_the_scene_turned_about_z(tmp_path, rng, cli, orbit, random_heightfield_exr):
    # Frame k of an orbit from A to B is the single image with the light (or the camera) turned
    # by A + k (B - A) / (N - 1) about the z axis, bit for bit.
    hf = random_heightfield_exr(16)
    subprocess.run([cli, "image", "--heightfield", hf, *SCENE, "--out", str(tmp_path / "f.exr"), "--frames", "3",
                    "--orbit", orbit, "--start-deg", "30", "--end-deg", "90", "--quiet"], check=True)
    light, camera = np.array([250.0, -40.0, 400.0]), np.array([-300.0, 50.0, 500.0])
    frames = []
    for k, angle in enumerate([30.0, 60.0, 90.0]):
        a = np.radians(angle)
        turn = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
        expected = wb.render_image(hf, plane_size_um=400, camera=tuple(turn @ camera if orbit == "camera" else camera),
                                   look_at=(0, 0, 0), fov_deg=40, resolution=(12, 10),
                                   point_light=tuple(turn @ light if orbit == "light" else light), spectral=3,
                                   sigma_p_um=3)
        frame = np.asarray(wb.read_slice(str(tmp_path / ("f_%04d.exr" % k)))[0])
        np.testing.assert_allclose(frame, expected, rtol=1e-5, atol=1e-6 * expected.max())
        frames.append(frame)
    assert not np.array_equal(frames[0], frames[2])  # the glints moved


@pytest.mark.parametrize("change, message", [
    (["--camera", "0,0,-5"], "camera position 0,0,-5 um is inside or below the sample"),
    (["--point-light", "0,0,-1"], "point light 0,0,-1 um is behind the sample"),
    (["--fov-deg", "0"], "field of view 0 deg is invalid"),
    (["--sigma-p-um", "1e6"], "too large for the tile"),
])
def test_bad_scenes_fail_before_work(tmp_path, rng, cli, change, message, random_heightfield_exr):
    hf = random_heightfield_exr(16)
    args = list(SCENE)
    for k in range(0, len(change), 2):
        i = args.index(change[k])
        args[i + 1] = change[k + 1]
    out = tmp_path / "bad.exr"
    r = subprocess.run([cli, "image", "--heightfield", hf, *args, "--out", str(out)], capture_output=True, text=True)
    assert r.returncode != 0 and message in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()
    with pytest.raises(ValueError, match="camera position"):
        wb.render_image(hf, plane_size_um=400, camera=(0, 0, -5), point_light=(0, 0, 100))


@pytest.mark.parametrize("extra, message", [
    (["--up", "0,0,0"], "--up 0,0,0 is invalid; expected a nonzero direction"),
    (["--frames", "3", "--start-deg", "nan"], "--start-deg nan is invalid; expected a finite angle within +-1e6"),
    (["--frames", "3", "--end-deg", "1e300"], "--end-deg 1e+300 is invalid; expected a finite angle within +-1e6"),
    (["--rotation-deg", "1e300"], "rotation 1e+300 deg is invalid"),
])
def test_bad_options_fail_before_work(tmp_path, rng, cli, extra, message, random_heightfield_exr):
    hf = random_heightfield_exr(16)
    out = tmp_path / "bad.exr"
    r = subprocess.run([cli, "image", "--heightfield", hf, *SCENE, *extra, "--out", str(out)], capture_output=True,
                       text=True)
    assert r.returncode != 0 and message in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not list(tmp_path.glob("bad*"))


def test_bad_python_vectors_fail_before_work(tmp_path, rng, random_heightfield_exr):
    hf = random_heightfield_exr(16)
    with pytest.raises(ValueError, match=r"up = \(0, 0, 0\) is invalid; expected a nonzero direction"):
        wb.render_image(hf, plane_size_um=400, camera=(0, 0, 500), point_light=(0, 0, 100), up=(0, 0, 0))
    with pytest.raises(ValueError, match=r"camera position 0,0,1e\+300 um is invalid"):
        wb.render_image(hf, plane_size_um=400, camera=(0, 0, 1e300), point_light=(0, 0, 100))


def test_missing_heightfield(tmp_path, cli):
    r = subprocess.run([cli, "image", "--heightfield", str(tmp_path / "none.exr"), *SCENE, "--out",
                        str(tmp_path / "o.exr")], capture_output=True, text=True)
    assert r.returncode != 0 and "none.exr" in r.stderr and not (tmp_path / "o.exr").exists()
