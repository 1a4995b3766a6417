#!/usr/bin/env python3
"""Evaluate the seed baseline (drive_baseline.py) against `rover sim`, one run per seed.

For every seed it starts drive_baseline.py on a free port (with the world's ground truth), waits
for its "ready on" line, runs `rover sim [--map PNG] --seed N --port P --max-sim-seconds S --report
FILE`, then combines the simulator's report with the driver's statistics into one row with the
fields of `rover eval --json`: seed, mapped_pct, fidelity_pct, located, collected, samples,
home_distance_m, sim_seconds, wall_seconds, frames_per_second, final_mode.

With --map PNG the map is also the ground truth. With --procedural each seed's world is the
simulator's procedural one, and `rover sim --seed N --export-map FILE` first writes its ground
truth (same format as map_bw.png) for the driver.

Progress goes to stderr; the table (or with --json the JSON list) goes to stdout. Ctrl-C stops the
simulator and the driver, prints the runs finished so far and exits with status 130.
"""
import argparse
import json
import os
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO_ROOT = os.path.abspath(os.path.join(HERE, '..', '..', '..'))
DRIVER = os.path.join(HERE, 'drive_baseline.py')
DEFAULT_ROVER = os.path.join(REPO_ROOT, 'target', 'release', 'rover')

# The mission targets of `rover eval` (src/missions/eval.rs, RunResult::complete), without its
# `final_mode == "done"` condition: the baseline has no such mode (see docs/mission.md).
TARGET_MAPPED_PCT = 90.0
TARGET_FIDELITY_PCT = 85.0
TARGET_HOME_DISTANCE_M = 3.0
TARGET_SIM_SECONDS = 1200.0

EXPORT_TIMEOUT_S = 60.0       # `rover sim --export-map` (builds the world, writes one PNG)
READY_TIMEOUT_S = 60.0        # driver start-up (imports of eventlet, numpy, opencv)
DRIVER_EXIT_TIMEOUT_S = 30.0  # the driver leaves 2 s after the simulator; then writes its stats
STOP_GRACE_S = 10.0           # after a stop signal, before SIGKILL
PROGRESS_PERIOD_S = 30.0      # relay at most one simulator progress line per this many seconds
PORT_ATTEMPTS = 3             # a free port can be taken by someone else before the driver binds it

RESULT_FIELDS = ('seed', 'mapped_pct', 'fidelity_pct', 'located', 'collected', 'samples',
                 'home_distance_m', 'sim_seconds', 'wall_seconds', 'frames_per_second',
                 'final_mode')


class EvalError(Exception):
    """A run could not be carried out or scored; the message says why."""


class Interrupted(Exception):
    """SIGINT or SIGTERM arrived."""


def progress(message):
    """One progress line on stderr."""
    print(f'[eval_baseline] {message}', file=sys.stderr, flush=True)


# --- command line -----------------------------------------------------------------------------
def parse_seeds(text):
    """Seeds 'A..B' (inclusive, 'A..=B' too) or a single 'N', as `rover eval --seeds` reads them."""
    def number(part):
        part = part.strip()
        if not part.isdigit():
            raise argparse.ArgumentTypeError(f'{part!r} is not a seed number')
        return int(part)

    if '..' in text:
        first, last = text.split('..', 1)
        first, last = number(first), number(last.lstrip('='))
        if first > last:
            raise argparse.ArgumentTypeError(f'seeds {text!r}: the first must not exceed the last')
        return list(range(first, last + 1))
    return [number(text)]


