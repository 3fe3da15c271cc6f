"""Parse URDF and SRDF documents as untrusted input.

A robot description can arrive from anywhere (a ``robot_description`` topic, a file somebody
sent), so the parser is locked down:

- lxml with ``resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False``: no
  external DTD, file or URL is fetched, no entity reference in content is replaced, and
  libxml2's own limit on entity amplification stops a "billion laughs" while parsing;
- a document whose DOCTYPE declares entities (general or parameter) is then rejected. The test
  is on what the parser read (``docinfo.internalDTD``), not on the text: the parser has
  decoded the document whatever its encoding (UTF-16, UTF-7, ...), which a search of the raw
  bytes for ``<!ENTITY`` would not (``+ADw-!ENTITY`` is ``<!ENTITY`` in UTF-7);
- a document larger than :data:`MAX_DOCUMENT_BYTES` (64 MiB) is rejected before it is read;
- a document nested deeper than :data:`MAX_ELEMENT_DEPTH` (64 elements; a URDF needs 4) is
  rejected.

Comments and processing instructions are dropped while parsing, so callers see elements only.

A ``str`` that starts with ``<`` is taken as the document, any other as a path. Text from the
network must never be taken for a path: pass it through :func:`document_bytes` first, which
turns it into ``bytes`` (always the document) or refuses it.
"""
import os

from lxml import etree

from collision_sensor.errors import CollisionSensorError, RobotDescriptionError, SrdfError
from collision_sensor.untrusted_text import listing, printable, quoted

#: Largest document accepted, in bytes. The biggest real URDFs are a few MiB.
MAX_DOCUMENT_BYTES = 64 * 1024 * 1024

#: Deepest element nesting accepted (the root element is depth 1). URDF needs 4, SRDF 3.
MAX_ELEMENT_DEPTH = 64

_ERROR_FOR = {'URDF': RobotDescriptionError, 'SRDF': SrdfError}


def is_xml_text(text_or_path) -> bool:
    """Return True if ``text_or_path`` is XML text rather than a file path.

    XML text is ``bytes``, or a ``str`` whose first non-blank character is ``<``.

    :param text_or_path: a path (``str`` or ``os.PathLike``), or XML text.
    """
    if isinstance(text_or_path, bytes):
        return True
    return isinstance(text_or_path, str) and text_or_path.lstrip().startswith('<')


def document_bytes(text, what: str = 'URDF', max_bytes: int = None,
                   origin: str = 'robot_description') -> bytes:
    """Return XML text received from outside as ``bytes``, so that it is never read as a path.

    :param text: the document as received (``str``).
    :param what: the document kind named in messages.
    :param max_bytes: the largest document accepted, in UTF-8 bytes (default
        :data:`MAX_DOCUMENT_BYTES`).
    :param origin: where the text came from, for messages (a topic name).
    :return: the UTF-8 bytes, which :func:`parse_xml` always parses as the document.
    :raises RobotDescriptionError | SrdfError: ``text`` is not a ``str``, does not start with
        ``<`` (a path, or not XML at all), or is over ``max_bytes``.
    """
    error = _ERROR_FOR.get(what, CollisionSensorError)
    limit = MAX_DOCUMENT_BYTES if max_bytes is None else max_bytes
    if not isinstance(text, str):
        raise error(f'{origin}: expected {what} XML text, got {type(text).__name__}')
    # Cheap bound first: a UTF-8 character is at least one byte.
    if len(text) > limit or len(text.encode('utf-8', 'surrogatepass')) > limit:
        raise error(f'{origin}: {len(text)} characters is over the limit of {limit} bytes; '
                    f'this is not a plausible {what}')
    if not text.lstrip().startswith('<'):
        raise error(f'{origin}: not {what} XML text (it starts with '
                    f'{quoted(text.lstrip()[:40], 60)}); {origin} carries the document itself, '
                    'never a file path: give a path with the urdf_path parameter instead')
    return text.encode('utf-8', 'surrogatepass')


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
    parser = etree.XMLParser(
        resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False,
        remove_comments=True, remove_pis=True, dtd_validation=False)
    try:
        root = etree.fromstring(data, parser)
    except etree.XMLSyntaxError as exc:
        line = exc.lineno if exc.lineno is not None else '?'
        message = printable(getattr(exc, 'msg', None) or str(exc), 300)
        if 'amplification' in message.lower() or 'external entity' in message.lower():
            # libxml2 stopped at a declared entity: an expansion over its amplification limit,
            # or a reference to an external one (never read).
            raise error(
                f'{what} "{source}": its DOCTYPE declares entities, which are refused (the '
                f'parser stopped at line {line}: {message}); remove the DOCTYPE and write the '
                f'{what} without entities (expand xacro beforehand)') from None
        if 'depth' in message.lower():
            raise error(
                f'{what} "{source}": elements nested deeper than {MAX_ELEMENT_DEPTH} '
                f'(line {line}); a {what} needs only a few levels, fix the document') from None
        raise error(
            f'{what} "{source}": broken XML at line {line}: {message}; fix the document '
            '(is it the complete file, xacro already expanded?)') from None
    if root is None:
        raise error(f'{what} "{source}": the document is empty; give a complete {what}')
    _reject_entity_declarations(root, what, source, error)
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


def _reject_entity_declarations(root, what, source, error):
    # What the parser read, in whatever encoding the document came: the internal subset of the
    # DOCTYPE (the external one is never loaded) and every entity it declares.
    dtd = root.getroottree().docinfo.internalDTD
    if dtd is None:
        return
    names = [entity.name for entity in dtd.iterentities()]
    if names:
        raise error(
            f'{what} "{source}": its DOCTYPE declares entities ({listing(names, max_items=5)}), '
            'which are refused (entity expansion can exhaust memory or read files); remove the '
            f'DOCTYPE and write the {what} without entities (expand xacro beforehand)')


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
