"""Show text that came from outside (joint names, robot descriptions) in logs and diagnostics.

Anything a message carries can hold a newline, an ANSI escape or a megabyte of text. Shown as
it is, a joint name ``"j1\\n[ERROR] [node]: robot on fire"`` forges a log line, and a flood of
long names makes ``/diagnostics`` unbounded. :func:`printable` is the one gate: every value from
the network goes through it before it reaches a log line or a diagnostics value.

Rules: printable characters (``str.isprintable``, which excludes control, format and separator
characters other than the space) are kept, the backslash is doubled, everything else is written
as a Python escape (``\\n``, ``\\x1b``, ``\\u202e``), so the result is one line whose escapes
cannot be confused with the text. The result is cut to ``limit`` characters, with the number of
characters left out.
"""
from typing import Iterable

#: Longest text shown for one value from outside (characters, after escaping).
MAX_SHOWN_CHARS = 120

_NAMED_ESCAPES = {'\n': '\\n', '\r': '\\r', '\t': '\\t', '\\': '\\\\'}


def _escape(char: str) -> str:
    named = _NAMED_ESCAPES.get(char)
    if named is not None:
        return named
    if char.isprintable():
        return char
    code = ord(char)
    if code < 0x100:
        return f'\\x{code:02x}'
    if code < 0x10000:
        return f'\\u{code:04x}'
    return f'\\U{code:08x}'


def printable(value, limit: int = MAX_SHOWN_CHARS) -> str:
    """Return ``value`` as one line of printable text, escaped and cut to ``limit`` characters.

    :param value: any object; a ``str`` is shown as it is, ``bytes`` decoded as UTF-8 with
        undecodable bytes escaped, anything else through ``str()``.
    :param limit: the longest result, >= 16; longer text ends in ``...(+N chars)``.
    :return: text without control or line-breaking characters.
    """
    if isinstance(value, bytes):
        value = value.decode('utf-8', 'backslashreplace')
    elif not isinstance(value, str):
        value = str(value)
    out, length = [], 0
    # Escape only what can be shown: a 10 MB value costs no more than a short one.
    for index, char in enumerate(value[:limit + 1]):
        piece = _escape(char)
        if length + len(piece) > limit:
            tail = f'...(+{len(value) - index} chars)'
            while out and length + len(tail) > limit:
                length -= len(out.pop())
                index -= 1
                tail = f'...(+{len(value) - index} chars)'
            return ''.join(out) + tail
        out.append(piece)
        length += len(piece)
    return ''.join(out)


def quoted(value, limit: int = MAX_SHOWN_CHARS) -> str:
    """Return ``printable(value)`` in double quotes, as log lines name joints and links."""
    return f'"{printable(value, limit)}"'


def listing(values: Iterable, total: int = None, max_items: int = 10, limit: int = 400,
            escape: bool = True) -> str:
    """Return a bounded, comma-separated list of values.

    :param values: the values (only the first ``max_items`` are read).
    :param total: how many there are in all (default: ``len(values)`` when it has one).
    :param max_items: the most values shown.
    :param limit: the longest list in characters, before the ``(+N more)``.
    :param escape: pass each value through :func:`printable`; False for values that are safe
        already (built from :func:`quoted` parts), which are then only cut.
    :return: e.g. ``a, b, c (+97 more)``.
    """
    if total is None and hasattr(values, '__len__'):
        total = len(values)
    each = max(16, min(MAX_SHOWN_CHARS, limit // 4)) if escape else limit
    shown, count = [], 0
    for value in values:
        if count >= max_items:
            count += 1
            break
        shown.append(printable(value, each) if escape else str(value))
        count += 1
    total = max(total if total is not None else count, len(shown))
    text = ', '.join(shown)
    if len(text) > limit:
        text = text[:limit - 3] + '...'
    more = total - len(shown)
    return text + (f' (+{more} more)' if more > 0 else '')
