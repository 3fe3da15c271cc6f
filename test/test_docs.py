"""The README and docs/: every relative link and anchor resolves, the README keeps the commands
CI runs, and what the reference pages list (parameters, topics, the Python example) is what the
code has.

Anchors are GitHub's: a heading's text, lower case, without punctuation other than ``-`` and
``_``, spaces as ``-``, a repeated heading suffixed ``-1``, ``-2``. No ROS is started.
"""
import os
import re
import shlex

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOCS = os.path.join(REPO, 'docs')
PAGES = [os.path.join(REPO, 'README.md')] + sorted(
    os.path.join(DOCS, name) for name in os.listdir(DOCS) if name.endswith('.md'))
FENCE = re.compile(r'^(```|~~~).*?^\1[ \t]*$', re.M | re.S)
LINK = re.compile(r'!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+"[^"]*")?\s*\)')
HEADING = re.compile(r'^(#{1,6})[ \t]+(.+?)[ \t]*#*[ \t]*$', re.M)
#: Modules of collision_sensor/ros/ that are tools beside the node, not the node itself (the
#: player's, the demo's and collision_sensor_ctl's; names starting so).
NOT_THE_NODE = ('player.py', 'sequence_player.py', 'playback_', 'demo', 'ctl.py')


def read(path):
    with open(path, encoding='utf-8') as stream:
        return stream.read()


def prose(text):
    """The text outside fenced code blocks and inline code (their brackets are not links)."""
    text = FENCE.sub('', text)
    return re.sub(r'`[^`\n]*`', lambda m: '' if '](' in m.group(0) else m.group(0), text)


def slug(heading):
    """GitHub's anchor for a heading's text."""
    text = re.sub(r'!?\[([^\]]*)\]\([^)]*\)', r'\1', heading)   # a link's text only
    text = text.replace('`', '').strip().lower()
    text = re.sub(r'[^\w\- ]', '', text)
    return text.replace(' ', '-')


def anchors(path):
    seen = {}
    found = set()
    for _, heading in HEADING.findall(FENCE.sub('', read(path))):
        base = slug(heading)
        count = seen.get(base, 0)
        seen[base] = count + 1
        found.add(base if count == 0 else f'{base}-{count}')
    return found


def relative_links(path):
    for target in LINK.findall(prose(read(path))):
        if re.match(r'^[a-z][a-z0-9+.-]*:', target):     # http:, https:, mailto:
            continue
        yield target


def test_slugs_are_githubs():
    assert slug('Motion between joint states: `check_motion`') == \
        'motion-between-joint-states-check_motion'
    assert slug('Performance against pinocchio+coal and python-fcl') == \
        'performance-against-pinocchiocoal-and-python-fcl'
    assert slug('Recordings: `collision_sensor_check --motion`') == \
        'recordings-collision_sensor_check---motion'
    assert slug("Run to run: S2 by seed, S4's growth") == 'run-to-run-s2-by-seed-s4s-growth'


def test_links_are_found_and_code_is_not_read_as_links(tmp_path):
    page = tmp_path / 'page.md'
    page.write_text('# A page\n\n[one](other.md#x), ![two\nlines](img/a.png), '
                    '[web](https://example.org) and `[not](a-link.md)`.\n\n'
                    '```md\n[nor](this.md)\n# Nor a heading\n```\n')
    assert list(relative_links(str(page))) == ['other.md#x', 'img/a.png']
    assert anchors(str(page)) == {'a-page'}


@pytest.mark.parametrize('page', PAGES, ids=[os.path.relpath(p, REPO) for p in PAGES])
def test_every_relative_link_and_anchor_resolves(page):
    broken = []
    for target in relative_links(page):
        file_part, _, anchor = target.partition('#')
        resolved = (os.path.normpath(os.path.join(os.path.dirname(page), file_part))
                    if file_part else page)
        if not os.path.exists(resolved):
            broken.append(f'{target}: no file {os.path.relpath(resolved, REPO)}')
        elif anchor and resolved.endswith('.md') and anchor not in anchors(resolved):
            broken.append(f'{target}: no heading with anchor "#{anchor}" in '
                          f'{os.path.relpath(resolved, REPO)}')
    assert not broken, '\n'.join(broken)


#: What user docs do not hold: a date, a time in UTC, a commit hash (history is the commits').
DATED = re.compile(r'\b20\d\d-\d\d-\d\d\b|\bUTC\b'
                   r'|\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*\d)[0-9a-f]{7,40}\b')


@pytest.mark.parametrize('page', [os.path.relpath(path, REPO) for path in PAGES])
def test_no_page_holds_a_date_or_a_commit(page):
    found = [line for line in read(os.path.join(REPO, page)).splitlines() if DATED.search(line)]
    assert found == []


def test_the_date_check_sees_dates_and_hashes():
    for text in ('on 2026-11-25', '01:51 UTC', 'commit 1399db0', 'at a339679'):
        assert DATED.search(text), text
    for text in ('10000000 triangles', 'deadbeef', 'panda_link0'):
        assert not DATED.search(text), text


def ci_test_command():
    """The command ``.ci/run`` runs: its last line that is not set-up (set, cd, export, echo)."""
    commands = [line.strip() for line in read(os.path.join(REPO, '.ci', 'run')).splitlines()
                if line.strip() and not line.lstrip().startswith('#')]
    setup = ('set ', 'cd ', 'export ', 'echo ')
    return [line for line in commands if not line.startswith(setup)][-1]


