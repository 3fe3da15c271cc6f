"""Several runs of the benchmark as one report: every figure with its spread.

``python -m benchmarks --runs N`` runs the chosen scenarios N times in a row (same seed, so
the same inputs, tables and rows) and merges the N markdown reports line by line:

- a line that is the same in every run stays as it is;
- a line (a table row cell by cell, or a sentence) whose runs differ only in their numbers
  gets, for each number, the median run's figure followed by the range over the runs:
  ``2.32 [2.30-2.41]``. The median is the median value of that one figure; its text is the
  run's own (its digits, its thousands separators);
- anything else (a verdict that differs, a line only some runs have) lists the runs' versions
  side by side, ``run 1 / run 2 / run 3``, so no run's answer is hidden.

On a shared machine the best of N runs says little; the median and the range say what a reader
will see when they run it.
"""
import re
import statistics
from typing import List, Sequence

#: A figure in a report: digits with optional thousands separators and decimals, perhaps with
#: a unit after it (0.07x, 33.5us), not inside a word, a time or a date (panda_link0, S12,
#: 11:10 and 1998-06-30 stay text).
NUMBER = re.compile(r'(?<![\w.:-])(?:\d{1,3}(?:,\d{3})+|\d+)(?:\.\d+)?(?![\d,.:-]\d)(?:[x%](?!\w))?')


def _value(text: str) -> float:
    return float(text.replace(',', '').rstrip('x%'))


def merge_line(lines: Sequence[str]) -> str:
    """Merge one line of each run (see the module docstring)."""
    if all(line == lines[0] for line in lines):
        return lines[0]
    if all(line.startswith('|') for line in lines):
        cells = [line.strip().strip('|').split('|') for line in lines]
        if all(len(c) == len(cells[0]) for c in cells):
            merged = [merge_text([c[k] for c in cells]) for k in range(len(cells[0]))]
            return '|' + '|'.join(merged) + '|'
    return merge_text(lines)


def merge_text(texts: Sequence[str]) -> str:
    """Merge one text of each run: figure by figure when only figures differ, else side by
    side."""
    if all(text == texts[0] for text in texts):
        return texts[0]
    skeletons = [NUMBER.sub('#', text) for text in texts]
    if any(s != skeletons[0] for s in skeletons):
        return ' ' + ' / '.join(text.strip() for text in texts) + ' '
    figures = [NUMBER.findall(text) for text in texts]
    out = []
    for k in range(len(figures[0])):
        column = [f[k] for f in figures]
        values = [_value(v) for v in column]
        middle = statistics.median_low(values)
        shown = column[values.index(middle)]
        low, high = column[values.index(min(values))], column[values.index(max(values))]
        out.append(shown if low == high else f'{shown} [{low}-{high}]')
    parts = NUMBER.split(texts[0])
    return ''.join(part + (out[k] if k < len(out) else '') for k, part in enumerate(parts))


def merge_reports(reports: Sequence[str]) -> str:
    """Merge the markdown reports of N runs (one string each)."""
    if len(reports) == 1:
        return reports[0]
    split = [report.splitlines() for report in reports]
    note = (f'**{len(reports)} runs**, merged: each figure is the median run\'s, with the range '
            'over the runs in brackets; where runs differ otherwise their versions are listed '
            'side by side (run 1 / run 2 / ...).')
    if any(len(lines) != len(split[0]) for lines in split):
        # The runs' tables differ in shape: each run whole, one after the other.
        out: List[str] = [note, '']
        for k, report in enumerate(reports):
            out += [f'#### Run {k + 1}', '', report]
        return '\n'.join(out) + '\n'
    merged = [merge_line(lines) for lines in zip(*split)]
    for k, line in enumerate(split[0]):
        if line.startswith('Machine: '):     # the header's machine line
            merged[k + 1:k + 1] = ['', note]
            break
    else:
        merged[0:0] = [note, '']
    return '\n'.join(merged) + '\n'
