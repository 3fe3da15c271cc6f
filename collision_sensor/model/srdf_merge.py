"""Write ``<disable_collisions>`` entries into an SRDF: a new document, or merged into one.

The merge is textual on purpose: an SRDF is often hand-edited, with comments, blank lines and
attribute orders that a re-serialising XML writer would lose. New entries become whole lines
inserted just before the line holding ``</robot>``, indented like the document's existing
``<disable_collisions>`` lines (else like its first indented element, else two spaces), with
the document's line ending. Every other byte stays where it was, so the original is the merged
file with the inserted lines taken out.

Entries already in the document are kept as they are, whatever their reason; a pair is
written only if the document does not yet disable it (pairs compared as two names in sorted
order), so merging the same entries twice adds nothing the second time.
"""
import re
from typing import Iterable, List, Sequence, Tuple
from xml.sax.saxutils import escape

from collision_sensor.errors import SrdfError
from collision_sensor.model.exception_list import sorted_pair
from collision_sensor.model.srdf import load_srdf

#: ``(link1, link2, reason)`` of one ``<disable_collisions>`` element; ``link1 < link2``.
Entry = Tuple[str, str, str]

_CLOSING_ROOT = re.compile(rb'</robot\s*>')
_DISABLE_LINE = re.compile(rb'^([ \t]*)<disable_collisions\b', re.MULTILINE)
_INDENTED_ELEMENT = re.compile(rb'^([ \t]+)<[A-Za-z_]', re.MULTILINE)
_TRAILER = re.compile(rb'\s*(?:(?:<!--.*?-->|<\?.*?\?>)\s*)*\Z', re.DOTALL)


def _attribute(value: str) -> str:
    return escape(value, {'"': '&quot;'})


def disable_collisions_element(entry: Entry) -> str:
    """Return ``<disable_collisions link1="a" link2="b" reason="R"/>`` for one entry."""
    link1, link2, reason = entry
    return (f'<disable_collisions link1="{_attribute(link1)}" link2="{_attribute(link2)}" '
            f'reason="{_attribute(reason)}"/>')


def new_srdf(robot_name: str, entries: Sequence[Entry], comment: str = '') -> str:
    """Return a new SRDF document holding only ``entries``, in the order given.

    :param comment: one line put in an XML comment after the declaration ('' for none).
    """
    lines = ['<?xml version="1.0" encoding="UTF-8"?>']
    if comment:
        lines.append(f'<!-- {comment.replace("--", "- -")} -->')
    lines.append(f'<robot name="{_attribute(robot_name)}">')
    lines.extend('  ' + disable_collisions_element(entry) for entry in entries)
    lines.append('</robot>')
    return '\n'.join(lines) + '\n'


def merge_disable_collisions(original: bytes, entries: Iterable[Entry],
                             source: str = '<SRDF text>') -> Tuple[bytes, List[Entry]]:
    """Insert the entries the SRDF lacks as new lines before ``</robot>``.

    :param original: the SRDF document, bytes as read from the file.
    :param entries: ``(link1, link2, reason)``; a pair the document already disables (in
        either order, with any reason) is skipped, and so is a repeat within ``entries``.
    :param source: the file name, for messages.
    :return: ``(merged document, entries added)``; the document is ``original`` unchanged
        when nothing is added.
    :raises SrdfError: the document is not a readable SRDF, has no ``</robot>`` closing tag
        (an empty ``<robot/>``), or the merged document does not read back as expected.
    """
    existing = load_srdf(original)  # also refuses unsafe or broken XML
    present = {(pair.link1, pair.link2) for pair in existing.disabled_pairs}
    added = []
    for link1, link2, reason in entries:
        pair = sorted_pair(link1, link2)
        if pair not in present:
            present.add(pair)
            added.append((pair[0], pair[1], reason))
    if not added:
        return original, []

    closing = _last_closing_root(original, source)
    newline = b'\r\n' if b'\r\n' in original else b'\n'
    line_start = original.rfind(b'\n', 0, closing.start()) + 1
    before_closing = original[line_start:closing.start()]
    indent = _indentation(original)
    text = b''.join(indent + disable_collisions_element(entry).encode('utf-8') + newline
                    for entry in added)
    if before_closing.strip():
        # "</robot>" shares its line with other content: start the new lines on a line of
        # their own and put "</robot>" back at the start of the next one.
        at = closing.start()
        text = newline + text
    else:
        at = line_start
    merged = original[:at] + text + original[at:]

    reread = {(pair.link1, pair.link2) for pair in load_srdf(merged).disabled_pairs}
    missing = [entry for entry in added if (entry[0], entry[1]) not in reread]
    if missing or not reread >= {(p.link1, p.link2) for p in existing.disabled_pairs}:
        raise SrdfError(f'SRDF "{source}": the merged document does not read back with the new '
                        '<disable_collisions> entries; write to a new file with --output instead')
    return merged, added


def _last_closing_root(document: bytes, source: str):
    """Return the match of the root's closing tag: the last ``</robot>`` with only blanks,
    comments or processing instructions after it."""
    # From the end: a "</robot>" inside a trailing comment is followed by "-->", not a trailer.
    for match in reversed(list(_CLOSING_ROOT.finditer(document))):
        if _TRAILER.match(document, match.end()):
            return match
    raise SrdfError(f'SRDF "{source}": no closing </robot> tag at the end of the document '
                    '(an empty <robot .../> element?); write the root as <robot ...> ... '
                    '</robot> and run again')


def _indentation(document: bytes) -> bytes:
    disable_lines = _DISABLE_LINE.findall(document)
    if disable_lines:
        return disable_lines[-1]
    indented = _INDENTED_ELEMENT.search(document)
    return indented.group(1) if indented else b'  '