def test_the_readme_shows_the_command_ci_runs_and_the_demo():
    command = ci_test_command()
    assert command == 'make test'
    blocks = re.findall(r'^```sh\n(.*?)^```', read(os.path.join(REPO, 'README.md')), re.M | re.S)
    lines = [line.split('#')[0].strip() for block in blocks for line in block.splitlines()]
    assert command in lines and 'make demo' in lines


def test_the_readme_shows_how_to_run_the_node_on_your_own_robot():
    """The console script with --ros-args and a urdf_path, and a params file (issue 28)."""
    readme = read(os.path.join(REPO, 'README.md'))
    blocks = re.findall(r'^```sh\n(.*?)^```', readme, re.M | re.S)
    commands = [block.replace('\\\n', ' ') for block in blocks]
    node = [line for block in commands for line in block.splitlines()
            if line.strip().startswith('.venv/bin/collision_sensor_node --ros-args')]
    assert node and '-p urdf_path:=' in node[0], commands
    for word in shlex.split(node[0]):
        if word.startswith('__ns:=') or ':=' not in word or word.startswith('-'):
            continue
        name = word.split(':=')[0]
        assert name in node_parameter_names(), f'{name} is no parameter of the node'
    assert 'config/collision_sensor.yaml' in readme and 'ros__parameters:' in readme


#: ros2 commands a user runs against a running node (not ros2 run, which starts one).
RUNTIME_ROS2 = re.compile(r'ros2 (param|topic|bag|service) \w+ (/|-)')


def paragraphs(text):
    """Paragraphs of prose, table rows and fenced blocks, each a piece of its own."""
    pieces = []
    for block in re.split(r'\n\s*\n', text):
        pieces.extend(block.splitlines() if block.lstrip().startswith('|') else [block])
    return pieces


def test_every_runtime_ros2_command_shown_has_its_pip_equivalent_beside_it():
    """A pip install has no ros2 command line: wherever the docs show one to run against the
    node, collision_sensor_ctl's equivalent is in the same paragraph or table row."""
    alone = []
    for path in PAGES:
        for piece in paragraphs(read(path)):
            if RUNTIME_ROS2.search(piece) and 'collision_sensor_ctl' not in piece:
                alone.append(f'{os.path.relpath(path, REPO)}: {" ".join(piece.split())[:120]}')
    assert alone == []


def test_every_collision_sensor_ctl_command_shown_parses():
    from collision_sensor.ros.ctl import build_parser
    shown = set()
    for path in PAGES + [os.path.join(REPO, 'config', 'collision_sensor.yaml')]:
        text = read(path).replace('\\\n', ' ').replace('\n', ' ')
        shown.update(re.findall(r'collision_sensor_ctl ((?:param|echo|trajectory|scene|record)'
                                r'[^`),]*)', text))
    assert len(shown) >= 8, shown
    for command in shown:
        words = [w for w in shlex.split(command.split(' or ')[0]) if w != '...']
        parser = build_parser()
        try:
            parser.parse_args(words)
        except SystemExit:
            pytest.fail(f'collision_sensor_ctl {command!r} does not parse')


def node_parameter_names():
    from collision_sensor.ros.node_parameters import PARAMETERS
    return {spec.name for spec in PARAMETERS}


def test_the_node_reference_lists_every_parameter():
    table = re.findall(r'^\| `([a-z_]+)` \|', read(os.path.join(DOCS, 'parameters.md')), re.M)
    assert set(table) >= node_parameter_names(), node_parameter_names() - set(table)


def node_topics():
    """Every topic the node's modules publish or subscribe, as written in the source."""
    ros = os.path.join(REPO, 'collision_sensor', 'ros')
    call = re.compile(r"create_(?:publisher|subscription)\(\s*\w+\s*,\s*'([^']+)'")
    topics = set()
    for name in os.listdir(ros):
        if name.endswith('.py') and not name.startswith(NOT_THE_NODE):
            topics.update(call.findall(read(os.path.join(ros, name))))
    return topics


@pytest.mark.parametrize('page', ['README.md', 'docs/node.md'])
def test_the_topic_tables_name_every_topic_of_the_node(page):
    topics = node_topics()
    assert {'joint_states', 'contact', 'colliding_pairs', 'scene', 'trajectory',
            'trajectory_out', '/diagnostics', '~/markers'} <= topics   # the parse still works
    table = set(re.findall(r'^\| `([^`]+)` \|', read(os.path.join(REPO, page)), re.M))
    assert topics <= table, topics - table


def test_the_readme_python_example_runs_and_says_what_it_prints(monkeypatch):
    """The example's comments against what the calls return (run from the repository root,
    as the README says)."""
    readme = read(os.path.join(REPO, 'README.md'))
    code, = re.findall(r'^```python\n(.*?)^```', readme, re.M | re.S)
    monkeypatch.chdir(REPO)
    calls = [line for line in code.splitlines() if line.startswith('checker.')]
    setup = '\n'.join(line for line in code.splitlines() if line not in calls)
    scope = {}
    exec(compile(setup, 'README.md', 'exec'), scope)
    answers = [eval(call.split('#')[0], scope) for call in calls]
    check, update, motion, trajectory = answers

    def shown(field):
        digits, = re.findall(field + r'=([0-9.]+?)\.\.\.', code)
        return digits
    assert not check.in_collision and check.colliding_pairs == ()
    assert update.in_collision
    assert motion.in_collision and repr(motion.first_contact).startswith(shown('first_contact'))
    assert motion.colliding_pairs == (('tool_link', 'washer_cabinet'),)
    assert not trajectory.valid and trajectory.first_invalid_segment == 0
    assert repr(trajectory.time_from_start).startswith(shown('time_from_start'))
