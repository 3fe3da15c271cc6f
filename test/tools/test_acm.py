"""collision_sensor_acm: the self-collision matrix against independent oracles.

Oracles: the shipped Panda SRDF (read with xml.etree), adjacency worked out from the URDF with
xml.etree, python-fcl with pinocchio's kinematics (``engine_oracles.FclOracle``) on fresh
random samples, and a hand-built slider robot whose collision rates and clearance follow from
its geometry (closed form). Sample counts are modest (a few thousand) to keep the module fast.
"""
import math
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml

from collision_sensor import CollisionChecker
from collision_sensor.engine.sampling import sampling_bounds, uniform_configurations
from collision_sensor.model.share import config_path
from collision_sensor.model.srdf import load_srdf
from collision_sensor.model.srdf_merge import merge_disable_collisions, new_srdf
from collision_sensor.tools import acm, collision_matrix, collision_matrix_report
from engine_oracles import FclOracle

SAMPLES = 1500        # per Always round
NEVER_SAMPLES = 3000
FRESH = 3000          # fresh samples for the independent rate check


def _pairs_of(srdf_path):
    """{(link1, link2) sorted: reason} of an SRDF, read with xml.etree (not our reader)."""
    pairs = {}
    for element in ET.parse(srdf_path).getroot().iter('disable_collisions'):
        pair = tuple(sorted((element.get('link1'), element.get('link2'))))
        pairs.setdefault(pair, element.get('reason', ''))
    return pairs


def _adjacent_by_etree(urdf_path):
    """Link with geometry and its nearest ancestor with geometry, from the URDF text alone."""
    root = ET.parse(urdf_path).getroot()
    geometric = {link.get('name') for link in root.findall('link')
                 if link.find('collision') is not None}
    parent = {joint.find('child').get('link'): joint.find('parent').get('link')
              for joint in root.findall('joint')}
    pairs = set()
    for link in geometric:
        up = parent.get(link)
        while up is not None and up not in geometric:
            up = parent.get(up)
        if up is not None:
            pairs.add(tuple(sorted((link, up))))
    return pairs


def _run(capsys, argv):
    status = acm.main(argv)
    out, err = capsys.readouterr()
    return status, out, err


def _error_line(err):
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith('collision_sensor_acm: error: '), err
    return lines[0]


# --- the Panda, SRDF stripped ----------------------------------------------------------------

@pytest.fixture(scope='module')
def panda_base(panda_urdf, erd_package_paths):
    return CollisionChecker.from_urdf(panda_urdf, package_paths=erd_package_paths,
                                      config={'ignore_adjacent': False})


@pytest.fixture(scope='module')
def panda_matrix(panda_base):
    return collision_matrix.compute_matrix(panda_base, never=True, samples_per_round=SAMPLES,
                              never_samples=NEVER_SAMPLES, seed=11)


@pytest.fixture(scope='module')
def fresh_panda(panda_base):
    lower, upper = sampling_bounds(panda_base)
    return uniform_configurations(lower, upper, FRESH, np.random.default_rng(2024))


def test_panda_compared_with_the_shipped_srdf(panda_matrix, panda_srdf):
    shipped = _pairs_of(panda_srdf)
    found = {f.pair: f.reason for f in panda_matrix.findings}
    print(f'\nPanda (URDF only, seed {panda_matrix.seed}) against the shipped SRDF:')
    for reason in collision_matrix.REASONS:
        want = {p for p, r in shipped.items() if r == reason}
        got = {p for p, r in found.items() if r == reason}
        print(f'  {reason:<8} shipped {len(want):2d}  found {len(got & want):2d}  '
              f'missing {sorted(want - got)}  extra {sorted(got - want)}')
    other = {p: (r, found.get(p)) for p, r in shipped.items() if found.get(p) != r}
    print(f'  pairs where the reasons differ (shipped, ours): {other}')
    shipped_adjacent = {p for p, r in shipped.items() if r == collision_matrix.ADJACENT}
    assert shipped_adjacent <= set(panda_matrix.pairs(collision_matrix.ADJACENT))


