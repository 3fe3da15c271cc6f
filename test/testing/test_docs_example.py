"""docs/testing.md's planner test, as a user runs it: the block saved as a file of its own in an
empty directory (no conftest, nothing imported: the fixture comes from the package's pytest11
entry point) and run by pytest in a process of its own."""
import os
import pathlib
import re
import subprocess
import sys

DOC = pathlib.Path(__file__).parents[2] / 'docs' / 'testing.md'


def planner_test() -> str:
    section = DOC.read_text().split("## The planner's test", 1)[1]
    return re.search(r'```python\n(.*?)```', section, re.S).group(1)


def test_the_planner_test_of_the_docs_passes_in_at_most_25_lines(tmp_path):
    code = planner_test()
    assert len(code.splitlines()) <= 25
    (tmp_path / 'test_planner.py').write_text(code)
    env = dict(os.environ, COLLISION_SENSOR_TEST_DOMAIN=os.environ['ROS_DOMAIN_ID'])
    run = subprocess.run([sys.executable, '-m', 'pytest', 'test_planner.py', '-q',
                          '-p', 'no:cacheprovider'], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0 and '2 passed' in run.stdout, run.stdout + run.stderr
