"""x3p files (ISO 25178-72) that are not a single-layer areal surface, or whose data is damaged,
are refused with one line naming the file and the reason (docs/surfaces.md, "x3p"): profiles,
point clouds, point lists, several layers, inline points, a rotated system, a data block whose
MD5 is not main.xml's. The files are a valid x3p wavebrdf writes, edited with Python's zipfile
(another program): the edit is the only difference, so each refusal is the reader's for that
reason. A valid-point mask reads as NaN where the mask says 0."""
import hashlib
import os
import re
import subprocess
import zipfile

import numpy as np
import pytest

import wavebrdf as wb

import conftest

CLI = os.path.join(conftest.BUILD, "bin", "wavebrdf")


@pytest.fixture(scope="module")
def x3p(tmp_path_factory):
    path = tmp_path_factory.mktemp("x3p") / "good.x3p"
    heights = np.arange(20.0).reshape(5, 4) * 0.01
    wb.Heightfield.from_um(heights, 0.5).save(str(path))
    return path


def rewrite(src, dst, edit_xml=None, edit_data=None, extra=None):
    """A copy of x3p `src` with main.xml and/or bindata/data.bin edited; md5checksum.hex kept."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename.endswith("main.xml") and edit_xml:
                data = edit_xml(data.decode()).encode()
            if item.filename.endswith("data.bin") and edit_data:
                data = edit_data(data)
            zout.writestr(item.filename, data)
        for name, data in (extra or {}).items():
            zout.writestr(name, data)
    return dst


def stats(path):
    return subprocess.run([CLI, "stats", str(path)], capture_output=True, text=True)


def test_the_unedited_copy_reads(x3p, tmp_path):
    r = stats(rewrite(x3p, tmp_path / "same.x3p"))
    assert r.returncode == 0, r.stderr


def sub(pattern, replacement):
    return lambda xml: re.sub(pattern, replacement, xml, count=1)


def flip_first_byte(data):
    return bytes([data[0] ^ 0x40]) + data[1:]


@pytest.mark.parametrize("edit, needles", [
    (dict(edit_xml=sub(r"<FeatureType>SUR</FeatureType>", "<FeatureType>PRF</FeatureType>")), ["'PRF'"]),
    (dict(edit_xml=sub(r"<FeatureType>SUR</FeatureType>", "<FeatureType>PCL</FeatureType>")), ["'PCL'"]),
    (dict(edit_xml=sub(r"(<CX>\s*<AxisType>)I(</AxisType>)", r"\1A\2")), ["CX", "axis type 'A'"]),
    (dict(edit_xml=sub(r"<SizeZ>1</SizeZ>", "<SizeZ>2</SizeZ>")), ["2 layers"]),
    (dict(edit_xml=sub(r"</Record3>", "<DataList><Datum>1</Datum></DataList></Record3>")), ["DataList"]),
    (dict(edit_xml=sub(r"</Axes>", "<Rotation><r11>0</r11><r12>1</r12><r13>0</r13><r21>1</r21><r22>0</r22>"
                                   "<r23>0</r23><r31>0</r31><r32>0</r32><r33>1</r33></Rotation></Axes>")),
     ["rotated"]),
    (dict(edit_data=flip_first_byte), ["MD5", "damaged"]),
], ids=["profile", "point-cloud", "point-list", "layers", "inline", "rotated", "md5"])
def test_what_is_not_one_areal_surface_is_refused_with_one_line(x3p, tmp_path, edit, needles):
    bad = rewrite(x3p, tmp_path / "bad.x3p", **edit)
    r = stats(bad)
    assert r.returncode != 0, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and str(bad) in lines[0], r.stderr
    for n in needles:
        assert n in lines[0], lines[0]


def test_a_valid_point_mask_reads_as_nan(x3p, tmp_path):
    # One bit per point, least significant first, 0 = not measured: points 0 and 9 masked.
    mask = bytearray([0xFF, 0xFF, 0xFF])
    mask[0] &= ~0x01
    mask[1] &= ~0x02
    md5 = hashlib.md5(bytes(mask)).hexdigest().upper()
    link = "<ValidPointsLink>bindata/valid.bin</ValidPointsLink><MD5ChecksumValidPoints>%s</MD5ChecksumValidPoints>" % md5
    masked = rewrite(x3p, tmp_path / "masked.x3p", edit_xml=sub(r"</DataLink>", link + "</DataLink>"),
                     extra={"bindata/valid.bin": bytes(mask)})
    out = tmp_path / "masked.npy"
    r = subprocess.run([CLI, "convert", str(masked), str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    z = np.load(out)
    nan = np.flatnonzero(np.isnan(z.ravel()))
    assert list(nan) == [0, 9]