def test_panda_adjacent_pairs_match_the_urdf_tree(panda_matrix, panda_urdf):
    # panda_hand hangs under panda_link8, which has no geometry: adjacent to panda_link7.
    assert set(panda_matrix.pairs(collision_matrix.ADJACENT)) == _adjacent_by_etree(panda_urdf)
    assert ('panda_hand', 'panda_link7') in panda_matrix.pairs(collision_matrix.ADJACENT)


def test_panda_default_pairs_are_what_python_fcl_sees_at_zero(panda_base, panda_matrix,
                                                              panda_urdf):
    adjacent = set(panda_matrix.pairs(collision_matrix.ADJACENT))
    oracle = FclOracle(panda_base, panda_urdf)
    at_zero = set(oracle.colliding_pairs(np.zeros(len(panda_base.joint_names)))) - adjacent
    assert set(panda_matrix.pairs(collision_matrix.DEFAULT)) == at_zero


def test_panda_always_pairs_hold_in_fresh_samples(panda_base, panda_matrix, fresh_panda):
    _assert_always_hold(panda_base, panda_matrix, fresh_panda)


def test_panda_sampled_statuses_agree_with_python_fcl(panda_base, panda_matrix, fresh_panda,
                                                      panda_urdf):
    """The raw matrix the tool counts: check_batch against python-fcl on fresh samples."""
    sampled = [p for p in panda_base.checked_pairs if p not in panda_matrix.pairs(collision_matrix.ADJACENT)]
    sampler = collision_matrix.pair_checker(panda_base, sampled)
    oracle = FclOracle(sampler, panda_urdf)
    subset = fresh_panda[:60]
    ours = sampler.check_batch(subset)
    for q, row in zip(subset, ours):
        expected = set(oracle.colliding_pairs(q))
        got = {pair for pair, hit in zip(sampler.checked_pairs, row) if hit}
        assert got == expected, f'q = {q.tolist()!r}'


def test_panda_never_pairs_report_their_samples(panda_matrix):
    never = [f for f in panda_matrix.findings if f.reason == collision_matrix.NEVER]
    assert never and all(f.hits == 0 and f.samples == NEVER_SAMPLES for f in never)
    assert all(f.clearance is None for f in never)
    assert collision_matrix_report.NO_DISTANCE in collision_matrix_report.report(panda_matrix)
    assert 'not proof' in collision_matrix_report.report(panda_matrix)


def test_panda_default_state_from_the_srdf(panda_base, panda_srdf, panda_urdf):
    srdf = load_srdf(panda_srdf)
    matrix = collision_matrix.compute_matrix(panda_base, srdf=srdf, default_state='default',
                                samples_per_round=200, seed=1)
    q = collision_matrix.default_configuration(panda_base, srdf, 'default')
    assert q[panda_base.joint_names.index('panda_joint4')] == -2.35619
    oracle = FclOracle(panda_base, panda_urdf)
    expected = set(oracle.colliding_pairs(q)) - set(matrix.pairs(collision_matrix.ADJACENT))
    assert set(matrix.pairs(collision_matrix.DEFAULT)) == expected
    assert matrix.default_state == 'default'


def _assert_always_hold(checker, matrix, fresh):
    """Each Always pair collides in >= the fraction of fresh samples, less 4 standard errors."""
    always = matrix.pairs(collision_matrix.ALWAYS)
    if not always:
        print(f'\n{matrix.robot_name}: no Always pair at {matrix.always_fraction}')
        return
    sampler = collision_matrix.pair_checker(checker, always)
    rates = sampler.check_batch(fresh).mean(axis=0)
    f = matrix.always_fraction
    margin = 4.0 * math.sqrt(f * (1.0 - f) / len(fresh))
    for pair, rate in zip(sampler.checked_pairs, rates):
        print(f'\n{matrix.robot_name}: Always {pair}: {rate:.4f} of {len(fresh)} fresh samples')
        assert rate >= f - margin, pair


