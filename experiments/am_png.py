"""Minimal reader of the design's heights.png (16-bit grey, non-interlaced) and its scale chunk,
so the study scripts need no imaging package."""
import struct, zlib
import numpy as np


def read_heights_png(path):
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, texts = 8, b"", {}
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert depth == 16 and ctype == 0 and interlace == 0, (depth, ctype, interlace)
        elif kind == b"IDAT":
            idat += body
        elif kind in (b"tEXt", b"iTXt"):
            k, _, v = body.partition(b"\0")
            texts[k.decode()] = v
        pos += 12 + n
    raw = zlib.decompress(idat)
    bpp, stride = 2, 2 * w
    out = np.zeros((h, stride), np.uint8)
    prev = np.zeros(stride, np.int32)
    for r in range(h):
        f = raw[r * (stride + 1)]
        line = np.frombuffer(raw, np.uint8, stride, r * (stride + 1) + 1).astype(np.int32)
        cur = np.zeros(stride, np.int32)
        for i in range(stride):
            a = cur[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if f == 0: x = 0
            elif f == 1: x = a
            elif f == 2: x = b
            elif f == 3: x = (a + b) // 2
            else:
                p = a + b - c; pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                x = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            cur[i] = (line[i] + x) & 255
        out[r] = cur
        prev = cur
    v = out.reshape(h, w, 2)
    return (v[..., 0].astype(np.int64) << 8 | v[..., 1]), texts