def positive_float(text):
    """A float > 0, for argparse."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a number') from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f'{text} must be positive')
    return value


def parse_args(argv):
    """The command line; exits with a usage error on invalid or unsupported options."""
    parser = argparse.ArgumentParser(
        description='Run the seed baseline (drive_baseline.py) against `rover sim` once per seed '
                    'and print a table of the scores, or with --json a list with the fields of '
                    '`rover eval --json`.',
        epilog='A run is "complete" when mapped >= 90 %, fidelity >= 85 %, every sample '
               'collected, home distance <= 3 m and sim time <= 1200 s.')
    world = parser.add_mutually_exclusive_group(required=True)
    world.add_argument('--map', metavar='PNG',
                       help='world map (200x200 PNG, navigable > 0), also the ground truth')
    world.add_argument('--procedural', action='store_true',
                       help="the simulator's procedural world of each seed (its ground truth "
                            'written by `rover sim --export-map`)')
    parser.add_argument('--floor', metavar='PNG',
                        help='where the terrain is flat floor (with --map), passed to `rover sim`')
    parser.add_argument('--appearance-seed', type=int, default=0, metavar='N',
                        help="the simulator's appearance seed (default 0, the calibrated look)")
    parser.add_argument('--seeds', default='0..9', type=parse_seeds,
                        help='seeds, e.g. 0..9 (inclusive) or 4 (default 0..9)')
    parser.add_argument('--json', action='store_true', help='print one JSON list instead of a table')
    parser.add_argument('--max-sim-seconds', type=positive_float, default=1200.0, metavar='S',
                        help='simulated time per run, seconds (default 1200)')
    parser.add_argument('--rover', default=DEFAULT_ROVER, metavar='PATH',
                        help='the rover binary (default: target/release/rover, built with '
                             '`cargo build --release` if missing)')
    parser.add_argument('--keep', metavar='DIR',
                        help="keep each run's simulator report, driver stats, logs, world map "
                             'and (with --procedural) ground-truth PNG in DIR')
    parser.add_argument('--run-timeout', type=positive_float, default=7200.0, metavar='S',
                        help='wall-clock limit of one run, seconds (default 7200)')
    args = parser.parse_args(argv)
    if args.map is not None:
        if not os.path.isfile(args.map):
            parser.error(f'--map {args.map}: no such file')
        args.map = os.path.abspath(args.map)
    if args.floor is not None:
        if args.map is None:
            parser.error('--floor needs --map')
        if not os.path.isfile(args.floor):
            parser.error(f'--floor {args.floor}: no such file')
        args.floor = os.path.abspath(args.floor)
    if args.rover != DEFAULT_ROVER and not os.path.isfile(args.rover):
        parser.error(f'--rover {args.rover}: no such file')
    return args


# --- the simulator binary ---------------------------------------------------------------------
def ensure_rover(path):
    """The rover binary at `path`; builds it with `cargo build --release` if it is the default
    one and missing."""
    if os.path.isfile(path):
        return path
    progress(f'{path} is missing: running `cargo build --release` in {REPO_ROOT}')
    build = subprocess.run(['cargo', 'build', '--release'], cwd=REPO_ROOT, stdout=sys.stderr)
    if build.returncode != 0 or not os.path.isfile(path):
        raise EvalError(f'`cargo build --release` failed (status {build.returncode}); no {path}')
    return path


def snapshot_rover(path, work_dir):
    """A private copy of the rover binary, so that every seed runs the same build even if the
    workspace is rebuilt meanwhile."""
    copy = os.path.join(work_dir, 'rover')
    shutil.copy2(path, copy)
    built = time.strftime('%Y-%m-%d %H:%M:%S', time.localtime(os.path.getmtime(path)))
    progress(f'simulator: {path} (built {built}), copied for this evaluation')
    return copy


# --- child processes --------------------------------------------------------------------------
def free_port():
    """A TCP port on 127.0.0.1 that is free right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def pump_lines(stream, log_file, on_line=None):
    """Starts a thread that copies `stream` line by line into `log_file`, calling `on_line` on
    each line."""
    def run():
        for raw in iter(stream.readline, b''):
            line = raw.decode('utf-8', 'replace')
            log_file.write(line)
            log_file.flush()
            if on_line is not None:
                on_line(line.rstrip('\n'))
        stream.close()

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def start_process(command, log_file, pipe_name, on_line=None):
    """Starts `command` in its own session (so a terminal Ctrl-C reaches only this script, which
    then stops the child itself), with the stream `pipe_name` ('stdout' or 'stderr') pumped
    through `on_line` into `log_file` and the other written straight to `log_file`."""
    streams = {'stdout': log_file, 'stderr': log_file, pipe_name: subprocess.PIPE}
    process = subprocess.Popen(command, stdin=subprocess.DEVNULL, start_new_session=True,
                               **streams)
    process.pump = pump_lines(getattr(process, pipe_name), log_file, on_line)
    return process


def close_log(process, log_file):
    """Closes a child's log once the thread pumping its output has written the last line."""
    process.pump.join(timeout=STOP_GRACE_S)
    log_file.close()


