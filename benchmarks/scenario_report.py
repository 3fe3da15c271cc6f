"""The benchmark's output: sections of markdown, targets with a PASS/MISS verdict each."""
import math
import os
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence


@dataclass
class Verdict:
    """A target and how this run did against it; ``passed`` None when it cannot be judged."""

    target: str
    measured: str
    passed: Optional[bool]

    @property
    def word(self) -> str:
        return {True: 'PASS', False: 'MISS', None: 'n/a'}[self.passed]


@dataclass
class Section:
    """One scenario's output: markdown lines, verdicts, and data for the plot."""

    number: int
    title: str
    lines: List[str] = field(default_factory=list)
    verdicts: List[Verdict] = field(default_factory=list)
    plot: Dict[str, object] = field(default_factory=dict)

    def text(self, *lines: str) -> None:
        self.lines.extend(lines)

    def table(self, header: Sequence[str], rows: Sequence[Sequence[object]]) -> None:
        """Append a markdown table (a blank line before and after)."""
        self.lines.append('')
        self.lines.append('| ' + ' | '.join(header) + ' |')
        self.lines.append('|' + '---|' * len(header))
        for row in rows:
            self.lines.append('| ' + ' | '.join(str(cell) for cell in row) + ' |')
        self.lines.append('')

    def judge(self, target: str, measured: str, passed: Optional[bool]) -> Verdict:
        verdict = Verdict(target, measured, passed)
        self.verdicts.append(verdict)
        return verdict

    def judge_ratio(self, target: str, ours: float, theirs: Optional[float], limit: float,
                    peer: str, missing: Optional[str]) -> Verdict:
        """Judge ``ours <= limit * theirs`` (times in us); ``theirs`` None: the peer is not
        installed (``missing`` says why) and the target is not judged."""
        if theirs is None:
            return self.judge(target, f'{peer} {missing}', None)
        return self.judge(target, f'{ratio(ours, theirs)} ({us(ours)} vs {us(theirs)} us)',
                          ours <= limit * theirs)


def us(value: Optional[float]) -> str:
    """Format microseconds with sensible precision."""
    if value is None or not math.isfinite(value):
        return '-'
    if value >= 100:
        return f'{value:.0f}'
    if value >= 10:
        return f'{value:.1f}'
    return f'{value:.2f}'


def ratio(ours: Optional[float], theirs: Optional[float]) -> str:
    """Format ours / theirs as ``0.42x``."""
    if ours is None or theirs is None or not theirs > 0:
        return '-'
    return f'{ours / theirs:.2f}x'


def spread(values: Sequence[float]) -> str:
    """Format ``min / median / max`` of per-pass times (us)."""
    ordered = sorted(values)
    n = len(ordered)
    median = ordered[n // 2] if n % 2 else 0.5 * (ordered[n // 2 - 1] + ordered[n // 2])
    return f'{us(ordered[0])} / {us(median)} / {us(ordered[-1])}'


def load_note() -> str:
    """The machine's load average now, for figures measured on a shared machine."""
    try:
        one, five, _ = os.getloadavg()
    except OSError:
        return 'load average unknown'
    return f'load average {one:.1f} (1 min), {five:.1f} (5 min), {os.cpu_count()} CPUs'
