#!/usr/bin/env python3
"""Seed baseline controller: a drive_rover-style Socket.IO server running the perception and
decision of the seed report (000_05c6bb1bba49e7bd) against the Unity simulator or `rover sim`.

It answers every telemetry with exactly one event (`data`, `pickup` or `manual`), serves until the
simulator leaves for good (it closes with "41" then "1" at --max-sim-seconds) or a SIGINT/SIGTERM
arrives, then writes the scores (Udacity's mapped % / fidelity % / samples located) and the map.

Usage: drive_baseline.py --port P [--ground-truth map_bw.png] [--out stats.json]
                         [--map-out worldmap.npy] [--quiet]
"""
import argparse
import base64
import io
import json
import math
import os
import signal
import sys
import time
import warnings

warnings.filterwarnings('ignore', message=r'\s*Eventlet is deprecated')
import eventlet  # noqa: E402
import eventlet.wsgi  # noqa: E402
import numpy as np  # noqa: E402
import socketio  # noqa: E402
from PIL import Image  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from decision import RoverState, decide  # noqa: E402
from perception import perceive  # noqa: E402

# After the simulator disconnects, wait this long for it to reconnect before calling it the end.
RECONNECT_GRACE_S = 2.0
# A rock cell within this distance (cells) of a true sample position counts it as located.
LOCATE_RADIUS = 3


# --- telemetry ----------------------------------------------------------------------------------
def number(text):
    """A telemetry number: plain, with ',' as the decimal separator (older Unity locales), or with
    thousands separators (.NET "N4" of values >= 1000)."""
    text = text.strip()
    try:
        return float(text)
    except ValueError:
        pass
    if '.' in text:
        return float(text.replace(',', ''))
    return float(text.replace(',', '.'))


def number_list(text):
    return [number(part) for part in text.split(';')] if text.strip() else []


def read_telemetry(rover, data):
    """Loads one telemetry dict into the rover state, as the starter's update_rover does."""
    if rover.samples_pos is None:
        xs = np.array(number_list(data['samples_x']), dtype=np.float64)
        ys = np.array(number_list(data['samples_y']), dtype=np.float64)
        rover.samples_pos = (xs.astype(np.int64), ys.astype(np.int64))  # truncated, like np.int_
        rover.samples_to_find = int(data['sample_count'])
    rover.vel = number(data['speed'])
    x_m, y_m = number_list(data['position'])
    rover.pos = (x_m, y_m)
    rover.yaw = number(data['yaw'])
    rover.pitch = number(data['pitch'])
    rover.roll = number(data['roll'])
    rover.throttle = number(data['throttle'])
    rover.steer = number(data['steering_angle'])
    rover.near_sample = int(data['near_sample'])
    rover.picking_up = int(data['picking_up'])
    rover.samples_collected = rover.samples_to_find - int(data['sample_count'])
    rover.img = np.asarray(Image.open(io.BytesIO(base64.b64decode(data['image']))).convert('RGB'))


# --- scoring (Udacity supporting_functions.create_output_images) ---------------------------------
def load_ground_truth(path):
    """Ground-truth navigable mask, worldmap-indexed (row = y, column = x)."""
    image = np.asarray(Image.open(path))
    if image.ndim == 3:
        image = image[:, :, 1] if image.shape[2] >= 3 else image[:, :, 0]
    return image > 0


def _normalised(layer):
    """Scales a map layer so that the mean of its non-zero cells is 255."""
    layer = layer.astype(np.float64)
    if np.max(layer) > 0:
        return layer * (255.0 / np.mean(layer[layer > 0]))
    return layer


def map_scores(worldmap, ground_truth):
    """Mapped % and fidelity % of a worldmap against a ground-truth mask."""
    navigable = _normalised(worldmap[:, :, 2])
    obstacle = _normalised(worldmap[:, :, 0])
    obstacle[navigable >= obstacle] = 0
    navigable = np.clip(navigable, 0, 255)
    total = int(np.count_nonzero(navigable))
    good = int(np.count_nonzero((navigable > 0) & ground_truth))
    truth = int(np.count_nonzero(ground_truth))
    return {
        'ground_truth_pix': truth,
        'tot_nav_pix': total,
        'good_nav_pix': good,
        'mapped_pct': round(100.0 * good / truth, 1) if truth else 0.0,
        'fidelity_pct': round(100.0 * good / total, 1) if total > 0 else 0,
    }