def stop_process(process, sig, name):
    """Sends `sig` to `process` if it still runs, and kills it after STOP_GRACE_S."""
    if process is None or process.poll() is not None:
        return
    try:
        process.send_signal(sig)
        process.wait(timeout=STOP_GRACE_S)
    except subprocess.TimeoutExpired:
        progress(f'{name} (pid {process.pid}) ignored {sig.name}: killing it')
        process.kill()
        process.wait()


def wait_until(condition, timeout, interval=0.1):
    """Polls `condition` until it holds (True) or `timeout` seconds pass (False)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(interval)
    return condition()


def log_tail(path, lines=15):
    """The last lines of a log file, for error messages."""
    try:
        with open(path, errors='replace') as log:
            return ''.join(log.readlines()[-lines:]).rstrip()
    except OSError:
        return '(no log)'


# --- one run ----------------------------------------------------------------------------------
class RunFiles:
    """The files of one seed's run inside the work directory."""

    def __init__(self, work_dir, seed):
        stem = os.path.join(work_dir, f'seed{seed}')
        self.sim_report = f'{stem}_sim.json'
        self.sim_log = f'{stem}_sim.log'
        self.driver_stats = f'{stem}_driver.json'
        self.driver_log = f'{stem}_driver.log'
        self.worldmap = f'{stem}_worldmap.npy'
        self.truth = f'{stem}_truth.png'

    def clear(self):
        """Removes the outputs of an earlier run (with --keep), so none is taken for this one's."""
        for path in (self.sim_report, self.sim_log, self.driver_stats, self.driver_log,
                     self.worldmap, self.truth):
            if os.path.exists(path):
                os.remove(path)