# --- a hand-built robot whose rates follow from its geometry ---------------------------------
#
# base: a wall, the slab x in [1.02, 1.08] (y, z in [-0.5, 0.5]).
# mast (fixed on base): a 0.1 cube at z = 3, far from everything.
# gate (fixed on base): the slab x in [1.5, 1.56].
# slider (prismatic along x on mast, q in [0, 1]): a bar x in [q - 1, q + 1], 0.2 x 0.2 thick.
# The bar's side faces cross the wall when q >= 0.02 (rate 0.98, clear at q = 0) and the gate
# when q >= 0.5 (rate 0.5). Adjacent: base-mast, base-gate, mast-slider (siblings are not).
# gate-mast never meet: clearance sqrt(1.45^2 + 2.45^2) whatever q.

SLIDER_URDF = """<?xml version="1.0"?>
<robot name="slider_bench">
  <link name="base"><collision><origin xyz="1.05 0 0"/>
    <geometry><box size="0.06 1 1"/></geometry></collision></link>
  <link name="mast"><collision><origin xyz="0 0 3"/>
    <geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <link name="gate"><collision><origin xyz="1.53 0 0"/>
    <geometry><box size="0.06 1 1"/></geometry></collision></link>
  <link name="carriage"/>
  <link name="slider"><collision><geometry><box size="2 0.2 0.2"/></geometry></collision></link>
  <joint name="mast_joint" type="fixed"><parent link="base"/><child link="mast"/></joint>
  <joint name="gate_joint" type="fixed"><parent link="base"/><child link="gate"/></joint>
  <joint name="slide" type="prismatic"><parent link="mast"/><child link="carriage"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="1" effort="1" velocity="1"/></joint>
  <joint name="carriage_joint" type="fixed"><parent link="carriage"/><child link="slider"/>
  </joint>
</robot>
"""
GATE_MAST_CLEARANCE = math.hypot(1.53 - 0.03 - 0.05, 3 - 0.05 - 0.5)


@pytest.fixture(scope='module')
def slider_urdf(tmp_path_factory):
    path = tmp_path_factory.mktemp('slider') / 'slider_bench.urdf'
    path.write_text(SLIDER_URDF)
    return str(path)


@pytest.fixture(scope='module')
def slider_base(slider_urdf):
    return CollisionChecker.from_urdf(slider_urdf, config={'ignore_adjacent': False})


def test_slider_matrix_is_the_one_the_geometry_implies(slider_base):
    matrix = collision_matrix.compute_matrix(slider_base, never=True, clearance=True,
                                samples_per_round=SAMPLES, never_samples=NEVER_SAMPLES, seed=5)
    assert set(matrix.pairs(collision_matrix.ADJACENT)) == {('base', 'mast'), ('base', 'gate'),
                                               ('mast', 'slider')}
    assert matrix.pairs(collision_matrix.DEFAULT) == []
    assert matrix.pairs(collision_matrix.ALWAYS) == [('base', 'slider')]
    assert matrix.pairs(collision_matrix.NEVER) == [('gate', 'mast')]
    assert matrix.stable and matrix.rounds >= 2
    never, = [f for f in matrix.findings if f.reason == collision_matrix.NEVER]
    assert never.clearance == pytest.approx(GATE_MAST_CLEARANCE, abs=1e-6)
    assert f'smallest clearance {GATE_MAST_CLEARANCE:.4f} m over ' in collision_matrix_report.report(matrix)


# Gate and slider: the bar's end is 1.5 - (q + 1) = 0.5 - q from the gate for q < 0.5, in
# contact beyond: 0.5 m apart at most (at q = 0, the default pose, the first sample). Gate and
# mast: GATE_MAST_CLEARANCE apart whatever q.
@pytest.mark.parametrize('distance, listed', [
    (0.4, {}),                                                  # 0.5 > 0.4 at q = 0
    (0.6, {('gate', 'slider'): 0.5}),
    (3.0, {('gate', 'slider'): 0.5, ('gate', 'mast'): GATE_MAST_CLEARANCE}),
])
def test_slider_warning_zone_is_the_one_the_geometry_implies(slider_base, distance, listed):
    matrix = collision_matrix.compute_matrix(slider_base, samples_per_round=300, seed=5,
                                warning_distance=distance, warning_samples=500)
    zone = matrix.warning_zone
    # Checked: every pair but the Adjacent ones and the Always one (base, slider).
    assert zone.candidates == 2 and zone.samples == 500
    assert list(zone.farthest) == sorted(listed)
    for pair, farthest in listed.items():
        assert zone.farthest[pair] == pytest.approx(farthest, abs=1e-9)
    assert zone.warning_ignore() == [f'{a}:{b}' for a, b in sorted(listed)]


