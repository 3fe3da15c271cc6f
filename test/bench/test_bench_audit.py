"""Smoke test of ``python -m benchmarks audit``: it runs small, prints its table and targets,
and every run gives the same report lines; the arithmetic of ``audit cluster``'s projection;
``audit dataset`` run small (slow: the SO-101). No timing checks (timing is the
benchmark's)."""
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


def test_the_cluster_projection_solves_its_equation_and_the_fit_finds_its_terms():
    """The cluster benchmark's arithmetic: the fit recovers the terms of made-up driver CPU
    figures, and the projected W saturates one core, W * c(W) = t * (1 - r)."""
    import numpy as np
    from benchmarks.audit_cluster import DEPTH, fit, projection
    rng = np.random.default_rng(7)
    truth = {'r': 0.004, 'c_call': 7e-4, ('CSV', False): 2e-5, ('LeRobot', True): 3e-5}
    samples = []
    for group in (('CSV', False), ('LeRobot', True)):
        for _ in range(6):
            m = {'seconds': rng.uniform(1, 15), 'calls': int(rng.integers(5, 60)),
                 'units': int(rng.integers(30, 700))}
            m['cpu'] = (truth['r'] * m['seconds'] + truth['c_call'] * m['calls']
                        + truth[group] * m['units'])
            samples.append((group, m))
    found = fit(samples)
    assert abs(found['r'] - truth['r']) < 1e-9 and abs(found['c_call'] - truth['c_call']) < 1e-9
    for group in (('CSV', False), ('LeRobot', True)):
        assert abs(found['c_unit'][group] - truth[group]) < 1e-9
    c_unit, c_call, k, t, b, r = 2e-5, 7e-4, 8, 0.9, 3.8e-7, 0.004
    workers = projection(c_unit, c_call, k, t, b, r)
    cost = c_unit + (c_call + b * DEPTH * workers) / k
    assert abs(workers * cost - t * (1 - r)) < 1e-9 and 1000 < workers < 10_000
    assert abs(projection(c_unit, c_call, k, t, 0.0, r) - t * (1 - r) / (c_unit + c_call / k)) \
        < 1e-6


@pytest.mark.slow
def test_small_dataset_benchmark_prints_runs_memory_and_targets(tmp_path, capsys):
    table = tmp_path / 'dataset.md'
    assert bench.main(['audit', 'dataset', '--episodes', '4', '--frames', '60', '--runs', '1',
                       '--markdown', str(table)]) == 0
    text = table.read_text()
    assert capsys.readouterr().out.strip() == text.strip()
    assert '4 episodes of 60 frames at 30 fps (240 frames' in text
    assert 'Every run gave the same report lines: yes.' in text
    for row in ('| --jobs 1 |', '| --jobs 2 |', '| --jobs 2 >= 1.5x --jobs 1, as the user waits',
                "| an extra worker's own memory < 10% of the first's"):
        assert row in text
