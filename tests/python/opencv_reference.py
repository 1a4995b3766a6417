"""OpenCV's side of tests/opencv_reference.rs: the perspective matrix, the warped frames and the
warped view mask of the perception calibration, and the HSV of every RGB colour, written as raw
bytes for the Rust test to compare with its own.

usage: opencv_reference.py WIDTH HEIGHT SRC_POINTS DST_POINTS FRAMES_RGB OUT_DIR
  SRC_POINTS, DST_POINTS: 8 comma-separated numbers (x0,y0,...,x3,y3), pixels
  FRAMES_RGB: frames of HEIGHT x WIDTH x 3 bytes, one after the other
  OUT_DIR receives matrix.f64 (9 little-endian doubles), warped.rgb, view.u8, hsv.u8
"""

import os
import sys

import cv2
import numpy as np


def points(text):
    return np.array([float(v) for v in text.split(',')], dtype=np.float32).reshape(4, 2)


def main(width, height, source, destination, frames_path, out_dir):
    width, height = int(width), int(height)
    matrix = cv2.getPerspectiveTransform(points(source), points(destination))
    matrix.astype('<f8').tofile(os.path.join(out_dir, 'matrix.f64'))
    size = (width, height)
    warp = lambda image: cv2.warpPerspective(image, matrix, size, flags=cv2.INTER_LINEAR,
                                             borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    frames = np.fromfile(frames_path, dtype=np.uint8).reshape(-1, height, width, 3)
    with open(os.path.join(out_dir, 'warped.rgb'), 'wb') as out:
        for frame in frames:
            out.write(np.ascontiguousarray(warp(frame)).tobytes())
    warp(np.ones((height, width), dtype=np.uint8)).tofile(os.path.join(out_dir, 'view.u8'))
    channel = np.arange(256, dtype=np.uint8)
    every_colour = np.stack(np.meshgrid(channel, channel, channel, indexing='ij'), axis=-1).reshape(4096, 4096, 3)
    cv2.cvtColor(every_colour, cv2.COLOR_RGB2HSV).tofile(os.path.join(out_dir, 'hsv.u8'))


if __name__ == '__main__':
    if len(sys.argv) != 7:
        sys.exit(__doc__)
    main(*sys.argv[1:])