def test_warning_zone_leaves_out_the_srdf_pairs(slider_base, slider_urdf, tmp_path):
    srdf_path = tmp_path / 'slider.srdf'
    srdf_path.write_text('<robot name="slider_bench"><disable_collisions link1="slider" '
                         'link2="gate" reason="User"/></robot>')
    from collision_sensor.model.srdf import load_srdf_for_model
    srdf = load_srdf_for_model(str(srdf_path), slider_base.model)
    matrix = collision_matrix.compute_matrix(slider_base, srdf=srdf, samples_per_round=300, seed=5,
                                warning_distance=3.0, warning_samples=200)
    assert matrix.warning_zone.candidates == 1
    assert list(matrix.warning_zone.farthest) == [('gate', 'mast')]


def test_slider_always_rates_match_the_closed_form(slider_base):
    matrix = collision_matrix.compute_matrix(slider_base, always_fraction=0.4, samples_per_round=SAMPLES,
                                seed=6)
    assert set(matrix.pairs(collision_matrix.ALWAYS)) == {('base', 'slider'), ('gate', 'slider')}
    fresh = uniform_configurations(*sampling_bounds(slider_base), FRESH,
                                      np.random.default_rng(99))
    q = fresh[:, 0]
    closed_form = {('base', 'slider'): np.mean(q >= 0.02), ('gate', 'slider'): np.mean(q >= 0.5)}
    sampler = collision_matrix.pair_checker(slider_base, list(closed_form))
    statuses = sampler.check_batch(fresh)
    for column, pair in enumerate(sampler.checked_pairs):
        away = np.abs(q - (0.02 if pair[0] == 'base' else 0.5)) > 1e-6
        assert np.array_equal(statuses[away, column],
                              (q >= (0.02 if pair[0] == 'base' else 0.5))[away]), pair
        assert closed_form[pair] >= 0.4
    _assert_always_hold(slider_base, matrix, fresh)
    found = {f.pair: f for f in matrix.findings}
    assert found[('base', 'slider')].hits / found[('base', 'slider')].samples == \
        pytest.approx(0.98, abs=0.02)
    assert found[('gate', 'slider')].hits / found[('gate', 'slider')].samples == \
        pytest.approx(0.5, abs=0.05)


def test_same_seed_same_matrix(slider_base):
    first = collision_matrix.compute_matrix(slider_base, never=True, samples_per_round=300, seed=8)
    again = collision_matrix.compute_matrix(slider_base, never=True, samples_per_round=300, seed=8)
    assert first == again


