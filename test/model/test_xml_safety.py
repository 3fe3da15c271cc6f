"""Untrusted XML: entity expansion, size and depth limits, broken documents."""
import os

import pytest

from collision_sensor.errors import RobotDescriptionError, SrdfError
from collision_sensor.model import xml_safety
from collision_sensor.model.xml_safety import document_bytes, is_xml_text, parse_xml

BILLION_LAUGHS = """<?xml version="1.0"?>
<!DOCTYPE robot [
  <!ENTITY lol "lol">
  <!ENTITY lol1 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
  <!ENTITY lol2 "&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;">
  <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
]>
<robot name="&lol3;"><link name="a"/></robot>
"""

EXTERNAL_ENTITY = """<?xml version="1.0"?>
<!DOCTYPE robot [<!ENTITY secret SYSTEM "file:///etc/passwd">]>
<robot name="r"><link name="&secret;"/></robot>
"""


def nested(depth):
    return '<robot>' + '<a>' * (depth - 1) + '</a>' * (depth - 1) + '</robot>'


def test_text_and_paths_are_told_apart(tmp_path):
    assert is_xml_text('  \n<robot/>')
    assert is_xml_text(b'<robot/>')
    assert not is_xml_text('robot.urdf')
    assert not is_xml_text(tmp_path / 'robot.urdf')


def test_parses_text_bytes_and_files(tmp_path):
    text = '<?xml version="1.0" encoding="UTF-8"?>\n<robot name="r"><!-- c --><link/></robot>'
    path = tmp_path / 'r.urdf'
    path.write_text(text)
    for source in (text, text.encode(), str(path), path):
        root = parse_xml(source)
        assert root.tag == 'robot' and [child.tag for child in root] == ['link']


@pytest.mark.parametrize('document', [BILLION_LAUGHS, EXTERNAL_ENTITY])
def test_entity_declarations_are_refused(document):
    with pytest.raises(RobotDescriptionError, match='declares entities') as raised:
        parse_xml(document)
    assert 'remove the DOCTYPE' in str(raised.value)


def utf7_forced(text):
    """Return ``text`` in UTF-7 with every ``<`` base64-encoded (``+ADw-``), as an attacker
    would write it to hide ``<!ENTITY`` from a search of the bytes."""
    body = text.split('?>', 1)[1]
    data = ('<?xml version="1.0" encoding="UTF-7"?>' + body.replace('<', '+ADw-')).encode()
    assert b'<!ENTITY' not in data and b'<!DOCTYPE' not in data
    return data


@pytest.mark.parametrize('encode', [
    utf7_forced,
    lambda text: text.replace('version="1.0"?>', 'version="1.0" encoding="UTF-16"?>'
                              ).encode('utf-16'),
    lambda text: text.replace('version="1.0"?>', 'version="1.0" encoding="UTF-16BE"?>'
                              ).encode('utf-16-be'),
    lambda text: text.encode('utf-8-sig'),
], ids=['utf-7', 'utf-16', 'utf-16be', 'utf-8-bom'])
@pytest.mark.parametrize('document', [BILLION_LAUGHS, EXTERNAL_ENTITY], ids=['laughs', 'external'])
def test_entity_declarations_are_refused_whatever_the_encoding(document, encode):
    data = encode(document)
    with pytest.raises(RobotDescriptionError, match='declares entities'):
        parse_xml(data)


def test_a_utf7_document_without_entities_parses():
    # The same parser reads UTF-7: the refusal above is about entities, not the encoding.
    data = utf7_forced('<?xml version="1.0"?>\n<robot name="r"><link name="a"/></robot>')
    assert [child.get('name') for child in parse_xml(data)] == ['a']


