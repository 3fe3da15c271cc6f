"""``python -m benchmarks page`` (``make bench``): it writes docs/performance.md from the
benchmarks' runs, each section with its command and its spread, without dates; ``--only``
replaces one section and keeps the others. Quick runs of two small benchmarks; no timing
checks. The committed page has a section for every benchmark."""
import os
import re

import pytest
from benchmark_process import run_benchmark

from benchmarks import page

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
#: What a page must not hold: a date, a time of day in UTC, a commit hash.
UNDATED = re.compile(r'\b20\d\d-\d\d-\d\d\b|\bUTC\b'
                     r'|\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*\d)[0-9a-f]{7,40}\b')


@pytest.mark.slow
def test_page_sections_have_their_command_and_spread_and_only_replaces_one(tmp_path):
    output = tmp_path / 'performance.md'
    run = run_benchmark('benchmarks', 'page', '--runs', 3, '--quick', '--only', 'fk',
                        '--output', output, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    first = output.read_text()
    assert first.startswith('# Performance\n') and '\nMachine: ' in first
    fk = page.sections_of(first)['fk']
    assert '`python -m benchmarks.fk --configs 50` (3 runs)' in fk
    assert '**3 runs**' in fk and re.search(r'\d \[\d[^\]]*-[^\]]*\d\]', fk), fk
    assert page.QUICK_NOTE in fk
    assert not UNDATED.search(first), UNDATED.search(first)

    run = run_benchmark('benchmarks', 'page', '--runs', 3, '--quick', '--only', 'acm',
                        '--output', output, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    second = page.sections_of(output.read_text())
    assert list(second) == ['fk', 'acm']          # in the page's order
    assert second['fk'] == fk                       # kept as it was
    assert '### Sampling rate on the Panda' in second['acm']   # its markdown, shown as such


def test_a_failing_benchmark_fails_the_page_and_writes_nothing(tmp_path, monkeypatch):
    broken = page.Benchmark('fk', 'x', 'x', lambda runs, quick, out: ['benchmarks.no_such'])
    monkeypatch.setattr(page, 'BENCHMARKS', (broken,))
    output = tmp_path / 'performance.md'
    assert page.main(['--runs', '1', '--output', str(output)]) == 1
    assert not output.exists()



def test_the_committed_page_has_every_benchmark_and_no_date():
    with open(os.path.join(ROOT, 'docs', 'performance.md'), encoding='utf-8') as stream:
        text = stream.read()
    assert list(page.sections_of(text)) == list(page.NAMES)
    assert not UNDATED.search(text), UNDATED.search(text)
