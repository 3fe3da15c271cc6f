"""Parse URDF and SRDF documents as untrusted input.

A robot description can arrive from anywhere (a ``robot_description`` topic, a file somebody
sent), so the parser is locked down:

- lxml with ``resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False``: no
  external files or URLs are fetched, no entity is expanded;
- a DOCTYPE that declares entities is rejected outright (the "billion laughs" attack hides in
  nested entity declarations), before lxml sees the document;
- a document larger than :data:`MAX_DOCUMENT_BYTES` (64 MiB) is rejected before it is read;
- a document nested deeper than :data:`MAX_ELEMENT_DEPTH` (64 elements; a URDF needs 4) is
  rejected.

Comments and processing instructions are dropped while parsing, so callers see elements only.
"""
import os
import re

from lxml import etree

from collision_sensor.errors import CollisionSensorError, RobotDescriptionError, SrdfError

#: Largest document accepted, in bytes. The biggest real URDFs are a few MiB.
MAX_DOCUMENT_BYTES = 64 * 1024 * 1024

#: Deepest element nesting accepted (the root element is depth 1). URDF needs 4, SRDF 3.
MAX_ELEMENT_DEPTH = 64

# An entity declaration anywhere in the prolog; XML names are case-sensitive.
_ENTITY_DECLARATION = re.compile(rb'<!ENTITY\b')
_DOCTYPE = re.compile(rb'<!DOCTYPE\b')

_ERROR_FOR = {'URDF': RobotDescriptionError, 'SRDF': SrdfError}


def is_xml_text(text_or_path) -> bool:
    """Return True if ``text_or_path`` is XML text rather than a file path.

    XML text is ``bytes``, or a ``str`` whose first non-blank character is ``<``.

    :param text_or_path: a path (``str`` or ``os.PathLike``), or XML text.
    """
    if isinstance(text_or_path, bytes):
        return True
    return isinstance(text_or_path, str) and text_or_path.lstrip().startswith('<')


def describe_source(text_or_path, what: str = 'URDF') -> str:
    """Return how messages name the document: its path, or ``<WHAT text>``.

    :param text_or_path: as for :func:`parse_xml`.
    :param what: the document kind, ``'URDF'`` or ``'SRDF'``.
    """
    if is_xml_text(text_or_path):
        return '<robot_description text>' if what == 'URDF' else f'<{what} text>'
    return os.fspath(text_or_path)


def parse_xml(text_or_path, what: str = 'URDF', *, error: type = None) -> etree._Element:
    """Parse an XML document safely and return its root element.

    :param text_or_path: a path (``str`` or ``os.PathLike``), or the document itself (``bytes``,
        or a ``str`` whose first non-blank character is ``<``).
    :param what: the document kind named in messages, ``'URDF'`` or ``'SRDF'``.
    :param error: exception class to raise; by default :class:`RobotDescriptionError` for a
        URDF, :class:`SrdfError` for an SRDF, :class:`CollisionSensorError` otherwise.
    :return: the root element; comments and processing instructions removed.
    :raises RobotDescriptionError | SrdfError: the file cannot be read, is too large, nests too
        deeply, declares entities, or is not well-formed XML (the message names the line).
    """
    error = error or _ERROR_FOR.get(what, CollisionSensorError)
    source = describe_source(text_or_path, what)
    data = _read_bounded(text_or_path, what, source, error)
    _reject_entity_declarations(data, what, source, error)
    parser = etree.XMLParser(
        resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False,
        remove_comments=True, remove_pis=True, dtd_validation=False)
    try:
        root = etree.fromstring(data, parser)
    except etree.XMLSyntaxError as exc:
        line = exc.lineno if exc.lineno is not None else '?'
        message = getattr(exc, 'msg', None) or str(exc)
        if 'depth' in message.lower():
            raise error(
                f'{what} "{source}": elements nested deeper than {MAX_ELEMENT_DEPTH} '
                f'(line {line}); a {what} needs only a few levels, fix the document') from None
        raise error(
            f'{what} "{source}": broken XML at line {line}: {message}; fix the document '
            '(is it the complete file, xacro already expanded?)') from None
    if root is None:
        raise error(f'{what} "{source}": the document is empty; give a complete {what}')
    _check_depth(root, what, source, error)
    return root


def _read_bounded(text_or_path, what, source, error) -> bytes:
    if is_xml_text(text_or_path):
        data = text_or_path if isinstance(text_or_path, bytes) else text_or_path.encode('utf-8')
        if len(data) > MAX_DOCUMENT_BYTES:
            raise error(f'{what} "{source}": {len(data)} bytes is over the limit of '
                        f'{MAX_DOCUMENT_BYTES} bytes; this is not a plausible {what}')
        return data
    try:
        size = os.stat(source).st_size
        if size > MAX_DOCUMENT_BYTES:
            raise error(f'{what} "{source}": {size} bytes is over the limit of '
                        f'{MAX_DOCUMENT_BYTES} bytes; this is not a plausible {what}')
        with open(source, 'rb') as stream:
            # Read one byte more than the limit: a file that grew after stat() is caught too.
            data = stream.read(MAX_DOCUMENT_BYTES + 1)
    except OSError as exc:
        raise error(f'{what} "{source}": cannot read the file ({exc.strerror or exc}); '
                    'check the path') from None
    if len(data) > MAX_DOCUMENT_BYTES:
        raise error(f'{what} "{source}": over the limit of {MAX_DOCUMENT_BYTES} bytes')
    return data


def _reject_entity_declarations(data: bytes, what, source, error):
    doctype = _DOCTYPE.search(data)
    if doctype is None:
        return
    # Only the internal subset can declare entities; it ends before the root element.
    if _ENTITY_DECLARATION.search(data, doctype.start()):
        line = data.count(b'\n', 0, doctype.start()) + 1
        raise error(
            f'{what} "{source}": DOCTYPE at line {line} declares entities, which are refused '
            f'(entity expansion can exhaust memory); remove the DOCTYPE and write the {what} '
            'without entities (expand xacro beforehand)')


def _check_depth(root, what, source, error):
    depth = 0
    for event, element in etree.iterwalk(root, events=('start', 'end')):
        if event == 'start':
            depth += 1
            if depth > MAX_ELEMENT_DEPTH:
                raise error(
                    f'{what} "{source}": elements nested deeper than {MAX_ELEMENT_DEPTH} at '
                    f'line {element.sourceline} (<{element.tag}>); a {what} needs only a few '
                    'levels, fix the document')
        else:
            depth -= 1
