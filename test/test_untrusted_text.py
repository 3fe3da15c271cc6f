"""Text from the network is shown escaped and bounded (no ROS)."""
import random

from collision_sensor.untrusted_text import MAX_SHOWN_CHARS, listing, printable, quoted


def test_control_characters_are_escaped_so_no_line_can_be_forged():
    name = 'j1\n[ERROR] [1.0] [collision_sensor]: forged\r\x1b[31mred\x00\u202e\u2028'
    shown = printable(name)
    assert '\n' not in shown and '\r' not in shown and '\x1b' not in shown
    assert shown == ('j1\\n[ERROR] [1.0] [collision_sensor]: forged\\r\\x1b[31mred\\x00'
                     '\\u202e\\u2028')
    assert printable('a\\nb') == 'a\\\\nb'     # a literal backslash-n stays distinguishable
    assert printable('gelenk_ä_1') == 'gelenk_ä_1'
    assert quoted('x\ty') == '"x\\ty"'


def test_long_text_is_cut_with_the_count_left_out():
    shown = printable('x' * 10_000_000)
    assert len(shown) <= MAX_SHOWN_CHARS and shown.endswith('chars)')
    assert shown.startswith('x' * 90)
    count = int(shown.rsplit('+', 1)[1].split()[0])
    assert count + shown.count('x') == 10_000_000
    assert printable('short', limit=20) == 'short'
    assert len(printable('\n' * 100, limit=30)) <= 30


def test_random_text_is_always_one_bounded_printable_line():
    rng = random.Random(7)
    for _ in range(2000):
        text = ''.join(chr(rng.choice([rng.randrange(0, 0x80), rng.randrange(0, 0x110000)]))
                       for _ in range(rng.randrange(0, 300)))
        text = text.encode('utf-8', 'surrogatepass').decode('utf-8', 'replace')
        for limit in (16, 50, MAX_SHOWN_CHARS):
            shown = printable(text, limit)
            assert len(shown) <= limit and shown.isprintable(), (text, shown)
    assert printable(b'\xff\n') == '\\\\xff\\n'
    assert printable(3.5) == '3.5'


def test_listing_is_bounded_whatever_the_number_of_values():
    names = (f'ghost_{i}\n' for i in range(10_000))
    text = listing(names, total=10_000)
    assert text.endswith('(+9990 more)') and '\n' not in text and len(text) < 500
    assert listing([]) == '' and listing(['a', 'b']) == 'a, b'
    assert listing([str(i) for i in range(100)], max_items=3) == '0, 1, 2 (+97 more)'
    assert len(listing(['y' * 5000] * 5)) < 500