# --- robots without an SRDF get a usable list --------------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize('robot', ['ur5', 'demo_arm'])
def test_generated_list_clears_the_zero_pose(capsys, tmp_path, robot, ur5_urdf,
                                             erd_package_paths):
    if robot == 'ur5':
        urdf, packages = ur5_urdf, erd_package_paths
        argv = [urdf, '--package-path', f'example-robot-data={packages["example-robot-data"]}']
    else:
        urdf, packages, argv = config_path('demo_arm.urdf'), None, [config_path('demo_arm.urdf')]
    params = tmp_path / 'acm.yaml'
    srdf = tmp_path / 'acm.srdf'
    status, out, err = _run(capsys, argv + ['--samples-per-round', str(SAMPLES), '--never',
                                            '--never-samples', str(NEVER_SAMPLES),
                                            '--yaml', str(params), '--output', str(srdf),
                                            '--progress', 'never'])
    assert status == 0, err
    assert 'took ' in out and 'not proof' in out
    listed = yaml.safe_load(params.read_text())['/**']['ros__parameters']['allowed_collisions']
    assert f'allowed_collisions: [{", ".join(chr(34) + e + chr(34) for e in listed)}]' in out
    written = _pairs_of(str(srdf))
    assert {tuple(sorted(e.split(':'))) for e in listed} == set(written)
    assert set(written.values()) <= set(collision_matrix.REASONS)
    assert {p for p, r in written.items() if r == 'Adjacent'} == _adjacent_by_etree(urdf)
    zero = np.zeros
    for ignore_adjacent in (True, False):
        checker = CollisionChecker.from_urdf(
            urdf, package_paths=packages,
            config={'allowed_collisions': listed, 'ignore_adjacent': ignore_adjacent})
        assert checker.check(zero(len(checker.joint_names))).in_collision is False
    # Without the list the zero pose is not clear (else the test proves nothing).
    raw = CollisionChecker.from_urdf(urdf, package_paths=packages,
                                     config={'ignore_adjacent': False})
    assert raw.check(zero(len(raw.joint_names))).in_collision is True


# --- the warning zone of a real robot, from the command line -----------------------------------

@pytest.mark.slow
def test_ur5_warning_ignore_from_the_command_line_against_python_fcl(ur5_urdf, ur5_srdf,
                                                                     erd_share, tmp_path):
    """The issue's UR5: ee_link and wrist_2_link are 0.0198 m apart wherever the arm goes. The
    tool runs as a user runs it; python-fcl (with pinocchio's kinematics) measures the pairs
    on fresh samples."""
    import subprocess
    from collision_sensor.ros.console_scripts import console_command
    distance = 0.05
    params = tmp_path / 'ur5_acm.yaml'
    run = subprocess.run(console_command('collision_sensor_acm') + [
        ur5_urdf, '--srdf', ur5_srdf, '--package-path', f'example-robot-data={erd_share}',
        '--warning-distance', str(distance), '--warning-samples', '500',
        '--samples-per-round', '500', '--yaml', str(params), '--progress', 'never'],
        capture_output=True, text=True, timeout=300, cwd=str(tmp_path))
    assert run.returncode == 0, run.stderr
    document = yaml.safe_load(params.read_text())
    listed = document['/**']['ros__parameters']['warning_ignore']
    assert 'ee_link:wrist_2_link' in listed
    assert f'warning_ignore: [{", ".join(chr(34) + e + chr(34) for e in listed)}]' in run.stdout
    farthest = re.search(r'Warning\s+ee_link -- wrist_2_link\s+at most (\d\.\d+) m', run.stdout)
    assert farthest and float(farthest.group(1)) == pytest.approx(0.0198, abs=1e-4), run.stdout
    # A ros2 params file as rclpy reads it: a string array.
    from rclpy.parameter import parameter_dict_from_yaml_file
    parameters = parameter_dict_from_yaml_file(str(params), use_wildcard=True)
    assert list(parameters['warning_ignore'].value.string_array_value) == listed

    # The oracle: every checked pair's distance on fresh samples. Listed pairs stay below the
    # distance in all of them; every other pair reaches it in at least one.
    checker = CollisionChecker.from_urdf(ur5_urdf, srdf=ur5_srdf,
                                         package_paths={'example-robot-data': erd_share})
    oracle = FclOracle(checker, ur5_urdf)
    fresh = uniform_configurations(*sampling_bounds(checker), 200, np.random.default_rng(31))
    farthest_fcl = {pair: 0.0 for pair in checker.checked_pairs}
    for q in fresh:
        poses = oracle.poses(q)
        for pair in checker.checked_pairs:
            farthest_fcl[pair] = max(farthest_fcl[pair], oracle.pair_distance(poses, *pair))
    below = sorted(f'{a}:{b}' for (a, b), d in farthest_fcl.items() if d < distance)
    assert below == sorted(listed), farthest_fcl
    assert farthest_fcl[('ee_link', 'wrist_2_link')] == pytest.approx(0.0198, abs=1e-4)


