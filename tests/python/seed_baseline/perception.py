"""Perception of the seed baseline: camera image -> rover-centric terrain and rock bearings, plus the
Udacity-style world map.

Re-implements the perception described in Shane Reynolds' report "Udacity: Search and Sample
Return" (2018), section 2.2/2.3.1 and appendix A: a fixed bird's-eye warp, RGB thresholds for
terrain (> 165) and obstacles (not > 135), an HSV band for the golden samples, a "blind cone"
mask that keeps the unseen part of the warp out of the obstacle layer, a rotate / scale / translate
into the 200 x 200 world grid, and the switch into the rock-approach mode when more than 20 rock
pixels are in view. There is no pitch/roll filtering in that design, so none here either.
"""
import cv2
import numpy as np

# --- camera calibration (Udacity starter grid, 1 m squares) --------------------------------------
IMAGE_H, IMAGE_W = 160, 320
# Half the side of the 1 m square in the warped image (so 10 px = 1 m) and its gap to the bottom.
DST_HALF = 5
DST_BOTTOM_GAP = 6
SOURCE_POINTS = np.float32([[14, 140], [301, 140], [200, 96], [118, 96]])
TARGET_POINTS = np.float32([
    [IMAGE_W / 2 - DST_HALF, IMAGE_H - DST_BOTTOM_GAP],
    [IMAGE_W / 2 + DST_HALF, IMAGE_H - DST_BOTTOM_GAP],
    [IMAGE_W / 2 + DST_HALF, IMAGE_H - DST_BOTTOM_GAP - 2 * DST_HALF],
    [IMAGE_W / 2 - DST_HALF, IMAGE_H - DST_BOTTOM_GAP - 2 * DST_HALF],
])
# The homography never changes, so it is computed once instead of on every frame.
WARP = cv2.getPerspectiveTransform(SOURCE_POINTS, TARGET_POINTS)

WORLD_SIZE = 200        # world grid cells per side, 1 cell = 1 m
PX_PER_M = 10           # warped pixels per metre

# --- thresholds of the report -----------------------------------------------------------------------
TERRAIN_MIN_RGB = (165, 165, 165)   # navigable: every channel strictly above
OBSTACLE_MIN_RGB = (135, 135, 135)  # obstacle: NOT every channel above this
# Rock band in OpenCV HSV (H 0..180). The appendix code (what the report's rover ran) uses these;
# its section 2.2.3 snippet shows a wider band, kept here for reference.
ROCK_HSV_LOW = np.array([0, 120, 120])
ROCK_HSV_HIGH = np.array([40, 255, 255])
ROCK_HSV_LOW_SECTION_2_2_3 = np.array([0, 100, 110])
ROCK_HSV_HIGH_SECTION_2_2_3 = np.array([70, 255, 255])
ROCK_PIXELS_TO_APPROACH = 20        # more than this many rock pixels -> rock-approach mode

# Map update amounts (report, listing 10): obstacles accumulate, terrain and rocks saturate.
OBSTACLE_INCREMENT = 2
SATURATED = 255


def rgb_above(image, minimum):
    """Boolean mask of pixels whose R, G and B all exceed the given minimum."""
    return ((image[:, :, 0] > minimum[0])
            & (image[:, :, 1] > minimum[1])
            & (image[:, :, 2] > minimum[2]))


def birds_eye(image):
    """Warps a camera-sized image to the top-down view (same size; unseen areas come out 0)."""
    return cv2.warpPerspective(image, WARP, (IMAGE_W, IMAGE_H))


def rover_frame(mask):
    """Pixel coordinates of a top-down mask in the rover frame: x ahead, y to the left, origin at
    the bottom centre of the image, in warped pixels."""
    rows, cols = np.nonzero(mask)
    ahead = (IMAGE_H - rows).astype(np.float64)
    left = (IMAGE_W / 2 - cols).astype(np.float64)
    return ahead, left


def polar(ahead, left):
    """Distances (px) and bearings (rad, positive left) of rover-frame pixels."""
    return np.hypot(ahead, left), np.arctan2(left, ahead)


