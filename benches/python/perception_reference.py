#!/usr/bin/env python3
"""The usual Python perception of the Udacity project, timed on the recorded frames: the baseline of
benches/perception.rs. Per frame: decode the JPEG (cv2), warp the image and the field-of-view mask
(cv2.warpPerspective), threshold navigable (RGB > 160), obstacle and rock (R > 110, G > 110, B < 50),
convert the pixels to rover and world coordinates and add them to the 200x200x3 world map, and
compute the mean angle of the navigable pixels.

Usage: perception_reference.py DATASET_DIR [--passes N]   (prints one JSON object)
"""
import argparse
import glob
import json
import os
import time

import cv2
import numpy as np


def warp_matrix():
    source = np.float32([[14, 140], [301, 140], [200, 96], [118, 96]])
    destination = np.float32([[155, 154], [165, 154], [165, 144], [155, 144]])
    return cv2.getPerspectiveTransform(source, destination)


def to_world(xpix, ypix, x, y, yaw_deg):
    yaw = np.radians(yaw_deg)
    xr = xpix * np.cos(yaw) - ypix * np.sin(yaw)
    yr = xpix * np.sin(yaw) + ypix * np.cos(yaw)
    xw = np.clip(np.int_(xr / 10 + x), 0, 199)
    yw = np.clip(np.int_(yr / 10 + y), 0, 199)
    return xw, yw


def perceive(jpeg, pose, matrix, worldmap):
    image = cv2.cvtColor(cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    warped = cv2.warpPerspective(image, matrix, (320, 160))
    mask = cv2.warpPerspective(np.ones_like(image[:, :, 0]), matrix, (320, 160))
    navigable = (warped[:, :, 0] > 160) & (warped[:, :, 1] > 160) & (warped[:, :, 2] > 160)
    obstacle = (~navigable) & (mask == 1)
    rock = (warped[:, :, 0] > 110) & (warped[:, :, 1] > 110) & (warped[:, :, 2] < 50)
    angles = 0.0
    for channel, selected in ((2, navigable), (0, obstacle), (1, rock)):
        ypos, xpos = selected.nonzero()
        xpix = -(ypos - 160).astype(np.float64)
        ypix = -(xpos - 160).astype(np.float64)
        xw, yw = to_world(xpix, ypix, *pose)
        worldmap[yw, xw, channel] += 1
        if channel == 2 and len(xpix):
            angles = float(np.mean(np.arctan2(ypix, xpix)))
    return angles


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('dataset')
    parser.add_argument('--passes', type=int, default=3)
    args = parser.parse_args()
    rows = open(os.path.join(args.dataset, 'robot_log.csv')).read().splitlines()[1:]
    frames = []
    for row in rows:
        cells = row.split(';')
        with open(os.path.join(args.dataset, 'IMG', os.path.basename(cells[0])), 'rb') as f:
            frames.append((f.read(), (float(cells[5]), float(cells[6]), float(cells[8]))))
    matrix = warp_matrix()
    times = []
    for _ in range(args.passes):
        worldmap = np.zeros((200, 200, 3), np.float64)
        for jpeg, pose in frames:
            started = time.perf_counter()
            perceive(jpeg, pose, matrix, worldmap)
            times.append(time.perf_counter() - started)
    times.sort()
    print(json.dumps({'frames': len(frames), 'passes': args.passes, 'median_ms': 1000 * times[len(times) // 2],
                      'opencv': cv2.__version__, 'numpy': np.__version__}))


if __name__ == '__main__':
    main()
