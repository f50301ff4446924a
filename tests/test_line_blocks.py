"""The one chunked reader of whole lines (``tipgeo.inspect.textscan.line_blocks``)
that the CSV/TXT sniffer and the XYZ/PLY text reader share: every byte comes
back once, in order, in chunks of whole lines, with the count of lines before
each chunk; ``max_rows`` stops after that many lines."""

import io

from hypothesis import given, settings
from hypothesis import strategies as st

from tipgeo.inspect.textscan import line_blocks

# lines of a few bytes, some empty, with or without a last newline
_TEXT = st.lists(st.binary(max_size=12).map(lambda b: b.replace(b"\n", b"")), max_size=40)


def _text(lines: list[bytes], last_newline: bool) -> bytes:
    data = b"\n".join(lines)
    return data + b"\n" if last_newline and lines else data


@settings(max_examples=300, deadline=None)
@given(_TEXT, st.booleans(), st.integers(1, 20), st.integers(0, 8))
def test_blocks_are_the_stream_in_whole_lines(lines, last_newline, chunk, first_len):
    data = _text(lines, last_newline)
    first, rest = data[:first_len], data[first_len:]
    blocks = list(line_blocks(io.BytesIO(rest), first, chunk_bytes=chunk))
    joined = b"".join(b for _, b in blocks)
    # all of it, in order (a blank tail is dropped: it holds no line)
    assert joined == data or (data.startswith(joined) and not data[len(joined):].strip())
    rows = 0
    for k, (before, block) in enumerate(blocks):
        assert before == rows                       # lines before the chunk
        assert block.endswith(b"\n") or k == len(blocks) - 1
        rows += block.count(b"\n")


@settings(max_examples=300, deadline=None)
@given(_TEXT, st.booleans(), st.integers(1, 20), st.integers(1, 45))
def test_max_rows_stops_after_that_many_lines(lines, last_newline, chunk, max_rows):
    data = _text(lines, last_newline)
    blocks = list(line_blocks(io.BytesIO(data), chunk_bytes=chunk, max_rows=max_rows))
    joined = b"".join(b for _, b in blocks)
    whole = data.split(b"\n")
    if last_newline and lines:
        whole = whole[:-1]                          # the empty piece after the last newline
    want = b"".join(x + b"\n" for x in whole[:max_rows])
    if len(whole) <= max_rows and not (last_newline and lines):
        want = want[:-1] if want else want          # the last line has no newline
    # a tail of blank lines may be left out; nothing else
    assert want.startswith(joined) and not want[len(joined):].strip()


def test_known_chunks():
    data = b"1 2 3\n4 5 6\n7 8 9"
    blocks = list(line_blocks(io.BytesIO(data), chunk_bytes=7))
    assert blocks == [(0, b"1 2 3\n"), (1, b"4 5 6\n"), (2, b"7 8 9")]
    assert list(line_blocks(io.BytesIO(data), chunk_bytes=4, max_rows=2)) == \
        [(0, b"1 2 3\n"), (1, b"4 5 6\n")]