def export_ground_truth(rover, seed, files):
    """Writes the ground truth of the procedural world `seed` to files.truth with `rover sim
    --seed N --export-map FILE` and returns that path; raises EvalError if it fails."""
    command = [rover, 'sim', '--seed', str(seed), '--export-map', files.truth]
    failed = f'seed {seed}: `{shlex.join(command)}`'
    try:
        export = subprocess.run(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, timeout=EXPORT_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        raise EvalError(f'{failed} did not finish within {EXPORT_TIMEOUT_S:.0f} s') from None
    output = export.stdout.decode('utf-8', 'replace').rstrip() or '(no output)'
    if export.returncode != 0:
        raise EvalError(f'{failed} exited with status {export.returncode}; its output:\n{output}')
    if not os.path.isfile(files.truth):
        raise EvalError(f'{failed} wrote no {files.truth}; its output:\n{output}')
    return files.truth


def start_driver(map_png, files):
    """Starts drive_baseline.py on a free port and waits for its ready line; returns (process,
    port, log file). Retries on another port if that one was taken before the driver bound it."""
    for _attempt in range(PORT_ATTEMPTS):
        port = free_port()
        ready = threading.Event()
        log = open(files.driver_log, 'a')
        command = [sys.executable, DRIVER, '--port', str(port), '--ground-truth', map_png,
                   '--out', files.driver_stats, '--map-out', files.worldmap, '--quiet']
        driver = start_process(command, log, 'stdout',
                               lambda line: ready.set() if line.startswith('ready on') else None)
        try:
            answered = wait_until(lambda: ready.is_set() or driver.poll() is not None,
                                  READY_TIMEOUT_S)
        except BaseException:
            stop_process(driver, signal.SIGTERM, 'driver')
            close_log(driver, log)
            raise
        if ready.is_set():
            return driver, port, log
        stop_process(driver, signal.SIGTERM, 'driver')
        close_log(driver, log)
        if not answered:
            raise EvalError(f'drive_baseline.py was not ready within {READY_TIMEOUT_S:.0f} s; '
                            f'its log ends:\n{log_tail(files.driver_log)}')
        if 'Address already in use' not in log_tail(files.driver_log):
            break
        # The port was taken between free_port() and the driver's bind: try another one.
    raise EvalError(f'drive_baseline.py exited before it was ready; its log ends:\n'
                    f'{log_tail(files.driver_log)}')


def simulator_progress_relay(seed):
    """A line handler that relays the simulator's pickups at once and its periodic progress lines
    at most every PROGRESS_PERIOD_S, without the log timestamp."""
    last = {'time': time.monotonic()}

    def relay(line):
        message = line.split(' INFO ', 1)[1].strip() if ' INFO ' in line else None
        if message is None:
            if ' WARN ' in line or ' ERROR ' in line:
                progress(f'seed {seed}: simulator: {line.strip()}')
            return
        if message.startswith('sample picked up'):
            progress(f'seed {seed}: {message}')
        elif message.startswith('sim ') and time.monotonic() - last['time'] >= PROGRESS_PERIOD_S:
            last['time'] = time.monotonic()
            progress(f'seed {seed}: {message}')

    return relay


def run_simulator(rover, args, seed, port, files):
    """Runs `rover sim` for one seed (on --map, or else its procedural world) until it exits;
    raises EvalError on a failure."""
    world = ['--map', args.map] if args.map is not None else []
    world += ['--floor', args.floor] if args.floor is not None else []
    world += ['--appearance-seed', str(args.appearance_seed)]
    command = [rover, 'sim', *world, '--seed', str(seed), '--port', str(port),
               '--max-sim-seconds', f'{args.max_sim_seconds:g}', '--report', files.sim_report]
    with open(files.sim_log, 'a') as log:
        sim = start_process(command, log, 'stderr', simulator_progress_relay(seed))
        try:
            if not wait_until(lambda: sim.poll() is not None, args.run_timeout, interval=0.5):
                raise EvalError(f'seed {seed}: rover sim still running after {args.run_timeout:g} '
                                f's (--run-timeout); stopped')
        finally:
            stop_process(sim, signal.SIGINT, 'rover sim')
            sim.pump.join(timeout=STOP_GRACE_S)
    if sim.returncode != 0:
        raise EvalError(f'seed {seed}: rover sim exited with status {sim.returncode}; its log '
                        f'ends:\n{log_tail(files.sim_log)}')


def wait_for_driver(driver, seed, files):
    """Waits for the driver to notice the simulator has gone and write its stats; stops it with
    SIGTERM (which also makes it write them) if it takes too long."""
    if not wait_until(lambda: driver.poll() is not None, DRIVER_EXIT_TIMEOUT_S):
        progress(f'seed {seed}: driver still running {DRIVER_EXIT_TIMEOUT_S:.0f} s after the '
                 'simulator ended: sending SIGTERM')
        stop_process(driver, signal.SIGTERM, 'driver')
    if driver.returncode != 0:
        raise EvalError(f'seed {seed}: drive_baseline.py exited with status {driver.returncode}; '
                        f'its log ends:\n{log_tail(files.driver_log)}')


def load_json(path, what):
    """The JSON object in `path`; EvalError if it is missing or unreadable."""
    try:
        with open(path) as file:
            return json.load(file)
    except (OSError, ValueError) as error:
        raise EvalError(f'cannot read the {what} {path}: {error}') from None


def run_seed(rover, args, seed, work_dir):
    """One complete run (driver + simulator) for `seed`; returns its result row."""
    files = RunFiles(work_dir, seed)
    files.clear()
    truth = args.map if args.map is not None else export_ground_truth(rover, seed, files)
    driver, port, driver_log = start_driver(truth, files)
    progress(f'seed {seed}: driver ready on port {port} (pid {driver.pid}); starting rover sim')
    try:
        run_simulator(rover, args, seed, port, files)
        wait_for_driver(driver, seed, files)
    finally:
        stop_process(driver, signal.SIGTERM, 'driver')
        close_log(driver, driver_log)
    sim_report = load_json(files.sim_report, 'simulator report')
    driver_stats = load_json(files.driver_stats, 'driver stats')
    if driver_stats.get('errors'):
        progress(f'seed {seed}: the driver caught {driver_stats["errors"]} exceptions, the first: '
                 f'{driver_stats.get("first_error")}')
    return result_row(seed, sim_report, driver_stats)


# --- results ----------------------------------------------------------------------------------
def result_row(seed, sim_report, driver_stats):
    """The `rover eval --json` fields of one run: the map scores, samples located and final mode
    from the driver; samples, pickups, home distance, time and frame rate from the simulator."""
    wall = float(sim_report['wall_seconds'])
    return {
        'seed': seed,
        'mapped_pct': float(driver_stats['mapped_pct']),
        'fidelity_pct': float(driver_stats['fidelity_pct']),
        'located': int(driver_stats['samples_located']),
        'collected': int(sim_report['samples_collected']),
        'samples': int(sim_report['samples_total']),
        'home_distance_m': float(sim_report['final_distance_to_start_m']),
        'sim_seconds': float(sim_report['sim_seconds']),
        'wall_seconds': wall,
        'frames_per_second': int(sim_report['frames']) / max(wall, 1e-9),
        'final_mode': str(driver_stats['final_mode']),
    }


def is_complete(row):
    """Whether a run meets the mission targets (the rule of `rover eval`, minus its final-mode
    condition: see the module constants)."""
    return (row['mapped_pct'] >= TARGET_MAPPED_PCT
            and row['fidelity_pct'] >= TARGET_FIDELITY_PCT
            and row['collected'] == row['samples']
            and row['home_distance_m'] <= TARGET_HOME_DISTANCE_M
            and row['sim_seconds'] <= TARGET_SIM_SECONDS)


def format_table(rows):
    """The results as a table in the layout of `rover eval`."""
    lines = ['seed  mapped %  fidelity %  located  collected  home m  sim s   wall s  frames/s  '
             'mode         complete']
    for r in rows:
        collected = f'{r["collected"]}/{r["samples"]}'
        lines.append(
            f'{r["seed"]:>4}  {r["mapped_pct"]:>8.1f}  {r["fidelity_pct"]:>10.1f}  '
            f'{r["located"]:>7}  {collected:>9}  {r["home_distance_m"]:>6.1f}  '
            f'{r["sim_seconds"]:>6.0f}  {r["wall_seconds"]:>7.1f}  {r["frames_per_second"]:>8.0f}  '
            f'{r["final_mode"]:<12} {"yes" if is_complete(r) else "no"}')
    lines.append(f'{sum(map(is_complete, rows))} of {len(rows)} complete')
    return '\n'.join(lines) + '\n'


def print_results(rows, as_json):
    """The results on stdout: a JSON list or a table."""
    if as_json:
        print(json.dumps([{k: r[k] for k in RESULT_FIELDS} for r in rows], indent=2), flush=True)
        progress(f'{sum(map(is_complete, rows))} of {len(rows)} complete')
    else:
        sys.stdout.write(format_table(rows))
        sys.stdout.flush()


def describe(row):
    """One progress line summing up a finished run."""
    return (f'seed {row["seed"]}: mapped {row["mapped_pct"]:.1f} %, fidelity '
            f'{row["fidelity_pct"]:.1f} %, located {row["located"]}, collected '
            f'{row["collected"]}/{row["samples"]}, home {row["home_distance_m"]:.1f} m, '
            f'{row["sim_seconds"]:.0f} sim s in {row["wall_seconds"]:.0f} wall s '
            f'({row["frames_per_second"]:.0f} frames/s), mode {row["final_mode"]}')


# --- main -------------------------------------------------------------------------------------
def raise_interrupted(signum, _frame):
    """Signal handler: turns the first SIGINT / SIGTERM into an Interrupted exception and ignores
    further ones, so that the clean-up (stopping the children, bounded by STOP_GRACE_S) runs to
    its end."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise Interrupted(signal.Signals(signum).name)


def run_all(args, work_dir):
    """Runs every seed in sequence; returns (rows, status)."""
    rows = []
    try:
        rover = snapshot_rover(ensure_rover(args.rover), work_dir)
        for seed in args.seeds:
            progress(f'seed {seed}: starting ({args.max_sim_seconds:g} simulated s)')
            rows.append(run_seed(rover, args, seed, work_dir))
            progress(describe(rows[-1]))
        return rows, 0
    except Interrupted as signal_name:
        progress(f'{signal_name}: stopped; the unfinished run is left out')
        return rows, 130
    except EvalError as error:
        progress(f'error: {error}')
        return rows, 1


def main(argv=None):
    """Entry point: parse, run every seed, print the results."""
    args = parse_args(argv)
    signal.signal(signal.SIGINT, raise_interrupted)
    signal.signal(signal.SIGTERM, raise_interrupted)
    if args.keep:
        os.makedirs(args.keep, exist_ok=True)
        rows, status = run_all(args, os.path.abspath(args.keep))
        snapshot = os.path.join(args.keep, 'rover')
        if os.path.exists(snapshot):
            os.remove(snapshot)
    else:
        with tempfile.TemporaryDirectory(prefix='eval_baseline_') as work_dir:
            rows, status = run_all(args, work_dir)
    if rows or status == 0:
        print_results(rows, args.json)
    return status


if __name__ == '__main__':
    sys.exit(main())