def test_parameter_entities_and_deep_bombs_are_refused():
    parameter = ('<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY % p "<!ENTITY x \'y\'>"> %p;]>'
                 '<robot name="r"/>')
    with pytest.raises(RobotDescriptionError, match='declares entities'):
        parse_xml(parameter)
    lines = ['<?xml version="1.0"?>', '<!DOCTYPE robot [', '<!ENTITY l0 "lol">']
    lines += [f'<!ENTITY l{i} "' + f'&l{i - 1};' * 10 + '">' for i in range(1, 10)]
    lines += [']>', '<robot name="&l9;"/>']
    # 10^9 "lol" in an attribute, which libxml2 expands even without resolve_entities: its
    # amplification limit stops it while parsing.
    with pytest.raises(RobotDescriptionError, match='declares entities'):
        parse_xml('\n'.join(lines))


def test_text_from_the_network_is_never_a_path(tmp_path):
    urdf = tmp_path / 'r.urdf'
    urdf.write_text('<robot name="r"><link name="a"/></robot>')
    fifo = tmp_path / 'fifo'
    os.mkfifo(fifo)
    for text in ('/etc/passwd', '/dev/zero', str(fifo), str(urdf), 'robot.urdf', '', '   ',
                 '\n/etc/passwd'):
        with pytest.raises(RobotDescriptionError, match='not URDF XML text.*urdf_path'):
            document_bytes(text)
    assert parse_xml(document_bytes('  <robot name="r"/>')).get('name') == 'r'
    with pytest.raises(RobotDescriptionError, match='over the limit of 100 bytes'):
        document_bytes('<robot>' + 'x' * 100 + '</robot>', max_bytes=100)
    with pytest.raises(RobotDescriptionError, match='not URDF XML text') as raised:
        document_bytes('x\n[ERROR] forged' + 'y' * 1000)
    assert '\n' not in str(raised.value) and len(str(raised.value)) < 400


def test_entity_declarations_are_refused_in_srdf_files(tmp_path):
    path = tmp_path / 'bomb.srdf'
    path.write_text(BILLION_LAUGHS)
    with pytest.raises(SrdfError, match='bomb.srdf'):
        parse_xml(path, 'SRDF')


def test_doctype_without_entities_is_accepted():
    root = parse_xml('<?xml version="1.0"?>\n<!DOCTYPE robot SYSTEM "http://x.invalid/r.dtd">'
                     '<robot name="r"/>')
    assert root.get('name') == 'r'


@pytest.mark.parametrize('depth', [xml_safety.MAX_ELEMENT_DEPTH + 1, 100, 300, 5000])
def test_too_deep_nesting_is_refused(depth):
    with pytest.raises(RobotDescriptionError, match='nested deeper than 64'):
        parse_xml(nested(depth))


def test_nesting_at_the_limit_is_accepted():
    assert parse_xml(nested(xml_safety.MAX_ELEMENT_DEPTH)).tag == 'robot'


def test_too_large_documents_are_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(xml_safety, 'MAX_DOCUMENT_BYTES', 100)
    document = '<robot>' + ' ' * 200 + '</robot>'
    with pytest.raises(RobotDescriptionError, match='over the limit of 100 bytes'):
        parse_xml(document)
    path = tmp_path / 'big.urdf'
    path.write_text(document)
    with pytest.raises(RobotDescriptionError, match='big.urdf.*over the limit'):
        parse_xml(str(path))


def test_broken_xml_names_file_and_line(tmp_path):
    path = tmp_path / 'broken.urdf'
    path.write_text('<robot name="r">\n  <link name="a">\n</robot>\n')
    with pytest.raises(RobotDescriptionError, match=r'broken\.urdf.*broken XML at line 3'):
        parse_xml(str(path))
    with pytest.raises(SrdfError, match='<SRDF text>.*broken XML at line 1'):
        parse_xml('<robot', 'SRDF')


def test_missing_file_is_named(tmp_path):
    with pytest.raises(RobotDescriptionError, match='nope.urdf.*cannot read'):
        parse_xml(str(tmp_path / 'nope.urdf'))
