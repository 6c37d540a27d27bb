#!/usr/bin/python3
"""Score a design's heights.png (16-bit, 0 ... TOP um) over the band with am3_band.py's NumPy exact
scalar diffraction, each texel snapped to the nearest of the given levels (unequal levels too).
Usage: am4_score_png.py DIR/heights.png TOP_UM h0,h1,...,h7"""
import sys, numpy as np
from PIL import Image
sys.path.insert(0, __import__('os').path.dirname(__import__('os').path.abspath(__file__)))
import am3_band as am
img = Image.open(sys.argv[1]); top = float(sys.argv[2]); levels = np.array([float(x) for x in sys.argv[3].split(',')])
v = np.asarray(img, dtype=float) / 65535.0 * top
h = levels[np.abs(v[..., None] - levels).argmin(-1)]
print('max snap error um', np.abs(h - v).max(), 'texels', h.shape)
am.print_score(sys.argv[1], h, 0.5)
