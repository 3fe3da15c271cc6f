"""Smoke test of ``python -m benchmarks audit``: it runs small, prints its table and targets,
and every run gives the same report lines; no timing checks (timing is the benchmark's)."""
import pytest

from benchmarks import main as bench


@pytest.mark.slow
def test_small_audit_benchmark_prints_runs_rates_and_targets(tmp_path, capsys):
    table = tmp_path / 'audit.md'
    assert bench.main(['audit', '--recordings', '6', '--frames', '40', '--runs', '2',
                       '--no-ray', '--markdown', str(table)]) == 0
    text = table.read_text()
    assert capsys.readouterr().out.strip() == text.strip()
    assert '6 CSV recordings of 40 Panda frames (240 frames' in text
    for row in ('| jobs 1 |', '| jobs 2 |', '| --jobs 2 >= 1.8x --jobs 1 |'):
        assert row in text
    assert 'Every run gave the same report lines: yes.' in text
    assert 'check_batch' in text and 'update_batch' in text
