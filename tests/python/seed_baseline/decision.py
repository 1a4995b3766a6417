"""Decision of the seed baseline: a four-mode state machine (forward, stop, stuck, rocking) that
turns the perception output into throttle / brake / steering and a pickup request.

Re-implements the decision tree described in Shane Reynolds' report "Udacity: Search and Sample
Return" (2018), section 2.3.2 and appendix C. Every counter is in processed frames, as in the
report (the Unity simulator ran at about 36 frames/s; the headless one steps 0.04 s per command).
"""
import numpy as np

# --- tuning of the report -------------------------------------------------------------------------
THROTTLE_SET = 0.2       # throttle while cruising
BRAKE_SET = 10           # brake when stopping
STOP_FORWARD = 50        # fewer terrain pixels than this -> stop
GO_FORWARD = 500         # at least this many terrain pixels while stopped -> go
MAX_VEL = 2.0            # m/s, cruise cap
MAX_STEER = 15.0         # degrees

MOVING_SPEED = 0.08      # above this the stationary counter is cleared
STILL_SPEED = 0.05       # below this a frame counts as stationary
STILL_FRAMES = 400       # stationary frames (while driving) before backing out
BACKOUT_FRAMES = 300     # frames spent reversing in the stuck mode
BACKOUT_THROTTLE = -0.1
ROCK_LOST_FRAMES = 200   # frames without the rock in view before giving up the approach
ROCK_APPROACH_VEL = 0.5  # m/s, creep speed towards a rock
ROCK_THROTTLE = 0.1
STOP_BRAKING_SPEED = 0.2  # the stop mode keeps braking above this speed
SPIN_STEER = -15.0       # stopped without a way ahead: four-wheel turn to the right (clockwise)

WORLD_SIZE = 200


class RoverState:
    """Everything the controller remembers between frames (the starter's RoverState)."""

    def __init__(self):
        # telemetry
        self.img = None
        self.pos = (0.0, 0.0)
        self.yaw = 0.0
        self.pitch = 0.0
        self.roll = 0.0
        self.vel = 0.0
        self.steer = 0.0          # re-read from telemetry every frame
        self.throttle = 0.0       # re-read from telemetry every frame
        self.brake = 0.0          # kept from the last decision (the starter never reads it back)
        self.near_sample = 0
        self.picking_up = 0
        self.samples_pos = None   # (xs, ys) of the samples in the first telemetry, truncated
        self.samples_to_find = 0
        self.samples_collected = 0
        # perception output
        self.nav_angles = None
        self.nav_dists = None
        self.rock_angles = None
        self.rock_dists = None
        self.vision_image = np.zeros((160, 320, 3), dtype=np.float64)
        self.worldmap = np.zeros((WORLD_SIZE, WORLD_SIZE, 3), dtype=np.float64)
        # decision state
        self.mode = 'forward'
        self.vel_count = 0        # consecutive-ish stationary frames while trying to drive
        self.stuck_count = 0      # frames spent backing out
        self.rock_spot_count = 0  # frames since the rock was last in view
        self.send_pickup = False


def _mean_bearing_deg(angles):
    """Mean bearing of a set of pixel angles (rad) in degrees, limited to the steering range."""
    return float(np.clip(np.mean(np.asarray(angles) * 180.0 / np.pi), -MAX_STEER, MAX_STEER))


def _count_stillness(rover):
    """Counts a stationary frame; after STILL_FRAMES of them the rover starts backing out."""
    if abs(rover.vel) < STILL_SPEED:
        rover.vel_count += 1
        if rover.vel_count > STILL_FRAMES:
            rover.vel_count = 0
            rover.stuck_count = 0
            rover.throttle = 0
            rover.brake = 0
            rover.steer = 0
            rover.mode = 'stuck'


def _forward(rover):
    if abs(rover.vel) > MOVING_SPEED:
        rover.vel_count = 0
    if len(rover.nav_angles) >= STOP_FORWARD:
        if rover.vel < MAX_VEL:
            # Below the cap: keep the throttle on (the brake is left as it was) and watch for a
            # rover that pushes without moving.
            rover.throttle = THROTTLE_SET
            _count_stillness(rover)
        else:
            # At the cap: coast.
            rover.throttle = 0
            rover.brake = 0
        # Low-pass the steering: two parts the current wheel angle, one part the terrain bearing.
        rover.steer = (2 * rover.steer + _mean_bearing_deg(rover.nav_angles)) / 3
    else:
        # Too little terrain ahead: brake hard and switch to the stop mode.
        rover.throttle = 0
        rover.brake = BRAKE_SET
        rover.steer = 0
        rover.mode = 'stop'


def _rocking(rover):
    if abs(rover.vel) > MOVING_SPEED:
        rover.vel_count = 0
    if rover.rock_spot_count > ROCK_LOST_FRAMES:
        # The rock has been out of sight too long: back to exploring (controls unchanged this frame).
        rover.mode = 'forward'
        return
    if rover.vel < ROCK_APPROACH_VEL:
        # Creep towards the rock, with the same stationary watchdog as the forward mode.
        rover.throttle = ROCK_THROTTLE
        rover.brake = 0
        _count_stillness(rover)
    else:
        rover.throttle = 0
    # Aim at the rock (bearing 0, i.e. straight, while it is out of sight).
    rover.steer = _mean_bearing_deg(rover.rock_angles)
    # Within reach of the arm: stop so that the pickup can be requested.
    if rover.near_sample:
        rover.throttle = 0
        rover.brake = BRAKE_SET


def _stop(rover):
    if rover.vel > STOP_BRAKING_SPEED:
        # Still rolling: keep braking.
        rover.throttle = 0
        rover.brake = BRAKE_SET
        rover.steer = 0
        return
    if len(rover.nav_angles) < GO_FORWARD:
        # Not enough open ground: release the brake and spin in place.
        rover.throttle = 0
        rover.brake = 0
        rover.steer = SPIN_STEER
    else:
        # Enough open ground: drive off along the mean bearing.
        rover.throttle = THROTTLE_SET
        rover.brake = 0
        rover.steer = _mean_bearing_deg(rover.nav_angles)
        rover.mode = 'forward'


def _stuck(rover):
    # Reverse straight for a fixed number of frames, then try forward again.
    rover.stuck_count += 1
    rover.steer = 0
    rover.throttle = BACKOUT_THROTTLE
    rover.brake = 0
    if rover.stuck_count > BACKOUT_FRAMES:
        rover.stuck_count = 0
        rover.steer = 0
        rover.mode = 'forward'


MODES = {'forward': _forward, 'rocking': _rocking, 'stop': _stop, 'stuck': _stuck}


def decide(rover):
    """One decision step on `rover`; sets throttle, brake, steer, mode and send_pickup."""
    if rover.nav_angles is not None and rover.mode in MODES:
        MODES[rover.mode](rover)
    else:
        # No perception yet (or an unknown mode): just roll ahead.
        rover.throttle = THROTTLE_SET
        rover.steer = 0
        rover.brake = 0
    # Ask for a pickup once the rover has come to a complete stop next to a sample.
    if rover.near_sample and rover.vel == 0 and not rover.picking_up:
        rover.send_pickup = True
    return rover
