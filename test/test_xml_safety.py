"""Untrusted XML: entity expansion, size and depth limits, broken documents."""
import pytest

from collision_sensor import xml_safety
from collision_sensor.errors import RobotDescriptionError, SrdfError
from collision_sensor.xml_safety import is_xml_text, parse_xml

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
    assert 'line 2' in str(raised.value) and 'remove the DOCTYPE' in str(raised.value)


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