def samples_located(worldmap, samples_pos):
    """How many true sample positions have a mapped rock cell closer than LOCATE_RADIUS."""
    if samples_pos is None:
        return 0
    rock_rows, rock_cols = np.nonzero(worldmap[:, :, 1])
    if rock_rows.size == 0:
        return 0
    found = 0
    for x, y in zip(*samples_pos):
        if np.min(np.hypot(x - rock_cols, y - rock_rows)) < LOCATE_RADIUS:
            found += 1
    return found


def encode_inset(image):
    """Base64 JPEG of an RGB float/uint8 image, as the starter sends for the on-screen insets."""
    buffer = io.BytesIO()
    Image.fromarray(np.clip(image, 0, 255).astype(np.uint8)).save(buffer, format='JPEG')
    return base64.b64encode(buffer.getvalue()).decode('utf-8')


# --- server ---------------------------------------------------------------------------------------
def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--port', type=int, required=True)
    parser.add_argument('--host', default='127.0.0.1')
    parser.add_argument('--ground-truth', help='ground-truth PNG for mapped %% and fidelity %%')
    parser.add_argument('--out', help='write the run statistics as JSON here')
    parser.add_argument('--map-out', help='write the 200x200x3 worldmap (.npy) here')
    parser.add_argument('--insets', action='store_true',
                        help='send the vision image and world map as inset JPEGs (slower)')
    parser.add_argument('--trace', metavar='DIR',
                        help='debugging: write trace.csv (one line per frame) and every 100th '
                             'camera frame to DIR')
    parser.add_argument('--quiet', action='store_true')
    args = parser.parse_args()

    ground_truth = load_ground_truth(args.ground_truth) if args.ground_truth else None
    trace = None
    if args.trace:
        os.makedirs(args.trace, exist_ok=True)
        trace = open(os.path.join(args.trace, 'trace.csv'), 'w')
        trace.write('frame,x,y,yaw,pitch,roll,vel,near,picking,mode,nav_pix,throttle,brake,steer\n')
    rover = RoverState()
    sio = socketio.Server(async_mode='eventlet')
    stats = {
        'frames': 0, 'data_sent': 0, 'pickups_sent': 0, 'manual_sent': 0, 'nan_commands': 0,
        'errors': 0, 'first_error': None, 'connects': 0, 'disconnects': 0,
        'mode_frames': {}, 'mode_changes': 0,
    }
    state = {'connected': set(), 'last_disconnect': None, 'stop': None, 'first_frame': None,
             'last_frame': None}

    def say(*parts):
        if not args.quiet:
            print(*parts, flush=True)

    def send_data(throttle, brake, steer, inset1='', inset2=''):
        values = (throttle, brake, steer)
        if not all(math.isfinite(float(v)) for v in values):
            stats['nan_commands'] += 1
        sio.emit('data', data={'throttle': str(throttle), 'brake': str(brake),
                               'steering_angle': str(steer), 'inset_image1': inset1,
                               'inset_image2': inset2}, skip_sid=True)
        stats['data_sent'] += 1

    @sio.on('connect')
    def on_connect(sid, environ):
        stats['connects'] += 1
        state['connected'].add(sid)
        say('simulator connected', sid)
        # As drive_rover does: an idle command, and a request for the sample positions.
        send_data(0, 0, 0)
        sio.emit('get_samples', {}, skip_sid=True)

    @sio.on('disconnect')
    def on_disconnect(sid):
        stats['disconnects'] += 1
        state['connected'].discard(sid)
        state['last_disconnect'] = time.monotonic()
        say('simulator disconnected', sid)

    @sio.on('telemetry')
    def on_telemetry(sid, data):
        now = time.monotonic()
        state['first_frame'] = state['first_frame'] or now
        state['last_frame'] = now
        stats['frames'] += 1
        if not data:
            sio.emit('manual', data={}, skip_sid=True)
            stats['manual_sent'] += 1
            return
        try:
            read_telemetry(rover, data)
            if not np.isfinite(rover.vel):
                # Invalid telemetry: idle command, as the starter does.
                send_data(0, 0, 0)
                return
            mode_before = rover.mode
            perceive(rover)
            decide(rover)
            if trace is not None:
                trace.write(f'{stats["frames"]},{rover.pos[0]:.2f},{rover.pos[1]:.2f},'
                            f'{rover.yaw:.1f},{rover.pitch:.2f},{rover.roll:.2f},{rover.vel:.3f},'
                            f'{rover.near_sample},{rover.picking_up},{rover.mode},'
                            f'{len(rover.nav_angles)},{float(rover.throttle):.3f},'
                            f'{float(rover.brake):.1f},{float(rover.steer):.2f}\n')
                if stats['frames'] % 100 == 0:
                    Image.fromarray(rover.img).save(
                        os.path.join(args.trace, f'frame_{stats["frames"]:06d}.png'))
            stats['mode_frames'][rover.mode] = stats['mode_frames'].get(rover.mode, 0) + 1
            if rover.mode != mode_before:
                stats['mode_changes'] += 1
                say(f'frame {stats["frames"]}: {mode_before} -> {rover.mode}')
        except Exception as error:  # noqa: BLE001 - the loop must get its one reply regardless
            stats['errors'] += 1
            stats['first_error'] = stats['first_error'] or repr(error)
            send_data(0, 0, 0)
            return
        if rover.send_pickup and not rover.picking_up:
            sio.emit('pickup', data={}, skip_sid=True)
            stats['pickups_sent'] += 1
            rover.send_pickup = False
            say(f'frame {stats["frames"]}: pickup')
        else:
            inset1 = inset2 = ''
            if args.insets:
                inset1 = encode_inset(rover.vision_image)
                inset2 = encode_inset(np.flipud(rover.worldmap))
            send_data(rover.throttle, rover.brake, rover.steer, inset1, inset2)

    def request_stop(signum, _frame):
        state['stop'] = signal.Signals(signum).name

    signal.signal(signal.SIGINT, request_stop)
    signal.signal(signal.SIGTERM, request_stop)

    app = socketio.WSGIApp(sio)
    listener = eventlet.listen((args.host, args.port))
    server = eventlet.spawn(eventlet.wsgi.server, listener, app, log_output=False)
    print(f'ready on {args.host}:{args.port}', flush=True)  # printed even with --quiet
    started = time.monotonic()

    ended_by = None
    while ended_by is None:
        eventlet.sleep(0.1)
        if state['stop']:
            ended_by = state['stop']
        elif (not state['connected'] and state['last_disconnect'] is not None
              and time.monotonic() - state['last_disconnect'] > RECONNECT_GRACE_S):
            ended_by = 'simulator disconnected'

    result = dict(stats)
    result['ended_by'] = ended_by
    result['final_mode'] = rover.mode
    result['wall_seconds'] = round(time.monotonic() - started, 3)
    if state['first_frame'] is not None and state['last_frame'] > state['first_frame']:
        result['fps'] = round(stats['frames'] / (state['last_frame'] - state['first_frame']), 1)
    else:
        result['fps'] = None
    result['samples_total'] = rover.samples_to_find
    result['samples_collected'] = rover.samples_collected
    result['samples_located'] = samples_located(rover.worldmap, rover.samples_pos)
    result['samples_pos'] = ([list(map(int, axis)) for axis in rover.samples_pos]
                             if rover.samples_pos is not None else None)
    result['final_position'] = list(rover.pos)
    if ground_truth is not None:
        result.update(map_scores(rover.worldmap, ground_truth))
    else:
        result.update({'mapped_pct': None, 'fidelity_pct': None})

    if trace is not None:
        trace.close()
    if args.map_out:
        np.save(args.map_out, rover.worldmap)
    if args.out:
        with open(args.out, 'w') as out:
            json.dump(result, out, indent=2)
    say(json.dumps({k: result[k] for k in ('frames', 'pickups_sent', 'samples_located',
                                           'mapped_pct', 'fidelity_pct', 'final_mode', 'fps')}))
    server.kill()
    return 0


if __name__ == '__main__':
    sys.exit(main())
