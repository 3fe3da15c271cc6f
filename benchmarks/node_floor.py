"""The node's joint-state hop beside ROS 2's floor, with parameters of your choice.

``python -m benchmarks.node_floor --floor ../shared/floor [--runs 3] [--rate 1000]
[--duration 15] [-p name:=value ...] [variants ...]`` runs the floor probe (``floor_probe.py`` of
the floor folder: the node beside a C program over rcl answering the same stream, the answerers
in turn within each run, latency from publish stamp to arrival and each answerer's CPU time per
message) with the node started with the extra parameters given (e.g. ``-p
warning_distance:=0.05``); without any, it is the probe as it is. It prints the probe's lines,
then each figure of the node as a ratio to the rcl echo's of the same run: the comparison that
holds on a busy machine.
"""
import argparse
import importlib.util
import os
import sys

import numpy as np


def load_probe(folder: str):
    """Import ``floor_probe.py`` from ``folder``."""
    path = os.path.join(folder, 'floor_probe.py')
    if not os.path.isfile(path):
        raise SystemExit(f'node_floor: {path} not found; give the floor folder with --floor')
    spec = importlib.util.spec_from_file_location('floor_probe', path)
    probe = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(probe)
    return probe


def with_parameters(probe, parameters):
    """Make the probe start the node with ``-p`` ``parameters`` too."""
    start = probe.start

    def start_with(kind, ns, venv, build):
        if kind != 'node' or not parameters:
            return start(kind, ns, venv, build)
        real = probe.subprocess.Popen

        def popen(command, **kwargs):
            extra = [item for parameter in parameters for item in ('-p', parameter)]
            at = command.index('--ros-args') + 1
            return real(command[:at] + extra + command[at:], **kwargs)
        probe.subprocess.Popen = popen
        try:
            return start(kind, ns, venv, build)
        finally:
            probe.subprocess.Popen = real
    probe.start = start_with


def ratios(rows):
    """``{run: {figure: node / rcl}}`` from the probe's rows."""
    out = []
    for rcl, node in zip(rows.get('rcl', []), rows.get('node', [])):
        if rcl is None or node is None:
            continue
        out.append({key: node[key] / rcl[key] for key in ('p50', 'p99', 'cpu_us')})
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('variants', nargs='*', default=['rcl', 'node'])
    parser.add_argument('--floor', default=os.path.join('..', 'shared', 'floor'))
    parser.add_argument('--rate', type=float, default=1000.0)
    parser.add_argument('--duration', type=float, default=15.0)
    parser.add_argument('--runs', type=int, default=3)
    parser.add_argument('--venv', default='.venv')
    parser.add_argument('-p', dest='parameters', action='append', default=[],
                        metavar='NAME:=VALUE', help='a parameter of the node')
    args = parser.parse_args(argv)
    probe = load_probe(args.floor)
    with_parameters(probe, args.parameters)
    rows = {}
    measure = probe.measure

    def measured(kind, run, *rest):
        row = measure(kind, run, *rest)
        rows.setdefault(kind, []).append(row)
        return row
    probe.measure = measured
    sys.argv = ['floor_probe.py', *args.variants, '--rate', str(args.rate), '--duration',
                str(args.duration), '--runs', str(args.runs), '--venv', args.venv]
    probe.main()
    found = ratios(rows)
    if found:
        print(f'\nthe node / the rcl echo, same run ({", ".join(args.parameters) or "defaults"}):')
        for key, name in (('p50', 'p50'), ('p99', 'p99'), ('cpu_us', 'CPU per message')):
            values = [r[key] for r in found]
            print(f'  {name:16s} {min(values):.2f}x / {float(np.median(values)):.2f}x / '
                  f'{max(values):.2f}x (min / median / max of {len(values)} runs)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
