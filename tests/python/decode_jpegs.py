"""Decodes JPEG files as the Python tools of the Udacity project do, for tests/jpeg_python.rs.

Usage: decode_jpegs.py OUT_PIL OUT_CV2 JPEG...
Writes the RGB bytes of every JPEG, one after the other, as PIL (Image.open().convert("RGB")) and
as OpenCV (cv2.imread, BGR turned to RGB) decode them.
"""

import sys

import cv2
import numpy as np
from PIL import Image


def main():
    out_pil, out_cv2, paths = sys.argv[1], sys.argv[2], sys.argv[3:]
    with open(out_pil, "wb") as pil, open(out_cv2, "wb") as opencv:
        for path in paths:
            pil.write(np.asarray(Image.open(path).convert("RGB")).tobytes())
            opencv.write(cv2.cvtColor(cv2.imread(path), cv2.COLOR_BGR2RGB).tobytes())


if __name__ == "__main__":
    main()
