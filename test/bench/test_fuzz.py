"""``python -m benchmarks.fuzz``, short: the node against every malformed class.

The tool starts ``collision_sensor_node`` (Panda) as a process of its own, sends half valid
and half malformed joint states and compares every verdict with ``CollisionChecker.check``
(see its docstring). Here a few thousand messages, as a subprocess, as a user runs it.
"""
import json

import pytest
from benchmark_process import run_benchmark

pytest.importorskip('rclpy')

MESSAGES = 3000

pytestmark = pytest.mark.node_process


def run_fuzz(tmp_path, *args):
    report = tmp_path / 'fuzz.json'
    # cwd: not the source directory, whose package has no engine under colcon test
    run = run_benchmark('benchmarks.fuzz', '--messages', MESSAGES, '--seed', 7,
                        '--json', report, *args, cwd=tmp_path)
    assert report.exists(), run.stdout + run.stderr
    return run, json.loads(report.read_text())


def assert_node_survived(run, report):
    out = run.stdout + run.stderr
    totals = report['totals']
    assert totals['sent'] == MESSAGES
    assert totals['lost'] == 0 and totals['unexpected'] == 0, out
    assert report['forged_lines'] == [] and report['foreign_lines'] == [], out
    assert report['node_exit_status'] == 0 and report['clean_exit'], out
    # The node's own counters: every message received; every one it did not answer counted.
    d = report['diagnostics']
    assert int(d['received_total']) == MESSAGES, d
    assert int(d['verdicts_total']) == totals['checked'], d
    assert int(d['skipped_total']) == MESSAGES - totals['checked'], d
    # Every message answered: a refused one too, by a failure entry.
    assert totals['expected'] == totals['received'] == MESSAGES, out
    assert d['lost_total'] == '0' and d['skipped_engine_error'] == '0', d
    # Bounded memory: 100 unknown names remembered whatever the flood, the rest counted; the
    # node grows by less than 64 MiB while it takes 3000 messages, 107 of them with 10^3 new
    # names and 107 with 2 * 10^4 (rejected before decoding, counted as such).
    assert d['unknown_joints_count'] == '100' and int(d['unknown_joints_not_remembered']) > 10**4
    assert int(d['rejected_oversized']) == report['classes']['oversized']['sent'] > 0, d
    rss = report['rss_kib']
    assert rss['max'] - rss['at_ready'] < 64 * 1024, rss
    assert len(d['unknown_joints']) < 500 and max(len(v) for v in d.values()) < 1000


def test_fuzz_default_policy_every_verdict_right_none_lost(tmp_path):
    run, report = run_fuzz(tmp_path)
    assert_node_survived(run, report)
    assert report['totals']['wrong'] == 0, report['wrong_examples']
    classes = report['classes']
    for kind in ('length_mismatch', 'duplicate_names', 'nan', 'inf', 'huge_1e9', 'huge_9.2e18',
                 'huge_1.7e308', 'only_control_char_names', 'empty', 'velocity_only',
                 'oversized'):
        # None checked; each answered as refused (or, changing nothing, by the state held).
        assert classes[kind]['sent'] > 0 and classes[kind]['checked'] == 0, kind
    for kind in ('valid', 'unknown_names', 'unknown_flood', 'control_char_names'):
        assert classes[kind]['received'] == classes[kind]['checked'] == classes[kind]['sent'] \
            > 0, kind
    assert run.returncode == 0 and 'result: OK' in run.stdout, run.stdout


def test_fuzz_accept_policy_hands_absurd_values_to_the_engine(tmp_path):
    run, report = run_fuzz(tmp_path, '--joint-limit-policy', 'accept')
    assert_node_survived(run, report)
    classes = report['classes']
    for kind in ('huge_1e9', 'huge_9.2e18', 'huge_1.7e308'):
        # Verdicts for every state the engine takes (huge revolute values); none lost.
        assert classes[kind]['received'] == classes[kind]['expected'] > 0, kind
        assert classes[kind]['checked'] > 0, kind
    # The engine takes any finite revolute value and refuses what it cannot honour (a slider
    # beyond 1e6 m): the node then rejects the message and keeps its state; every verdict
    # it does publish equals a fresh check() of the state it describes.
    wrong = {kind: stats['wrong'] for kind, stats in classes.items() if stats['wrong']}
    assert not wrong, (wrong, report['wrong_examples'][:2])
    assert int(report['diagnostics']['rejected_engine_range']) > 0
    assert run.returncode == 0