@pytest.mark.parametrize('value', ['0', '-0.1', 'inf', 'nan', 'near'])
def test_bad_warning_distance(capsys, value):
    status, out, err = _run(capsys, [config_path('demo_arm.urdf'), '--warning-distance', value])
    assert status == 2
    assert '--warning-distance' in _error_line(err)


def test_help_no_longer_says_the_engine_has_no_distance_query(capsys):
    status, out, err = _run(capsys, ['--help'])
    text = ' '.join(out.split())
    assert status == 0 and 'no distance' not in text and 'python-fcl' not in text
    assert '--warning-distance D' in text and 'warning_ignore' in text


# --- merging into an SRDF ------------------------------------------------------------------------

def _strip_new_lines(merged: bytes, original_pairs) -> bytes:
    """Remove the whole lines holding a <disable_collisions> of a pair the original lacked."""
    kept = []
    for line in merged.splitlines(keepends=True):
        text = line.decode('utf-8').strip()
        if text.startswith('<disable_collisions'):
            element = ET.fromstring(text)
            pair = tuple(sorted((element.get('link1'), element.get('link2'))))
            if pair not in original_pairs:
                continue
        kept.append(line)
    return b''.join(kept)


@pytest.fixture
def edited_panda_srdf(panda_srdf, tmp_path):
    """The shipped SRDF with its Adjacent and Never lines taken out, one reason changed by hand,
    a comment added, and CRLF line ends: what a merge must keep."""
    lines = []
    with open(panda_srdf, 'rb') as stream:
        for line in stream.read().splitlines():
            if b'reason="Adjacent"' in line or b'reason="Never"' in line:
                continue
            lines.append(line.replace(b'link2="panda_link7" reason="Default"',
                                      b'link2="panda_link7" reason="Hand-checked"'))
    lines.insert(2, b'    <!-- kept: a comment, a blank line and CRLF -->')
    lines.insert(3, b'')
    path = tmp_path / 'panda_edited.srdf'
    path.write_bytes(b'\r\n'.join(lines) + b'\r\n')
    return path


def test_merge_keeps_the_srdf_byte_for_byte_and_adds_nothing_twice(
        capsys, tmp_path, edited_panda_srdf, panda_urdf, erd_package_paths):
    original = edited_panda_srdf.read_bytes()
    original_pairs = _pairs_of(str(edited_panda_srdf))
    argv = [panda_urdf, '--package-path',
            f'example-robot-data={erd_package_paths["example-robot-data"]}',
            '--srdf', str(edited_panda_srdf), '--never', '--samples-per-round', '500',
            '--never-samples', '1500', '--progress', 'never']
    merged_path = tmp_path / 'merged.srdf'
    status, out, err = _run(capsys, argv + ['--output', str(merged_path)])
    assert status == 0, err
    assert edited_panda_srdf.read_bytes() == original  # --output leaves the input alone
    merged = merged_path.read_bytes()
    assert _strip_new_lines(merged, original_pairs) == original
    merged_pairs = _pairs_of(str(merged_path))
    assert merged_pairs[('panda_link5', 'panda_link7')] == 'Hand-checked'  # kept as it was
    added = {p: r for p, r in merged_pairs.items() if p not in original_pairs}
    assert added and {r for r in added.values()} <= {'Adjacent', 'Never'}
    new_lines = [line for line in merged.splitlines(keepends=True)
                 if line not in original.splitlines(keepends=True)]
    assert len(new_lines) == len(added)
    assert all(line.startswith(b'    <disable_collisions') and line.endswith(b'\r\n')
               for line in new_lines)
    assert merged.rstrip().endswith(b'</robot>')
    # Again, in place: nothing to add, not a byte changes.
    status, out, err = _run(capsys, argv[:5] + ['--srdf', str(merged_path), '--in-place',
                                                '--never', '--samples-per-round', '500',
                                                '--never-samples', '1500'])
    assert status == 0, err
    assert merged_path.read_bytes() == merged
    assert 'added 0 new' in out


