"""Joint sequences as CSV files: ``time`` and one column per joint, one row per frame (the
format: :mod:`collision_sensor.model.sequences`).

A plain file (decimal numbers, no quotes, no comments after the header) is read in one pass by
a number-table parser; anything else, or anything wrong, is read again row by row by the exact
reader, which names the line and column of the first problem.
"""
import csv
import io
import math
from typing import Iterable, Optional, Sequence

import numpy as np

from collision_sensor.errors import SequenceError
from collision_sensor.model.joint_sequence import JointSequence


def write_csv(seq: JointSequence, path: str) -> None:
    with open(path, 'w', newline='', encoding='utf-8') as stream:
        stream.write(','.join(('time',) + seq.joint_names) + '\n')
        for time, row in zip(seq.times.tolist(), seq.positions.tolist()):
            stream.write(','.join(repr(float(value)) for value in [time] + row) + '\n')


def _data_rows(reader) -> Iterable:
    """Yield (line number, fields) for rows that are neither blank nor comments."""
    for fields in reader:
        if not fields or all(not field.strip() for field in fields):
            continue
        if fields[0].lstrip().startswith('#'):
            continue
        yield reader.line_num, [field.strip() for field in fields]


#: The fast path's parser of a CSV file's body: (bytes, columns) -> (rows, columns) float64,
#: or None for anything but lines of plain decimal numbers. The compiled engine registers its
#: own when it loads (``cpp/number_table.hpp``, by :func:`use_number_table_parser`, from
#: ``collision_sensor/engine/compiled.py``): this layer does not import the engine. Until
#: then numpy's ``loadtxt`` reads the file (slower).
_number_table_parser = None


def use_number_table_parser(parse) -> None:
    """Read CSV bodies with ``parse(text: bytes, columns: int)`` (see above; None: numpy's
    ``loadtxt``)."""
    global _number_table_parser
    _number_table_parser = parse


def _number_table(body: str, columns: int) -> Optional[np.ndarray]:
    """The (rows, columns) float64 values of a CSV body, or None where the fast path does not
    read it."""
    if _number_table_parser is not None:
        try:
            return _number_table_parser(body.encode('ascii'), columns)
        except UnicodeEncodeError:
            return None
    if '#' in body or '"' in body:
        return None
    try:
        values = np.loadtxt(io.StringIO(body), delimiter=',', dtype=np.float64, ndmin=2)
    except ValueError:
        return None
    return values if values.shape[1] == columns else None


def read_csv_fast(path: str, text: str, joint_names: Optional[Sequence[str]]
                   ) -> Optional[JointSequence]:
    """Read a plain CSV file (no quotes, no comments after the header, plain decimal numbers)
    with the fast parser (:func:`use_number_table_parser`); return None for anything else or
    anything wrong, which the exact reader below then reads again and reports line by line.
    Both fast parsers give the floats Python's ``float`` gives (checked by the tests)."""
    start = 0
    while True:  # the header: the first line neither blank nor a comment
        end = text.find('\n', start)
        line = text[start:] if end < 0 else text[start:end]
        if line.strip() and not line.lstrip().startswith('#'):
            break
        if end < 0:
            return None
        start = end + 1
    if '"' in line:
        return None
    columns = [name.strip() for name in line.split(',')]
    body = '' if end < 0 else text[end + 1:]
    if columns[0] != 'time' or len(columns) < 2 or not all(columns) \
            or len(set(columns)) != len(columns) or not body.strip():
        return None
    if joint_names is not None and set(columns[1:]) != set(joint_names):
        return None
    values = _number_table(body, len(columns))
    if values is None or not len(values) or not np.all(np.isfinite(values)) \
            or np.any(np.diff(values[:, 0]) <= 0.0):
        return None
    seq = JointSequence(tuple(columns[1:]), values[:, 0], values[:, 1:], path)
    return seq.select(joint_names) if joint_names is not None else seq


def read_csv(path: str, joint_names: Optional[Sequence[str]]) -> JointSequence:
    try:
        with open(path, newline='', encoding='utf-8') as stream:
            text = stream.read()
        fast = read_csv_fast(path, text, joint_names)
        if fast is not None:
            return fast
        rows = list(_data_rows(csv.reader(io.StringIO(text, newline=''))))
    except (OSError, UnicodeDecodeError, csv.Error) as err:
        reason = getattr(err, 'strerror', None) or err
        raise SequenceError(f'{path}: cannot read: {reason}; give a readable UTF-8 CSV file') \
            from None
    if not rows:
        raise SequenceError(
            f'{path}: empty file; expected a header "time,<joint>,<joint>,..." and one row per '
            'frame')
    header_line, header = rows[0]
    if header[0] != 'time':
        raise SequenceError(
            f'{path}: line {header_line}: the first column is "{header[0]}", expected "time"; '
            'the header must read "time,<joint>,<joint>,..."')
    columns = header[1:]
    if not columns or any(not name for name in columns):
        raise SequenceError(
            f'{path}: line {header_line}: empty joint name in the header; name every column')
    repeated = sorted({name for name in columns if columns.count(name) > 1})
    if repeated:
        raise SequenceError(
            f'{path}: line {header_line}: column(s) {repeated} appear more than once; keep one')
    if joint_names is not None:
        unknown = [name for name in columns if name not in joint_names]
        missing = [name for name in joint_names if name not in columns]
        if unknown:
            raise SequenceError(
                f'{path}: line {header_line}: unknown joint column(s) {unknown}; the robot\'s '
                f'joints are {list(joint_names)}; rename or remove the column(s)')
        if missing:
            raise SequenceError(
                f'{path}: line {header_line}: no column for joint(s) {missing}; add a column '
                'per joint')
    if len(rows) == 1:
        raise SequenceError(f'{path}: no frames after the header; add one row per frame')

    names = ['time'] + columns
    values = np.empty((len(rows) - 1, len(names)))
    for row_index, (line, fields) in enumerate(rows[1:]):
        if len(fields) != len(names):
            raise SequenceError(
                f'{path}: line {line}: {len(fields)} values, expected {len(names)} (time and '
                f'{len(columns)} joints as in the header)')
        for column, (name, text) in enumerate(zip(names, fields)):
            try:
                value = float(text)
            except ValueError:
                raise SequenceError(
                    f'{path}: line {line}, column "{name}": "{text}" is not a number; write a '
                    'decimal number such as 0.25') from None
            if not math.isfinite(value):
                raise SequenceError(
                    f'{path}: line {line}, column "{name}": {text} is not a finite number; '
                    'fill in the value or drop the row')
            values[row_index, column] = value
        if row_index and values[row_index, 0] <= values[row_index - 1, 0]:
            raise SequenceError(
                f'{path}: line {line}: time {fields[0]} is not after the previous row\'s time '
                f'{values[row_index - 1, 0]!r}; times must strictly increase (sort the rows, '
                'drop repeated ones)')
    seq = JointSequence(tuple(columns), values[:, 0], values[:, 1:], path)
    return seq.select(joint_names) if joint_names is not None else seq