def to_world_cells(ahead, left, x_m, y_m, yaw_deg):
    """Rover-frame pixels -> integer world cells (column x, row y), truncated and clipped to the
    grid, as the starter's pix_to_world does."""
    yaw = np.deg2rad(yaw_deg)
    cos_yaw, sin_yaw = np.cos(yaw), np.sin(yaw)
    world_x = (ahead * cos_yaw - left * sin_yaw) / PX_PER_M + x_m
    world_y = (ahead * sin_yaw + left * cos_yaw) / PX_PER_M + y_m
    # int conversion truncates toward zero (np.int_ in the original), then clip into the grid.
    cols = np.clip(world_x.astype(np.int64), 0, WORLD_SIZE - 1)
    rows = np.clip(world_y.astype(np.int64), 0, WORLD_SIZE - 1)
    return cols, rows


def segment(camera):
    """Splits one RGB camera frame into top-down terrain, obstacle and rock masks (booleans)."""
    top = birds_eye(camera)
    terrain = rgb_above(top, TERRAIN_MIN_RGB)

    hsv = cv2.cvtColor(top, cv2.COLOR_RGB2HSV)
    rock = cv2.inRange(hsv, ROCK_HSV_LOW, ROCK_HSV_HIGH) > 0

    # "Dark" pixels of the warp; this includes everything outside the camera's field of view,
    # because the warp fills the unseen area with black.
    dark = ~rgb_above(top, OBSTACLE_MIN_RGB)

    # Blind cone: threshold the *camera* image first, warp the non-terrain layer, and every warped
    # pixel that comes out 0 is either seen terrain or never seen at all. Those pixels are removed
    # from the dark layer, which leaves only what the camera actually saw as not-terrain.
    non_terrain_seen = birds_eye((~rgb_above(camera, TERRAIN_MIN_RGB)).astype(np.uint8))
    blind_or_terrain = (non_terrain_seen == 0) & dark

    # The report subtracts the cone and rock layers from the dark layer as integers and keeps
    # every non-zero result; doing the same arithmetic keeps its (rare) -1 cells as obstacles.
    obstacle = (dark.astype(np.int16) - blind_or_terrain - rock) != 0
    return terrain, obstacle, rock


def perceive(rover):
    """One perception step on `rover` (a decision.RoverState): updates its world map, vision image,
    terrain bearings and, when a rock is in view, switches it into the rock-approach mode."""
    terrain, obstacle, rock = segment(rover.img)

    # What the Unity screen shows on the left: obstacles red, rocks green, terrain blue.
    rover.vision_image[:, :, 0] = obstacle * SATURATED
    rover.vision_image[:, :, 1] = rock * SATURATED
    rover.vision_image[:, :, 2] = terrain * SATURATED

    x_m, y_m = rover.pos
    terrain_px = rover_frame(terrain)
    obstacle_px = rover_frame(obstacle)
    rock_px = rover_frame(rock)
    terrain_cols, terrain_rows = to_world_cells(*terrain_px, x_m, y_m, rover.yaw)
    obstacle_cols, obstacle_rows = to_world_cells(*obstacle_px, x_m, y_m, rover.yaw)
    rock_cols, rock_rows = to_world_cells(*rock_px, x_m, y_m, rover.yaw)

    # Map update in the report's order: obstacles build up slowly, whatever is seen as terrain now
    # clears the obstacle layer; rocks saturate; seen obstacles clear the terrain layer and then the
    # terrain seen now saturates it (so terrain wins a cell both layers claim in one frame).
    world = rover.worldmap
    world[obstacle_rows, obstacle_cols, 0] += OBSTACLE_INCREMENT
    world[terrain_rows, terrain_cols, 0] = 0
    world[rock_rows, rock_cols, 1] = SATURATED
    world[obstacle_rows, obstacle_cols, 2] = 0
    world[terrain_rows, terrain_cols, 2] = SATURATED

    # Rock in view (and not busy backing out): approach it and reset the lost-sight counter.
    # Rock lost while approaching: count the frames without it and steer straight meanwhile.
    if int(rock.sum()) > ROCK_PIXELS_TO_APPROACH and rover.mode != 'stuck':
        rover.mode = 'rocking'
        rover.rock_spot_count = 0
        rover.rock_dists, rover.rock_angles = polar(*rock_px)
    elif rover.mode == 'rocking':
        rover.rock_spot_count += 1
        rover.rock_angles = 0

    # Terrain bearings drive the steering in every mode.
    rover.nav_dists, rover.nav_angles = polar(*terrain_px)
    return rover
