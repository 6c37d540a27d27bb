"""report.png of a design run (wavebrdf.report_design), drawn from a synthetic run directory
written here: design.json by hand, the pictures by a minimal EXR writer of this file's own (an
independent writer of the format), heights.exr through Heightfield.save_exr."""
import json
import os
import struct
import subprocess
import sys

import numpy as np
import pytest

import wavebrdf as wb

matplotlib = pytest.importorskip("matplotlib")

PY_DIR = os.path.dirname(os.path.dirname(os.path.abspath(wb.__file__)))


def write_rgb_exr(path, rgb):
    """An uncompressed scanline OpenEXR of float R, G, B (OpenEXR file layout 2.0)."""
    rows, cols, _ = rgb.shape

    def attribute(name, kind, data):
        return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(data)) + data

    channels = b"".join(c.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for c in "BGR") + b"\0"
    box = struct.pack("<iiii", 0, 0, cols - 1, rows - 1)
    header = (attribute("channels", "chlist", channels) + attribute("compression", "compression", b"\0") +
              attribute("dataWindow", "box2i", box) + attribute("displayWindow", "box2i", box) +
              attribute("lineOrder", "lineOrder", b"\0") + attribute("pixelAspectRatio", "float", struct.pack("<f", 1)) +
              attribute("screenWindowCenter", "v2f", struct.pack("<ff", 0, 0)) +
              attribute("screenWindowWidth", "float", struct.pack("<f", 1)) + b"\0")
    start = 8 + len(header) + 8 * rows
    line_bytes = 4 * 3 * cols
    blob = bytearray(b"\x76\x2f\x31\x01" + struct.pack("<i", 2) + header)
    blob += b"".join(struct.pack("<Q", start + y * (8 + line_bytes)) for y in range(rows))
    for y in range(rows):
        blob += struct.pack("<ii", y, line_bytes)
        for c in (2, 1, 0):  # B, G, R: channels in name order
            blob += rgb[y, :, c].astype("<f4").tobytes()
    with open(path, "wb") as f:
        f.write(bytes(blob))


def design_doc(kind="colour"):
    exact = {"delta_uv": 0.021, "luminous_efficiency": 0.12, "uv": [0.2, 0.5], "target_uv": [0.21, 0.51],
             "linear_srgb": [0.8, 0.1, 0.05], "reflectance": [0.5, 0.4]}
    return {
        "kind": "design",
        "target": {"kind": kind, "text": "colour:#ff2010", "srgb8": [255, 32, 16], "linear_rgb": [1.0, 0.014, 0.005],
                   "view": [0.0, 0.0], "view_cone": 0.05},
        "constraints": {"size": 16, "texel_um": 0.5, "height_range_um": 2.0, "levels": 4},
        "levels_um": [0.0, 2.0 / 3, 4.0 / 3, 2.0],
        "metrics": {"model": dict(exact, delta_uv=0.018), "exact": exact, "final_loss": 0.01},
        "fabrication_errors": [{"error": "scale 0.95", "metrics": dict(exact, delta_uv=0.03)},
                               {"error": "blur 0.3 um", "metrics": dict(exact, delta_uv=0.05)}],
        "notes": ["a note"],
        "timings_s": {"total": 12.5},
    }


def make_run(d, doc=None, heights=True, pictures=True, csv=True):
    os.makedirs(d, exist_ok=True)
    if doc is not False:
        with open(os.path.join(d, "design.json"), "w") as f:
            json.dump(design_doc() if doc is None else doc, f)
    rng = np.random.default_rng(3)
    if heights:
        levels = rng.integers(0, 4, size=(16, 16))
        levels[0, 0] = 3
        levels[:, 1] = 1  # level 1 on 16 texels at least, so the histogram's counts are known below
        h_um = levels * (2.0 / 3)
        wb.Heightfield(h_um / 0.5, texel_um=0.5).save_exr(os.path.join(d, "heights.exr"))
    if pictures:
        n = 24
        y, x = np.mgrid[0:n, 0:n]
        blob = np.exp(-((x - 12) ** 2 + (y - 12) ** 2) / 20.0)
        write_rgb_exr(os.path.join(d, "target.exr"), np.stack([blob, 0.1 * blob, 0.0 * blob], axis=2))
        write_rgb_exr(os.path.join(d, "far_field.exr"), np.stack([0.8 * blob, 0.2 * blob, 0.1 * blob], axis=2))
    if csv:
        with open(os.path.join(d, "metrics.csv"), "w") as f:
            f.write("iteration,loss,phase,temperature\n")
            for i in range(30):
                f.write("%d,%g,%s,%g\n" % (i, 1.0 / (1 + i), "relaxed" if i < 20 else "refine", 0.5))
    return d


