#!/usr/bin/env python3
"""A Socket.IO 4.x server (python-socketio 4.6.1 / python-engineio 3.13.2, as the Udacity starter
code uses) that drives the headless simulator in a closed loop and checks its telemetry.

Each telemetry is decoded the way the starter's `update_rover` does it: every value is a string;
numbers may use ',' as the decimal separator; `position` is "x;y"; the sample lists are
';'-separated; near_sample / picking_up are ints; the image is a base64 JPEG that PIL opens as a
160x320 RGB array. Every telemetry is answered with exactly one `data` command, as drive_rover does.

Usage: unity_dialect_server.py --port PORT --frames N --out STATS.json
"""
import argparse
import base64
import io
import json
import sys

import eventlet
import eventlet.wsgi
import numpy as np
import socketio
from PIL import Image


def to_float(text):
    return float(text.replace(',', '.'))


def decode_telemetry(data):
    """Decode one telemetry dict; raises on anything the starter could not read."""
    for key, value in data.items():
        if not isinstance(value, str):
            raise TypeError(f'{key} is {type(value).__name__}, not a string')
    x, y = (to_float(v) for v in data['position'].split(';'))
    samples_x = [to_float(v) for v in data['samples_x'].split(';')] if data['samples_x'] else []
    samples_y = [to_float(v) for v in data['samples_y'].split(';')] if data['samples_y'] else []
    if len(samples_x) != len(samples_y):
        raise ValueError('sample lists differ in length')
    image = np.asarray(Image.open(io.BytesIO(base64.b64decode(data['image']))))
    if image.shape != (160, 320, 3):
        raise ValueError(f'image shape {image.shape}')
    return {
        'speed': to_float(data['speed']),
        'position': (x, y),
        'yaw': to_float(data['yaw']),
        'pitch': to_float(data['pitch']),
        'roll': to_float(data['roll']),
        'throttle': to_float(data['throttle']),
        'steer': to_float(data['steering_angle']),
        'near_sample': int(data['near_sample']),
        'picking_up': int(data['picking_up']),
        'sample_count': int(data['sample_count']),
        'samples': list(zip(samples_x, samples_y)),
        'image_mean': float(image.mean()),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--port', type=int, required=True)
    parser.add_argument('--frames', type=int, default=500)
    parser.add_argument('--out', required=True)
    args = parser.parse_args()

    sio = socketio.Server(async_mode='eventlet')
    stats = {'connects': 0, 'telemetry': 0, 'decoded': 0, 'errors': [], 'commands_sent': 0,
             'empty': 0, 'first': None, 'last': None, 'moved_m': 0.0}
    done = eventlet.event.Event()

    def send_command(throttle, steer):
        sio.emit('data', data={'throttle': str(throttle), 'brake': '0', 'steering_angle': str(steer),
                               'inset_image1': '', 'inset_image2': ''}, skip_sid=True)
        stats['commands_sent'] += 1

    @sio.on('connect')
    def connect(sid, environ):
        stats['connects'] += 1
        send_command(0, 0)

    @sio.on('telemetry')
    def telemetry(sid, data):
        stats['telemetry'] += 1
        if not data:
            stats['empty'] += 1
            sio.emit('manual', data={}, skip_sid=True)
            return
        try:
            rover = decode_telemetry(data)
            stats['decoded'] += 1
            stats['first'] = stats['first'] or rover
            stats['last'] = rover
        except Exception as error:  # noqa: BLE001 - every failure is recorded for the test
            stats['errors'].append(repr(error))
            rover = None
        if stats['telemetry'] >= args.frames:
            if not done.ready():
                done.send()
            return
        steer = 10.0 if (stats['telemetry'] // 50) % 2 else -10.0
        send_command(0.3 if rover is None or rover['speed'] < 1.5 else 0.0, steer)

    app = socketio.WSGIApp(sio)
    listener = eventlet.listen(('127.0.0.1', args.port))
    server = eventlet.spawn(eventlet.wsgi.server, listener, app, log_output=False)
    print('ready', flush=True)
    done.wait()
    eventlet.sleep(0.5)
    first, last = stats['first'], stats['last']
    if first and last:
        stats['moved_m'] = float(np.hypot(last['position'][0] - first['position'][0],
                                          last['position'][1] - first['position'][1]))
    with open(args.out, 'w') as out:
        json.dump(stats, out)
    server.kill()
    return 0


if __name__ == '__main__':
    sys.exit(main())
