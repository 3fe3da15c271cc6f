"""Progress bars on stderr for the command-line tools, drawn by tqdm.

tqdm draws only once the work has run for ``delay`` seconds (short runs print nothing) and at
most every ``interval`` seconds; here it also draws only on a terminal unless asked to::

    paper_experiment.csv:  50%|█████     | 286/571 [00:01<00:01, 250.1it/s]

The tools count finished steps, so :class:`ProgressBar` takes the total done so far, not the
increment tqdm's own ``update`` takes.
"""
import sys
from typing import Optional, TextIO

from tqdm import tqdm

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
    """Progress of ``total`` steps.

    :param total: number of steps (0 or less: unknown, the bar shows only the count).
    :param label: text before the bar.
    :param mode: ``auto`` (draw on a TTY), ``always`` or ``never``.
    :param stream: where to draw (default ``sys.stderr``).
    :param delay: seconds of work before the first draw.
    :param interval: least seconds between draws.
    """

    def __init__(self, total: int, label: str = '', mode: str = 'auto',
                 stream: Optional[TextIO] = None, delay: float = 0.5, interval: float = 0.1):
        stream = stream if stream is not None else sys.stderr
        self._bar = tqdm(total=total if total > 0 else None, desc=label or None, file=stream,
                         disable=not progress_enabled(mode, stream), delay=delay,
                         mininterval=interval, dynamic_ncols=True, leave=True)

    def update(self, done: int, note: str = '') -> None:
        """Report ``done`` steps finished in all (``note`` is shown after the bar)."""
        if self._bar.disable:
            return
        if note:
            self._bar.set_postfix_str(note, refresh=False)
        self._bar.update(done - self._bar.n)

    def close(self) -> None:
        """Finish the bar (later output starts on a new line)."""
        self._bar.close()

    def __enter__(self) -> 'ProgressBar':
        return self

    def __exit__(self, *exc) -> None:
        self.close()