def test_merge_closing_tag_shares_a_line():
    original = (b'<robot name="r"><link name="a"/>'
                b'<disable_collisions link1="b" link2="a" reason="User"/></robot>\n')
    merged, added = merge_disable_collisions(
        original, [('a', 'b', 'Never'), ('a', 'c', 'Adjacent'), ('a', 'c', 'Never')])
    assert added == [('a', 'c', 'Adjacent')]
    assert merged == (b'<robot name="r"><link name="a"/>'
                      b'<disable_collisions link1="b" link2="a" reason="User"/>\n'
                      b'  <disable_collisions link1="a" link2="c" reason="Adjacent"/>\n'
                      b'</robot>\n')


def test_merge_indents_like_the_document_and_keeps_trailing_comments():
    original = b'<robot name="r">\n\t<group name="g"/>\n</robot>\n<!-- </robot> -->\n'
    merged, added = merge_disable_collisions(original, [('a', 'b', 'Never')])
    assert merged == (b'<robot name="r">\n\t<group name="g"/>\n'
                      b'\t<disable_collisions link1="a" link2="b" reason="Never"/>\n'
                      b'</robot>\n<!-- </robot> -->\n')
    assert merge_disable_collisions(merged, [('b', 'a', 'Always')]) == (merged, [])


def test_merge_refuses_an_empty_root():
    from collision_sensor.errors import SrdfError
    with pytest.raises(SrdfError, match='no closing </robot>'):
        merge_disable_collisions(b'<robot name="r"/>', [('a', 'b', 'Never')], 'x.srdf')


def test_new_srdf_reads_back():
    text = new_srdf('r&d', [('a', 'b', 'Adjacent'), ('a"x', 'c', 'Never')], 'made -- here')
    srdf = load_srdf(text)
    assert srdf.robot_name == 'r&d'
    assert {(p.link1, p.link2, p.reason) for p in srdf.disabled_pairs} == {
        ('a', 'b', 'Adjacent'), ('a"x', 'c', 'Never')}


# --- bad input -------------------------------------------------------------------------------

def test_missing_urdf(capsys, tmp_path):
    missing = str(tmp_path / 'nowhere.urdf')
    status, out, err = _run(capsys, [missing])
    assert status == 2 and out == ''
    assert missing in _error_line(err)


def test_unknown_default_state(capsys, panda_urdf, panda_srdf, erd_package_paths):
    status, out, err = _run(capsys, [
        panda_urdf, '--package-path',
        f'example-robot-data={erd_package_paths["example-robot-data"]}', '--srdf', panda_srdf,
        '--default-state', 'nope'])
    assert status == 2
    line = _error_line(err)
    assert '"nope"' in line and '"default"' in line and panda_srdf in line


@pytest.mark.parametrize('fraction', ['1.5', '0', '-0.2', 'abc', 'nan'])
def test_bad_fraction(capsys, fraction):
    status, out, err = _run(capsys, [config_path('demo_arm.urdf'), '--always-fraction', fraction])
    assert status == 2
    assert '--always-fraction' in _error_line(err)


@pytest.mark.parametrize('argv, words', [
    (['--default-state', 'home'], '--srdf'),
    (['--in-place'], '--srdf'),
    (['--clearance'], '--never'),
    (['--package-path', 'nodirectory'], 'NAME=DIR'),
    (['--samples-per-round', '0'], '--samples-per-round'),
    (['--max-rounds', '1'], '--max-rounds'),
])
def test_bad_options(capsys, argv, words):
    status, out, err = _run(capsys, [config_path('demo_arm.urdf')] + argv)
    assert status == 2
    assert words in _error_line(err)


def test_help_says_sampling_is_not_proof(capsys):
    status, out, err = _run(capsys, ['--help'])
    assert status == 0
    assert 'not proof' in ' '.join(out.split())


def test_the_tool_does_not_import_rclpy():
    import subprocess
    import sys
    code = ('import sys, collision_sensor.tools.acm, collision_sensor.model.srdf_merge; '
            'sys.exit(1 if "rclpy" in sys.modules else 0)')
    assert subprocess.run([sys.executable, '-c', code]).returncode == 0