def run_report(d):
    env = dict(os.environ, PYTHONPATH=PY_DIR + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-m", "wavebrdf.report", d], capture_output=True, text=True, env=env)


def test_minimal_exr_writer_is_read_back_exactly(tmp_path):
    # The test's own EXR writer against the library's reader, so the pictures below are what
    # the report reads.
    rgb = np.random.default_rng(1).random((5, 7, 3)).astype(np.float32)
    write_rgb_exr(str(tmp_path / "x.exr"), rgb)
    image, _ = wb.read_slice(str(tmp_path / "x.exr"))
    np.testing.assert_array_equal(np.asarray(image), rgb)


def test_design_report_is_drawn(tmp_path):
    d = make_run(str(tmp_path / "run"))
    r = run_report(d)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == os.path.join(d, "report.png")
    from PIL import Image

    im = Image.open(os.path.join(d, "report.png"))
    assert im.size[0] > 1000 and im.size[1] > 500
    assert not [f for f in os.listdir(d) if f.endswith(".tmp")]


def test_metrics_table_and_histogram_read_the_run(tmp_path):
    from wavebrdf import report_design

    d = make_run(str(tmp_path / "run"))
    names, columns = report_design.metrics_rows(report_design.read_design_json(d))
    assert [c for c, _ in columns] == ["design model", "exact scalar", "scale 0.95", "blur 0.3 um"]
    assert names[0] == "delta_uv" and "luminous_efficiency" in names
    assert [m["delta_uv"] for _, m in columns] == [0.018, 0.021, 0.03, 0.05]
    h = report_design.read_heights_um(d)
    assert h.shape == (16, 16)
    # heights.exr holds texel units with texel_um 0.5: back in µm on the levels.
    np.testing.assert_allclose(np.sort(np.unique(np.round(h, 9))), [0.0, 2 / 3, 4 / 3, 2.0], atol=1e-6)
    curve = report_design.read_loss_curve(d)
    assert list(curve["iteration"][:3]) == [0, 1, 2] and curve["phase"][25] == "refine"


def test_linear_to_srgb_swatch():
    from wavebrdf import report_design

    np.testing.assert_allclose(report_design.linear_to_srgb([1.0, 0.0, 0.0]), [1.0, 0.0, 0.0])
    # Mid grey 0.2140 linear is sRGB 0.5 (IEC 61966-2-1), after normalising the largest channel to 1.
    np.testing.assert_allclose(report_design.linear_to_srgb([2.0, 0.428, 0.428]), [1.0, 0.5, 0.5], atol=1e-3)
    np.testing.assert_array_equal(report_design.linear_to_srgb([0.0, 0.0, 0.0]), [0.0, 0.0, 0.0])


def test_absent_optional_files_and_keys_still_draw(tmp_path):
    doc = {"target": {"kind": "anti-mirror"}}  # no metrics, no constraints, no levels
    d = make_run(str(tmp_path / "sparse"), doc=doc, heights=False, pictures=False, csv=False)
    r = run_report(d)
    assert r.returncode == 0, r.stderr
    assert os.path.exists(os.path.join(d, "report.png"))
    # A grayscale design without levels_um: the plain histogram.
    doc = design_doc("anti-mirror")
    del doc["levels_um"]
    del doc["target"]["linear_rgb"]
    d = make_run(str(tmp_path / "grey"), doc=doc)
    r = run_report(d)
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("damage", ["bad_json", "array_json", "truncated_exr", "bad_csv", "no_design_json"])
def test_unusable_files_give_one_line_and_exit_2(tmp_path, damage):
    d = make_run(str(tmp_path / damage))
    if damage == "bad_json":
        with open(os.path.join(d, "design.json"), "w") as f:
            f.write('{"target": ')
    elif damage == "array_json":
        with open(os.path.join(d, "design.json"), "w") as f:
            f.write("[1, 2]")
    elif damage == "truncated_exr":
        path = os.path.join(d, "far_field.exr")
        with open(path, "rb") as f:
            data = f.read()
        with open(path, "wb") as f:
            f.write(data[: len(data) // 2])
    elif damage == "bad_csv":
        with open(os.path.join(d, "metrics.csv"), "a") as f:
            f.write("31,not-a-number,refine,0.5\n")
    elif damage == "no_design_json":
        os.unlink(os.path.join(d, "design.json"))
    r = run_report(d)
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("wavebrdf.report: error: "), r.stderr
    expected = {"bad_json": "design.json", "array_json": "design.json", "truncated_exr": "far_field.exr",
                "bad_csv": "metrics.csv", "no_design_json": "design.json"}[damage]
    assert expected in lines[0]
    assert not os.path.exists(os.path.join(d, "report.png"))


def test_iridescent_pairs_are_drawn_as_swatches(tmp_path):
    # Each pair's target colour above what exact scalar diffraction reaches: pixels of those
    # colours appear in the picture (a pure red target, a pure blue reached colour).
    doc = design_doc("iridescent")
    doc["target"] = {"kind": "iridescent", "text": "iridescent:spec.json", "view_cone": 0.05,
                     "pairs": [{"view": [0.2, 0.0], "srgb8": [255, 0, 0], "linear_rgb": [1.0, 0.0, 0.0]},
                               {"view": [-0.2, 0.0], "srgb8": [0, 255, 0], "linear_rgb": [0.0, 1.0, 0.0]}]}
    pair = {"delta_uv": 0.01, "luminous_efficiency": 0.05, "linear_srgb": [0.0, 0.0, 1.0]}
    doc["metrics"]["exact"] = {"delta_uv": [0.01, 0.01], "pairs": [pair, pair]}
    d = make_run(str(tmp_path / "iri"), doc=doc)
    r = run_report(d)
    assert r.returncode == 0, r.stderr
    from PIL import Image

    im = np.asarray(Image.open(os.path.join(d, "report.png")).convert("RGB")).astype(int)
    for colour in ([255, 0, 0], [0, 255, 0], [0, 0, 255]):
        assert (np.abs(im - colour).sum(axis=2) < 10).sum() > 500, colour


def test_the_brightness_trade_is_in_the_colour_text(tmp_path, monkeypatch):
    from wavebrdf import report_design

    doc = design_doc("colour")
    assert report_design.brightness_trade_text(doc) is None  # no trade in the run
    doc["brightness_trade"] = {"blocks": 0, "ceiling": 0.04, "tolerance_used": 0.0, "model_y_before": 0.2,
                               "model_y_after": 0.2}
    assert report_design.brightness_trade_text(doc) is None  # a bright colour: no block ran
    doc["brightness_trade"].update(blocks=3, tolerance_used=0.03, model_y_before=0.0336, model_y_after=0.0579)
    text = report_design.brightness_trade_text(doc)
    assert text == "brightness trade: 3 blocks, Δu′v′ tolerance 0.03 (ceiling 0.04): loop's Y 3.4% → 5.8%"
    # The drawn figure holds that line (its texts read back from the figure before it is saved).
    drawn = []
    monkeypatch.setattr(report_design, "save_figure",
                        lambda fig, path, dpi: drawn.extend(t.get_text() for t in fig.findobj(matplotlib.text.Text)))
    report_design.make_report(make_run(str(tmp_path / "traded"), doc=doc))
    assert any(text in t.replace("\n  ", " ") for t in drawn), drawn
    # An iridescent run's values are per pair.
    doc["brightness_trade"].update(blocks=1, tolerance_used=[0.01, 0.0], model_y_before=[0.021, 0.06],
                                   model_y_after=[0.03, 0.055])
    assert report_design.brightness_trade_text(doc) == ("brightness trade per pair: 1 block, Δu′v′ tolerance "
                                                        "0.01/0 (ceiling 0.04): loop's Y 2.1/6.0% → 3.0/5.5%")
    doc["brightness_trade"]["model_y_after"] = "damaged"
    assert report_design.brightness_trade_text(doc) is None


def drawn_texts(monkeypatch, report_design, directory):
    """The texts of the figure make_report draws for `directory`, read back from the figure
    before it is saved (newlines of the report's wrapping undone)."""
    drawn = []
    monkeypatch.setattr(report_design, "save_figure",
                        lambda fig, path, dpi: drawn.extend(t.get_text() for t in fig.findobj(matplotlib.text.Text)))
    report_design.make_report(directory)
    return [t.replace("\n  ", " ") for t in drawn]


def test_a_run_with_a_warning_puts_it_on_the_report(cli, tmp_path, monkeypatch):
    # A real run whose exported relief breaks a limit no relief keeps (16 bins exactly even):
    # design.json's warnings, each word of each, are on the report's warnings panel.
    from wavebrdf import report_design

    out = tmp_path / "run"
    subprocess.run([cli, "design", "--out", str(out), "--size", "16", "--spectral", "3", "--band-um", "0.45,0.65",
                    "--levels", "4", "--height-range-um", "1", "--iterations", "8", "--refine-passes", "4",
                    "--seed", "7", "--uniformity-limit", "0.001", "--quiet", "--no-plots"], check=True,
                   capture_output=True)
    warnings = report_design.read_design_json(str(out))["warnings"]
    assert warnings and any("--uniformity-limit" in w for w in warnings)
    texts = drawn_texts(monkeypatch, report_design, str(out))
    panel = [t for t in texts if t.startswith("warning: ")]
    assert len(panel) == 1, texts
    assert panel[0].split("\n") == ["warning: " + w for w in warnings]
    # The same run's relief with no warnings in design.json draws no panel.
    doc = report_design.read_design_json(str(out))
    doc["warnings"] = []
    (out / "design.json").write_text(json.dumps(doc))
    assert not [t for t in drawn_texts(monkeypatch, report_design, str(out)) if "warning" in t]


def test_warnings_lines_keep_every_warning():
    from wavebrdf import report_design

    doc = design_doc()
    assert report_design.warnings_lines(doc) == []
    long = "the region's uniformity 0.312 at 0.69 um is above --uniformity-limit 0.25 " * 4
    doc["warnings"] = ["short one", long.strip(), {"odd": 1}]
    lines = report_design.warnings_lines(doc)
    assert len(lines) == 3 and lines[0] == "short one"
    assert "\n" in lines[1] and lines[1].replace("\n  ", " ") == long.strip()
    assert all(len(x) <= 182 for x in lines[1].split("\n"))
    assert lines[2] == '{"odd": 1}'


def test_an_anti_mirrors_step_survey_is_read_and_drawn(tmp_path):
    # design.json's step_survey (the anti-mirror's level steps, each with the region it reached)
    # as the report reads it, and a report drawn with it; a malformed entry is left out.
    from wavebrdf import report_design

    doc = design_doc("anti-mirror")
    doc["target"] = {"kind": "anti-mirror", "text": "anti-mirror"}
    doc["step_survey"] = {"size": 32, "iterations": 200, "refine_passes": 60, "chosen_um": 0.11,
                          "steps": [{"step_um": 0.153, "region_fraction_mean": 0.83, "limits_met": True},
                                    {"step_um": 0.11, "region_fraction_mean": 0.85, "limits_met": True},
                                    {"step_um": 0.12, "region_fraction_mean": 0.81, "limits_met": False},
                                    {"step_um": "x", "region_fraction_mean": 0.9}]}
    doc["level_step"] = {"start_um": 0.11, "final_um": 0.1112}
    assert report_design.survey_points(doc) == [(0.153, 0.83, True), (0.11, 0.85, True), (0.12, 0.81, False)]
    assert report_design.survey_points(design_doc()) == []
    d = make_run(str(tmp_path / "run"), doc=doc)
    r = run_report(d)
    assert r.returncode == 0, r.stderr
    assert os.path.getsize(os.path.join(d, "report.png")) > 10000
