"""A one-line terminal progress bar on stderr, for the command-line tools.

It draws only when the stream is a terminal (or when forced), only once the work has run for
``delay`` seconds (short runs print nothing), and at most every ``interval`` seconds::

    paper_experiment.csv [##########----------]  50.1 %  286/571
"""
import sys
import time
from typing import Optional, TextIO

MODES = ('auto', 'always', 'never')


def progress_enabled(mode: str, stream: TextIO) -> bool:
    """Return whether to draw: ``always``, ``never``, or ``auto`` (when ``stream`` is a TTY)."""
    if mode == 'always':
        return True
    if mode == 'never':
        return False
    isatty = getattr(stream, 'isatty', None)
    return bool(isatty and isatty())


class ProgressBar:
    """Progress of ``total`` steps, redrawn in place with carriage returns.

    :param total: number of steps (0 or less: unknown, the bar shows only the count).
    :param label: text before the bar.
    :param mode: ``auto`` (draw on a TTY), ``always`` or ``never``.
    :param stream: where to draw (default ``sys.stderr``).
    :param delay: seconds of work before the first draw.
    :param interval: least seconds between draws.
    """

    def __init__(self, total: int, label: str = '', mode: str = 'auto',
                 stream: Optional[TextIO] = None, delay: float = 0.5, interval: float = 0.1,
                 width: int = 30):
        self.total = int(total)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = progress_enabled(mode, self.stream)
        self.delay = delay
        self.interval = interval
        self.width = width
        self._start = time.monotonic()
        self._last_draw = None
        self._drawn = False

    def update(self, done: int, note: str = '') -> None:
        """Report ``done`` steps finished; draws if enabled and due."""
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self._start < self.delay:
            return
        if self._last_draw is not None and now - self._last_draw < self.interval \
                and done < self.total:
            return
        self._last_draw = now
        self._draw(done, note)

    def _draw(self, done: int, note: str) -> None:
        if self.total > 0:
            fraction = min(max(done / self.total, 0.0), 1.0)
            filled = int(round(fraction * self.width))
            bar = '#' * filled + '-' * (self.width - filled)
            text = f'{self.label} [{bar}] {100.0 * fraction:5.1f} %  {done}/{self.total}'
        else:
            text = f'{self.label} {done}'
        if note:
            text += f'  {note}'
        self.stream.write('\r' + text + '\x1b[K')
        self.stream.flush()
        self._drawn = True

    def close(self) -> None:
        """End the line if anything was drawn (so later output starts on a new line)."""
        if self._drawn:
            self.stream.write('\n')
            self.stream.flush()
            self._drawn = False

    def __enter__(self) -> 'ProgressBar':
        return self

    def __exit__(self, *exc) -> None:
        self.close()
